//! Pictures of what sensors see: depth images and top-down lidar views as
//! PNG (with a legend of the range), lidar scans as PLY.

use std::io::Write;
use std::path::Path;

use shared_types::{LidarPoint, RadarDetection, SemanticLidarPoint};

/// A grey image, one byte per pixel.
struct Canvas {
    width: usize,
    height: usize,
    pixels: Vec<u8>,
}

/// The 3×5 glyph of a legend character: a digit, or the decimal point.
fn glyph(c: u8) -> [u8; 5] {
    match c {
        b'0'..=b'9' => DIGITS[usize::from(c - b'0')],
        _ => POINT,
    }
}

/// The decimal point, in the middle column of the bottom row.
const POINT: [u8; 5] = [0, 0, 0, 0, 2];

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

    /// Writes `number` (digits and a decimal point, as [`tick_labels`]
    /// makes them) at (x, y) in 3×5 glyphs scaled `scale` times.
    fn number(&mut self, x: usize, y: usize, number: &str, value: u8, scale: usize) {
        for (i, c) in number.bytes().enumerate() {
            for (row, bits) in glyph(c).iter().enumerate() {
                for col in 0..3 {
                    if bits & (4 >> col) != 0 {
                        for dy in 0..scale {
                            for dx in 0..scale {
                                self.set(
                                    x + i * 4 * scale + col * scale + dx,
                                    y + row * scale + dy,
                                    value,
                                );
                            }
                        }
                    }
                }
            }
        }
    }

    /// A legend under the picture, [`legend_height`] high: a gradient from
    /// 0 to `max` metres with labelled ticks, near = white. Digits grow
    /// with the picture so they stay readable.
    fn legend(&mut self, top: usize, max: f32) {
        let scale = text_scale(self.width);
        let (left, right) = (4 * scale, self.width.saturating_sub(4 * scale));
        let span = right.saturating_sub(left).max(1);
        let bar = 4 * scale;
        for x in left..right {
            let shade = 255 - (255 * (x - left) / span) as u8;
            for y in top..top + bar {
                self.set(x, y, shade);
            }
        }
        let ticks = 4;
        for (t, label) in tick_labels(max, ticks).iter().enumerate() {
            let x = left + span * t / ticks;
            for y in top + bar..top + bar + 2 * scale {
                for dx in 0..scale.div_ceil(2) {
                    self.set(x + dx, y, 255);
                }
            }
            let width = 4 * scale * label.len();
            let at = x
                .saturating_sub(width / 2)
                .min(self.width.saturating_sub(width));
            self.number(at, top + bar + 3 * scale, label, 255, scale);
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

/// The labels of a legend's `ticks + 1` evenly spaced ticks from 0 to
/// `max` metres, as their real values: whole numbers without a decimal
/// point, others with as few decimals as they need (at most 3): a 30 m
/// legend reads 0, 7.5, 15, 22.5, 30 (not 8 and 23).
fn tick_labels(max: f32, ticks: usize) -> Vec<String> {
    (0..=ticks)
        .map(|t| {
            let value = f64::from(max) * t as f64 / ticks as f64;
            let text = format!("{value:.3}");
            let text = text.trim_end_matches('0').trim_end_matches('.');
            if text.is_empty() { "0" } else { text }.to_owned()
        })
        .collect()
}

/// How many pixels a legend digit's dot is: 2 up to 320 pixels wide, then
/// growing with the width.
fn text_scale(width: usize) -> usize {
    (width / 160).max(2)
}

/// Height of the legend strip under a picture `width` pixels wide.
fn legend_height(width: usize) -> usize {
    let scale = text_scale(width);
    4 * scale + 3 * scale + 5 * scale + 2 * scale
}

/// The legend's range for a depth image: the farthest hit below `far`,
/// rounded up to a readable number (1, 2 or 5 × a power of ten).
fn depth_range(depth: &[f32], far: f32) -> f32 {
    let farthest = depth
        .iter()
        .copied()
        .filter(|d| d.is_finite() && *d < far)
        .fold(0.0f32, f32::max);
    if farthest <= 0.0 {
        return far;
    }
    let power = 10f32.powf(farthest.log10().floor());
    let nice = [1.0, 2.0, 5.0, 10.0]
        .into_iter()
        .map(|m| m * power)
        .find(|v| *v >= farthest)
        .unwrap_or(farthest);
    nice.min(far)
}

/// A depth image as PNG: near white, far black, with a legend of the
/// range the grey scale spans: `range`, or the farthest hit (rounded up).
/// Returns that range.
pub(crate) fn save_depth(
    path: &Path,
    depth: &[f32],
    width: usize,
    height: usize,
    far: f32,
    range: Option<f32>,
) -> anyhow::Result<f32> {
    anyhow::ensure!(
        width.checked_mul(height) == Some(depth.len()),
        "the capture's header says {width}x{height} pixels but it holds {} values",
        depth.len()
    );
    let range = match range {
        Some(r) if r.is_finite() && r > 0.0 => r,
        Some(r) => anyhow::bail!("--range must be a positive number of metres, got {r}"),
        None => depth_range(depth, far),
    };
    let picture_width = width.max(96);
    let legend = legend_height(picture_width);
    let mut canvas = Canvas::new(picture_width, height + legend + 4, 0);
    for (i, d) in depth.iter().enumerate().take(width * height) {
        let shade = 255.0 * (1.0 - (d / range).clamp(0.0, 1.0));
        canvas.set(i % width, i / width, shade as u8);
    }
    canvas.legend(height + 4, range);
    canvas.save(path)?;
    Ok(range)
}

/// A lidar scan seen from above as PNG (sensor at the centre, X up the
/// image), brightness by distance, with a 0..`range` m legend.
pub(crate) fn save_lidar_top_down(
    path: &Path,
    points: &[LidarPoint],
    range: f32,
) -> anyhow::Result<()> {
    let size = 400;
    let mut canvas = Canvas::new(size, size + legend_height(size) + 4, 0);
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
/// Writes an RGB, semantic or instance image as a colour PNG: RGB and
/// instance pixels as they are (an instance's red is its tag, green and
/// blue its actor's id), semantic tags in CARLA's CityScapes colours.
pub(crate) fn save_image(
    path: &Path,
    pixels: &[shared_types::Bgra],
    width: usize,
    height: usize,
    cityscapes: bool,
) -> anyhow::Result<()> {
    let mut rgb = Vec::with_capacity(width * height * 3);
    for p in pixels.iter().take(width * height) {
        let colour = if cityscapes {
            shared_types::camera::cityscapes(p.r)
        } else {
            [p.r, p.g, p.b]
        };
        rgb.extend_from_slice(&colour);
    }
    let file = std::io::BufWriter::new(std::fs::File::create(path)?);
    let mut encoder = png::Encoder::new(file, width as u32, height as u32);
    encoder.set_color(png::ColorType::Rgb);
    encoder.set_depth(png::BitDepth::Eight);
    encoder.write_header()?.write_image_data(&rgb)?;
    Ok(())
}

/// A point cloud as an ASCII PLY: each vertex's `properties` (PLY type
/// and name, in order) and one row of values per vertex.
pub(crate) fn save_ply(
    path: &Path,
    properties: &[(&str, &str)],
    rows: impl ExactSizeIterator<Item = String>,
) -> anyhow::Result<()> {
    let mut out = std::io::BufWriter::new(std::fs::File::create(path)?);
    writeln!(out, "ply\nformat ascii 1.0\nelement vertex {}", rows.len())?;
    for (kind, name) in properties {
        writeln!(out, "property {kind} {name}")?;
    }
    writeln!(out, "end_header")?;
    for row in rows {
        writeln!(out, "{row}")?;
    }
    out.flush()?;
    Ok(())
}

/// A lidar's points as a PLY (x, y, z, intensity).
pub(crate) fn save_lidar_ply(path: &Path, points: &[LidarPoint]) -> anyhow::Result<()> {
    let properties = [
        ("float", "x"),
        ("float", "y"),
        ("float", "z"),
        ("float", "intensity"),
    ];
    let rows = points
        .iter()
        .map(|p| format!("{} {} {} {}", p.x, p.y, p.z, p.intensity));
    save_ply(path, &properties, rows)
}

/// A semantic lidar's points as a PLY (x, y, z, the cosine of the
/// incidence angle, the actor and tag met).
pub(crate) fn save_semantic_ply(path: &Path, points: &[SemanticLidarPoint]) -> anyhow::Result<()> {
    let properties = [
        ("float", "x"),
        ("float", "y"),
        ("float", "z"),
        ("float", "cos_inc_angle"),
        ("uint", "object_idx"),
        ("uint", "object_tag"),
    ];
    let rows = points.iter().map(|p| {
        let (x, y, z, cos) = (p.x, p.y, p.z, p.cos_inc_angle);
        format!("{x} {y} {z} {cos} {} {}", p.object_idx, p.object_tag)
    });
    save_ply(path, &properties, rows)
}

/// A radar's detections as a PLY: each where it was met (sensor frame, X
/// forward, Y up, Z right) with its velocity, azimuth, altitude and depth.
pub(crate) fn save_radar_ply(path: &Path, detections: &[RadarDetection]) -> anyhow::Result<()> {
    let properties = [
        ("float", "x"),
        ("float", "y"),
        ("float", "z"),
        ("float", "velocity"),
        ("float", "azimuth"),
        ("float", "altitude"),
        ("float", "depth"),
    ];
    let rows = detections.iter().map(|d| {
        let (x, y, z) = radar_point(d);
        format!(
            "{x} {y} {z} {} {} {} {}",
            d.velocity, d.azimuth, d.altitude, d.depth
        )
    });
    save_ply(path, &properties, rows)
}

/// Where a radar detection was met, sensor frame (X forward, Y up, Z right).
pub(crate) fn radar_point(d: &RadarDetection) -> (f32, f32, f32) {
    let (sin_alt, cos_alt) = d.altitude.sin_cos();
    let (sin_az, cos_az) = d.azimuth.sin_cos();
    (
        d.depth * cos_alt * cos_az,
        d.depth * sin_alt,
        d.depth * cos_alt * sin_az,
    )
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_depth_legend_spans_the_scene_not_the_far_range() {
        // A 20 m scene seen by a 100 m camera: the grey scale spans 20 m.
        let mut depth = vec![100.0; 64];
        depth[3] = 4.0;
        depth[9] = 17.5;
        assert_eq!(depth_range(&depth, 100.0), 20.0);
        assert_eq!(depth_range(&[100.0; 4], 100.0), 100.0, "nothing hit");
        assert_eq!(depth_range(&[0.3, 100.0], 100.0), 0.5);
        // The legend's digits grow with the picture.
        assert_eq!(text_scale(320), 2);
        assert_eq!(text_scale(2048), 12);
        assert!(legend_height(2048) > legend_height(320));
    }

    #[test]
    fn legend_labels_are_the_real_values_not_rounded_to_whole_metres() {
        assert_eq!(tick_labels(30.0, 4), ["0", "7.5", "15", "22.5", "30"]);
        assert_eq!(tick_labels(100.0, 4), ["0", "25", "50", "75", "100"]);
        assert_eq!(tick_labels(0.5, 4), ["0", "0.125", "0.25", "0.375", "0.5"]);
        assert_eq!(tick_labels(2.0, 4), ["0", "0.5", "1", "1.5", "2"]);
    }

    #[test]
    fn a_decimal_point_is_drawn_as_a_dot_between_digits() {
        let mut canvas = Canvas::new(40, 10, 0);
        canvas.number(0, 0, "7.5", 255, 1);
        let lit = |x: usize, y: usize| canvas.pixels[y * canvas.width + x] == 255;
        // The point: the middle column of the second glyph's bottom row only.
        assert!(lit(5, 4));
        assert!((0..4).all(|y| !lit(5, y)));
        assert!(!lit(4, 4) && !lit(6, 4));
        // The digits on either side are drawn.
        assert!(lit(0, 0) && lit(8, 0));
    }
}
