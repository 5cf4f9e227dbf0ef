//! Pictures of what sensors see: depth images and top-down lidar views as
//! PNG (with a legend of the range), lidar scans as PLY.

use std::io::Write;
use std::path::Path;

use shared_types::LidarPoint;

/// A grey image, one byte per pixel.
struct Canvas {
    width: usize,
    height: usize,
    pixels: Vec<u8>,
}

/// 3×5 digits for the legend, one row of 3 bits per line.
const DIGITS: [[u8; 5]; 10] = [
    [7, 5, 5, 5, 7],
    [2, 6, 2, 2, 7],
    [7, 1, 7, 4, 7],
    [7, 1, 7, 1, 7],
    [5, 5, 7, 1, 1],
    [7, 4, 7, 1, 7],
    [7, 4, 7, 5, 7],
    [7, 1, 1, 1, 1],
    [7, 5, 7, 5, 7],
    [7, 5, 7, 1, 7],
];

impl Canvas {
    fn new(width: usize, height: usize, fill: u8) -> Self {
        Self {
            width,
            height,
            pixels: vec![fill; width * height],
        }
    }

    fn set(&mut self, x: usize, y: usize, value: u8) {
        if x < self.width && y < self.height {
            self.pixels[y * self.width + x] = value;
        }
    }

    /// Writes `number` at (x, y) in 2× scaled 3×5 digits.
    fn number(&mut self, x: usize, y: usize, number: u32, value: u8) {
        for (i, digit) in number.to_string().bytes().enumerate() {
            let glyph = DIGITS[(digit - b'0') as usize];
            for (row, bits) in glyph.iter().enumerate() {
                for col in 0..3 {
                    if bits & (4 >> col) != 0 {
                        for (dx, dy) in [(0, 0), (1, 0), (0, 1), (1, 1)] {
                            self.set(x + i * 8 + col * 2 + dx, y + row * 2 + dy, value);
                        }
                    }
                }
            }
        }
    }

    /// A legend under the picture: a gradient from 0 to `max` metres with
    /// labelled ticks, near = white.
    fn legend(&mut self, top: usize, max: f32) {
        let (left, right) = (8, self.width.saturating_sub(8));
        let span = (right - left).max(1);
        for x in left..right {
            let shade = 255 - (255 * (x - left) / span) as u8;
            for y in top..top + 8 {
                self.set(x, y, shade);
            }
        }
        let ticks = 4;
        for t in 0..=ticks {
            let x = left + span * t / ticks;
            for y in top + 8..top + 12 {
                self.set(x, y, 255);
            }
            let label = (max * t as f32 / ticks as f32).round() as u32;
            let width = 8 * label.to_string().len();
            let at = x
                .saturating_sub(width / 2)
                .min(self.width.saturating_sub(width));
            self.number(at, top + 14, label, 255);
        }
    }

    fn save(&self, path: &Path) -> anyhow::Result<()> {
        let file = std::io::BufWriter::new(std::fs::File::create(path)?);
        let mut encoder = png::Encoder::new(file, self.width as u32, self.height as u32);
        encoder.set_color(png::ColorType::Grayscale);
        encoder.set_depth(png::BitDepth::Eight);
        encoder.write_header()?.write_image_data(&self.pixels)?;
        Ok(())
    }
}

/// Height of the legend strip under a picture.
const LEGEND: usize = 32;

/// A depth image as PNG: near white, far black, with a 0..`far` m legend.
pub fn save_depth(
    path: &Path,
    depth: &[f32],
    width: usize,
    height: usize,
    far: f32,
) -> anyhow::Result<()> {
    let mut canvas = Canvas::new(width.max(96), height + LEGEND, 0);
    for (i, d) in depth.iter().enumerate().take(width * height) {
        let shade = 255.0 * (1.0 - (d / far).clamp(0.0, 1.0));
        canvas.set(i % width, i / width, shade as u8);
    }
    canvas.legend(height + 4, far);
    canvas.save(path)
}

/// A lidar scan seen from above as PNG (sensor at the centre, X up the
/// image), brightness by distance, with a 0..`range` m legend.
pub fn save_lidar_top_down(path: &Path, points: &[LidarPoint], range: f32) -> anyhow::Result<()> {
    let size = 400;
    let mut canvas = Canvas::new(size, size + LEGEND, 0);
    let scale = (size as f32 / 2.0) / range;
    for p in points {
        let distance = (p.x * p.x + p.z * p.z).sqrt();
        let x = size as f32 / 2.0 + p.z * scale;
        let y = size as f32 / 2.0 - p.x * scale;
        if x >= 0.0 && y >= 0.0 {
            let shade = 255.0 * (1.0 - (distance / range).clamp(0.0, 0.8));
            canvas.set(x as usize, y as usize, shade as u8);
        }
    }
    canvas.set(size / 2, size / 2, 255);
    canvas.legend(size + 4, range);
    canvas.save(path)
}

/// A lidar scan as an ASCII PLY point cloud (x, y, z, intensity).
pub fn save_ply(path: &Path, points: &[LidarPoint]) -> anyhow::Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(
        out,
        "ply\nformat ascii 1.0\nelement vertex {}",
        points.len()
    )?;
    writeln!(out, "property float x\nproperty float y\nproperty float z\nproperty float intensity\nend_header")?;
    for p in points {
        writeln!(out, "{} {} {} {}", p.x, p.y, p.z, p.intensity)?;
    }
    Ok(())
}
