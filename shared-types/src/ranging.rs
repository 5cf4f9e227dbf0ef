//! The ranging sensors beyond the plain lidar: the semantic lidar (each
//! return names what it met) and the radar (each detection measures how
//! fast what it met moves along the ray). Their captures hold CARLA
//! 0.9.16's layouts, in simbus's axes (X forward, Y up, Z right of the
//! sensor); the CARLA gateway turns them into CARLA's.

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

/// The most detections a radar may make per simulated second.
pub const MAX_RADAR_POINTS_PER_SECOND: u32 = 1_000_000;

/// The longest stretch of simulated time one radar capture covers: a
/// frame longer than this casts `points_per_second` rays, not more (a
/// capture holds that many detections).
pub const RADAR_MAX_CAPTURE_SECONDS: f64 = 1.0;

/// One semantic lidar return (CARLA's `SemanticLidarDetection`, 24 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::SemanticLidarPoint/1")]
pub struct SemanticLidarPoint {
    /// Forward, metres.
    pub x: f32,
    /// Up, metres.
    pub y: f32,
    /// Right, metres.
    pub z: f32,
    /// The cosine of the angle between the ray and the surface's normal
    /// where it met it (1: head on).
    pub cos_inc_angle: f32,
    /// The actor met (0: none of the world's actors).
    pub object_idx: u32,
    /// Its CARLA tag ([`SemanticTag`](crate::camera::SemanticTag)).
    pub object_tag: u32,
}

/// A radar's parameters (CARLA's `sensor.other.radar`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Radar {
    /// Horizontal field of view, degrees, in (0, 180).
    pub horizontal_fov: f32,
    /// Vertical field of view, degrees, in (0, 180).
    pub vertical_fov: f32,
    /// How far it sees, metres.
    pub range: f32,
    /// Rays cast per simulated second, spread at random over the field of
    /// view (a frame of `dt` casts `points_per_second × dt`, truncated, as
    /// CARLA does).
    pub points_per_second: u32,
    /// The rays' generator's seed (CARLA's `noise_seed`),
    /// `0..=`[`crate::gnss::MAX_GNSS_SEED`]: the same seed, the same rays.
    pub seed: u32,
}

impl Default for Radar {
    /// CARLA's defaults: 30° by 30°, 100 m, 1500 points per second.
    fn default() -> Self {
        Self {
            horizontal_fov: 30.0,
            vertical_fov: 30.0,
            range: 100.0,
            points_per_second: 1500,
            seed: 0,
        }
    }
}

impl Radar {
    /// Whether the parameters can build a radar: both fields of view in
    /// (0, 180) degrees, a range in (0, 1e6] m, a whole number of points
    /// per second in `1..=`[`MAX_RADAR_POINTS_PER_SECOND`] and a whole seed
    /// in `0..=`[`crate::gnss::MAX_GNSS_SEED`] (the wire's `f32`s checked
    /// as sent: `points_on_wire`, `seed_on_wire`).
    pub(crate) fn valid(&self, points_on_wire: f32, seed_on_wire: f32) -> bool {
        let fov = |v: f32| v > 0.0 && v < 180.0;
        let whole_in = |v: f32, low: f32, high: f32| v >= low && v <= high && v.fract() == 0.0;
        fov(self.horizontal_fov)
            && fov(self.vertical_fov)
            && self.range > 0.0
            && self.range <= 1e6
            && whole_in(points_on_wire, 1.0, MAX_RADAR_POINTS_PER_SECOND as f32)
            && whole_in(seed_on_wire, 0.0, crate::gnss::MAX_GNSS_SEED as f32)
    }

    /// How many rays a frame of `dt_ns` nanoseconds casts: CARLA's
    /// `points_per_second × dt`, truncated, at most what one capture holds.
    pub fn rays_per_frame(&self, dt_ns: u64) -> usize {
        let seconds = (dt_ns as f64 * 1e-9).min(RADAR_MAX_CAPTURE_SECONDS);
        (f64::from(self.points_per_second) * seconds) as usize
    }

    /// How many detections one capture holds.
    pub fn capacity(&self) -> usize {
        (f64::from(self.points_per_second) * RADAR_MAX_CAPTURE_SECONDS) as usize
    }
}

/// One radar detection (CARLA's `RadarDetection`, 16 bytes).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::RadarDetection/1")]
pub struct RadarDetection {
    /// How fast what was met moves along the ray, relative to the sensor,
    /// m/s: negative when it comes towards the sensor.
    pub velocity: f32,
    /// The ray's azimuth, radians, positive to the right.
    pub azimuth: f32,
    /// The ray's altitude, radians, positive up.
    pub altitude: f32,
    /// How far along the ray it was met, metres.
    pub depth: f32,
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_layouts_are_carlas() {
        assert_eq!(std::mem::size_of::<SemanticLidarPoint>(), 24);
        assert_eq!(std::mem::size_of::<RadarDetection>(), 16);
    }

    #[test]
    fn a_frame_casts_points_per_second_times_dt_truncated_and_capped() {
        let radar = Radar::default();
        assert_eq!(radar.rays_per_frame(50_000_000), 75);
        assert_eq!(radar.rays_per_frame(33_333_333), 49);
        assert_eq!(radar.rays_per_frame(5_000_000_000), radar.capacity());
        assert_eq!(radar.capacity(), 1500);
    }

    #[test]
    fn only_sensible_radars_are_valid() {
        let ok = Radar::default();
        assert!(ok.valid(1500.0, 0.0));
        assert!(!ok.valid(1500.5, 0.0));
        assert!(!ok.valid(0.0, 0.0));
        assert!(!ok.valid(2e6, 0.0));
        assert!(!ok.valid(1500.0, -1.0));
        assert!(!ok.valid(1500.0, 0.5));
        for bad in [
            Radar {
                horizontal_fov: 180.0,
                ..ok
            },
            Radar {
                vertical_fov: 0.0,
                ..ok
            },
            Radar { range: -1.0, ..ok },
        ] {
            assert!(!bad.valid(1500.0, 0.0), "{bad:?}");
        }
    }
}
