//! What a [`SensorSpec`] may be: each limit, and the error that states
//! the one a spec breaks.

use crate::sensor::{
    SensorKind, SensorSpec, MAX_CAPTURE_BYTES, MAX_IMAGE_SIDE, MAX_LIDAR_CHANNELS,
    MAX_LIDAR_POINTS, MAX_SENSOR_TICK_SECONDS,
};
use crate::sensor_params::SensorParams;

/// Why a [`SensorSpec`] cannot build a sensor; each message states the
/// limit that was broken.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum SensorSpecError {
    /// Position, rotation and parameters must be finite numbers.
    #[error("position, rotation and parameters must be finite numbers")]
    NotFinite,
    /// The position must be within ±[`crate::limits::MAX_ACTOR_POSITION`] m
    /// on each axis (of its actor, or of the origin), as actors must.
    #[error(
        "position must be within +-{} m on each axis (of its actor, or of the origin)",
        crate::limits::MAX_ACTOR_POSITION
    )]
    Position,
    /// `sensor_tick` must be a finite number of seconds in 0..=18446744073 (the clock's range).
    #[error(
        "sensor_tick must be a finite number of seconds in 0..=18446744073 (the clock's range)"
    )]
    SensorTick,
    /// Camera width and height must be whole numbers in
    /// `1..=`[`MAX_IMAGE_SIDE`] with width x height at most 8388608 pixels
    /// (32 MiB per capture).
    #[error("camera width and height must be whole numbers in 1..={MAX_IMAGE_SIDE} with width x height at most 8388608 pixels (32 MiB per capture)")]
    CameraSize,
    /// Camera field of view must be in (0, 180) degrees.
    #[error("camera field of view must be in (0, 180) degrees")]
    CameraFieldOfView,
    /// Camera far range must be positive.
    #[error("camera far range must be positive")]
    CameraRange,
    /// Lidar channels must be in `1..=`[`MAX_LIDAR_CHANNELS`] and points per
    /// channel in `1..=`[`MAX_LIDAR_POINTS`], with channels x points at most
    /// 2097152 (32 MiB per capture).
    #[error("lidar channels must be in 1..={MAX_LIDAR_CHANNELS} and points per channel in 1..={MAX_LIDAR_POINTS}, with channels x points at most 2097152 (32 MiB per capture)")]
    LidarSize,
    /// Lidar range must be positive and -90 <= lower_fov <= upper_fov <= 90.
    #[error("lidar range must be positive and -90 <= lower_fov <= upper_fov <= 90")]
    LidarRange,
    /// Lidar rotation frequency must be >= 0 Hz.
    #[error("lidar rotation frequency must be >= 0 Hz")]
    LidarRotation,
    /// GNSS biases must be finite, deviations finite and >= 0, and the
    /// seed a whole number in `0..=`[`crate::gnss::MAX_GNSS_SEED`].
    #[error("GNSS biases must be finite, deviations finite and >= 0, and the seed a whole number in 0..=16777216")]
    GnssNoise,
    /// A lidar's noise deviation and attenuation rate must be finite and
    /// not negative, its drop-off values in 0..=1 and its seed a whole
    /// number in `0..=`[`crate::gnss::MAX_GNSS_SEED`]; a semantic lidar has
    /// no noise or drop-off.
    #[error("a lidar's noise_stddev and atmosphere_attenuation_rate must be finite and >= 0, its dropoff_general_rate, dropoff_intensity_limit and dropoff_zero_intensity in 0..=1 and its noise_seed a whole number in 0..=16777216; a semantic lidar has no noise or drop-off")]
    LidarNoise,
    /// A radar's fields of view must be in (0, 180) degrees, its range in
    /// (0, 1e6] m and its points per second a whole number in
    /// `1..=`[`crate::ranging::MAX_RADAR_POINTS_PER_SECOND`], its seed in
    /// `0..=`[`crate::gnss::MAX_GNSS_SEED`].
    #[error("a radar's fields of view must be in (0, 180) degrees, its range in (0, 1e6] m, its points per second a whole number in 1..=1000000 and its seed a whole number in 0..=16777216")]
    Radar,
    /// An obstacle detector's distance must be in (0, 1000] m and its hit
    /// radius in (0, 100] m.
    #[error(
        "an obstacle detector's distance must be in (0, 1000] m and its hit radius in (0, 100] m"
    )]
    Obstacle,
    /// Unknown sensor kind.
    #[error("unknown sensor kind")]
    UnknownKind,
}

impl SensorSpec {
    /// Why this spec cannot build a sensor, if it cannot. The message
    /// states the limit that was broken.
    ///
    /// # Errors
    ///
    /// Returns [`SensorSpecError::NotFinite`] if any position, rotation or
    /// parameter is NaN or infinite, [`SensorSpecError::Position`] if the
    /// position is further than
    /// [`MAX_ACTOR_POSITION`](crate::limits::MAX_ACTOR_POSITION) on an axis,
    /// [`SensorSpecError::SensorTick`] if `sensor_tick` is outside the clock's
    /// range, and [`SensorSpecError::UnknownKind`] for a kind this build does
    /// not know.
    ///
    /// Otherwise the kind's own rule decides: [`SensorSpecError::CameraSize`],
    /// [`SensorSpecError::CameraFieldOfView`] or
    /// [`SensorSpecError::CameraRange`] for the cameras;
    /// [`SensorSpecError::LidarSize`], [`SensorSpecError::LidarRange`],
    /// [`SensorSpecError::LidarRotation`] or [`SensorSpecError::LidarNoise`]
    /// for the lidars; [`SensorSpecError::GnssNoise`],
    /// [`SensorSpecError::Obstacle`] or [`SensorSpecError::Radar`] for those
    /// sensors. Each variant's message states the limit broken.
    pub fn check(&self) -> Result<(), SensorSpecError> {
        let p = self.params;
        let finite = self
            .position
            .iter()
            .chain(&self.rotation)
            .chain(&p)
            .all(|v| v.is_finite());
        if !finite {
            return Err(SensorSpecError::NotFinite);
        }
        let reach = crate::limits::MAX_ACTOR_POSITION;
        if self.position.iter().any(|v| v.abs() > reach) {
            return Err(SensorSpecError::Position);
        }
        if !(self.sensor_tick.is_finite()
            && (0.0..=MAX_SENSOR_TICK_SECONDS).contains(&self.sensor_tick))
        {
            return Err(SensorSpecError::SensorTick);
        }
        // The two sizes come first in the wire form of both kinds that have
        // sizes; they must be whole numbers, which the typed view (`u32`)
        // cannot tell, so they are checked as sent.
        let [first, second, ..] = p;
        let whole = |v: f32, max: u32| v >= 1.0 && v <= max as f32 && v.fract() == 0.0;
        match self.sensor_params() {
            Some(
                SensorParams::Depth(d)
                | SensorParams::Rgb(d)
                | SensorParams::Semantic(d)
                | SensorParams::Instance(d),
            ) => {
                if !(whole(first, MAX_IMAGE_SIDE) && whole(second, MAX_IMAGE_SIDE))
                    || self.payload_bytes() > MAX_CAPTURE_BYTES
                {
                    return Err(SensorSpecError::CameraSize);
                }
                if !(d.fov > 0.0 && d.fov < 180.0) {
                    return Err(SensorSpecError::CameraFieldOfView);
                }
                if d.range <= 0.0 {
                    return Err(SensorSpecError::CameraRange);
                }
            }
            Some(SensorParams::Lidar(l) | SensorParams::SemanticLidar(l)) => {
                if !(whole(first, MAX_LIDAR_CHANNELS) && whole(second, MAX_LIDAR_POINTS))
                    || self.payload_bytes() > MAX_CAPTURE_BYTES
                {
                    return Err(SensorSpecError::LidarSize);
                }
                if l.range <= 0.0
                    || l.upper_fov < l.lower_fov
                    || l.upper_fov.abs() > 90.0
                    || l.lower_fov.abs() > 90.0
                {
                    return Err(SensorSpecError::LidarRange);
                }
                if l.rotation_hz < 0.0 {
                    return Err(SensorSpecError::LidarRotation);
                }
                let semantic = self.sensor_kind() == Some(SensorKind::SemanticLidar);
                let noisy = l.noise != crate::sensor_params::LidarNoise::default();
                if !l.noise.valid(p[11]) || (semantic && noisy) {
                    return Err(SensorSpecError::LidarNoise);
                }
            }
            Some(SensorParams::Imu(_)) => {}
            Some(SensorParams::Gnss(g)) if !g.valid(p[6]) => {
                return Err(SensorSpecError::GnssNoise)
            }
            Some(SensorParams::Gnss(_) | SensorParams::Collision(_)) => {}
            Some(SensorParams::Obstacle(o)) if !o.valid() || ![0.0, 1.0].contains(&p[2]) => {
                return Err(SensorSpecError::Obstacle)
            }
            Some(SensorParams::Obstacle(_)) => {}
            Some(SensorParams::Radar(r)) if !r.valid(p[3], p[4]) => {
                return Err(SensorSpecError::Radar)
            }
            Some(SensorParams::Radar(_)) => {}
            None => return Err(SensorSpecError::UnknownKind),
        }
        Ok(())
    }
}
