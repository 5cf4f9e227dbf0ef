//! `sim-client sensor save`: captures to files.

use std::time::Duration;

use anyhow::Context;
use clap::Args;
use shared_types::SensorKind;
use sim_client::Client;
use simbus_input as input;

use super::sensor_capture::{failure, next_capture};
use super::sensor_text::{capture_json, gnss_text, imu_text};
use super::words::count;
use crate::cli::failure::Failure;

#[derive(Debug, Args)]
pub(super) struct SaveArgs {
    /// The sensor id.
    #[arg(allow_negative_numbers = true)]
    pub(super) id: u64,
    /// How many captures to save (N >= 1).
    #[arg(long, value_name = "N", default_value_t = 1, allow_negative_numbers = true, value_parser = input::count)]
    pub(super) captures: u64,
    /// Directory to write into (created if missing).
    #[arg(long, value_name = "DIR")]
    pub(super) out: std::path::PathBuf,
    /// Depth: the range the picture's grey scale spans, metres (default:
    /// the farthest hit in the image, so a 20 m scene is not all white).
    #[arg(long, value_name = "M", allow_negative_numbers = true, value_parser = |s: &str| input::metres(s).map(|m| m as f32))]
    pub(super) range: Option<f32>,
    /// Also write each capture's payload as it is in shared memory
    /// (`.raw`: a camera's pixels row by row, a lidar's points, ...).
    #[arg(long)]
    pub(super) raw: bool,
}

pub(super) fn save(client: &Client, a: SaveArgs, timeout: Duration) -> Result<(), Failure> {
    std::fs::create_dir_all(&a.out)
        .with_context(|| format!("creating the directory {}", a.out.display()))?;
    super::interrupt::interrupted();
    let mut sensor = client.sensor(a.id).map_err(failure)?;
    tracing::info!(sensor = a.id, captures = a.captures, "waiting for captures");
    let spec = sensor.spec();
    let depth_range = spec.camera().map_or(0.0, |d| d.range);
    let lidar_range = spec.lidar_params().map_or(0.0, |l| l.range);
    for saved in 0..a.captures {
        let Some(capture) = next_capture(&mut sensor, timeout)? else {
            // Ctrl-C or SIGTERM: not a success, whatever was saved.
            return Err(Failure::Interrupted(anyhow::anyhow!(
                "sensor save: {} of {} saved in {}",
                count(saved, "capture"),
                a.captures,
                a.out.display()
            )));
        };
        let h = *capture.header();
        let stem = a
            .out
            .join(format!("sensor{}-frame{}", h.sensor_id, h.frame));
        if a.raw {
            let path = stem.with_extension("raw");
            std::fs::write(&path, capture.bytes())
                .with_context(|| format!("writing {}", path.display()))?;
            println!(
                "wrote {} ({})",
                path.display(),
                count(capture.bytes().len() as u64, "byte")
            );
        }
        if let Some(pixels) = capture.image() {
            let path = stem.with_extension("png");
            let kind = SensorKind::from_u32(h.kind).unwrap_or(SensorKind::Rgb);
            let [w, hgt] = h.size.map(|v| v as usize);
            super::pictures::save_image(&path, pixels, w, hgt, kind == SensorKind::Semantic)
                .with_context(|| format!("writing {}", path.display()))?;
            let what = match kind {
                SensorKind::Semantic => "semantic segmentation, CARLA's CityScapes colours",
                SensorKind::Instance => {
                    "instance segmentation: red the tag, green and blue the actor id"
                }
                _ => "rgb",
            };
            println!("wrote {} ({what})", path.display());
        } else if let Some(depth) = capture.depth() {
            let path = stem.with_extension("png");
            let range = super::pictures::save_depth(
                &path,
                depth,
                h.size[0] as usize,
                h.size[1] as usize,
                depth_range,
                a.range,
            )
            .with_context(|| format!("writing {}", path.display()))?;
            println!(
                "wrote {} (depth, white = near, legend 0..{range} m)",
                path.display(),
            );
        } else if let Some(points) = capture.points() {
            let ply = stem.with_extension("ply");
            super::pictures::save_lidar_ply(&ply, points)
                .with_context(|| format!("writing {}", ply.display()))?;
            let png = stem.with_extension("png");
            super::pictures::save_lidar_top_down(&png, points, lidar_range)
                .with_context(|| format!("writing {}", png.display()))?;
            println!(
                "wrote {} and {} ({})",
                ply.display(),
                png.display(),
                count(points.len() as u64, "point")
            );
        } else if let Some(points) = capture.semantic_points() {
            let ply = stem.with_extension("ply");
            super::pictures::save_semantic_ply(&ply, points)
                .with_context(|| format!("writing {}", ply.display()))?;
            println!(
                "wrote {} ({}, each with the actor and tag it met)",
                ply.display(),
                count(points.len() as u64, "point")
            );
        } else if let Some(detections) = capture.detections() {
            let ply = stem.with_extension("ply");
            super::pictures::save_radar_ply(&ply, detections)
                .with_context(|| format!("writing {}", ply.display()))?;
            println!(
                "wrote {} ({}, each with its velocity along the ray)",
                ply.display(),
                count(detections.len() as u64, "detection")
            );
        } else if let Some(imu) = capture.imu() {
            // Nothing to draw: the readings, as `sensor watch --json` prints them.
            let path = stem.with_extension("json");
            let mut text = capture_json(&capture, sensor.missed()).to_string();
            text.push('\n');
            std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
            println!(
                "wrote {} (imu: {})",
                path.display(),
                imu_text(imu, h.rotation)
            );
        } else {
            // GNSS, collision and obstacle captures: as `sensor watch --json`
            // prints them.
            let path = stem.with_extension("json");
            let mut text = capture_json(&capture, sensor.missed()).to_string();
            text.push('\n');
            std::fs::write(&path, text).with_context(|| format!("writing {}", path.display()))?;
            match capture.gnss() {
                Some(gnss) => println!("wrote {} (gnss: {})", path.display(), gnss_text(gnss)),
                None => println!("wrote {}", path.display()),
            }
        }
    }
    Ok(())
}
