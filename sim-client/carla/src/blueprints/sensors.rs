//! The blueprints of the sensors that are not cameras (lidars, radar,
//! obstacle detector, GNSS): CARLA 0.9.16's attributes with their
//! defaults, and what each spawns in simbus.

use shared_types::gnss::MAX_GNSS_SEED;
use shared_types::{
    Gnss, Lidar, LidarNoise, Radar, SensorKind, SensorParams, SensorSpec, SensorSpecError,
};

use super::cameras::text;
use super::{float, int, Attribute, Description, Kind, Spawn, ROLE_NAME};
use crate::error::BlueprintError;

/// The ray-cast lidar's attributes (`sensor.lidar.ray_cast`).
pub(super) const LIDAR: &[Attribute] = &[
    ROLE_NAME,
    int("channels", "32"),
    int("points_per_second", "56000"),
    float("range", "10.0"),
    float("upper_fov", "10.0"),
    float("lower_fov", "-30.0"),
    float("rotation_frequency", "10.0"),
    float("sensor_tick", "0.0"),
    float("horizontal_fov", "360.0"),
    // CARLA's defaults: 45 % of the rays dropped at random, returns below
    // 0.8 intensity dropped up to 40 %, intensity exp(-0.004 d).
    float("noise_stddev", "0.0"),
    int("noise_seed", "0"),
    float("dropoff_general_rate", "0.45"),
    float("dropoff_intensity_limit", "0.8"),
    float("dropoff_zero_intensity", "0.4"),
    float("atmosphere_attenuation_rate", "0.004"),
];

/// The semantic lidar's attributes (`sensor.lidar.ray_cast_semantic`):
/// the lidar's without noise, drop-off or attenuation.
pub(super) const SEMANTIC_LIDAR: &[Attribute] = &[
    ROLE_NAME,
    int("channels", "32"),
    int("points_per_second", "56000"),
    float("range", "10.0"),
    float("upper_fov", "10.0"),
    float("lower_fov", "-30.0"),
    float("rotation_frequency", "10.0"),
    float("sensor_tick", "0.0"),
    float("horizontal_fov", "360.0"),
];

/// The radar's attributes (`sensor.other.radar`).
pub(super) const RADAR: &[Attribute] = &[
    ROLE_NAME,
    float("horizontal_fov", "30.0"),
    float("vertical_fov", "30.0"),
    float("range", "100.0"),
    int("points_per_second", "1500"),
    int("noise_seed", "0"),
    float("sensor_tick", "0.0"),
];

/// The obstacle detector's attributes (`sensor.other.obstacle`); its
/// `debug_linetrace` draws nothing here.
pub(super) const OBSTACLE: &[Attribute] = &[
    ROLE_NAME,
    float("distance", "5.0"),
    float("hit_radius", "0.5"),
    text("only_dynamics", Kind::Bool, "False"),
    text("debug_linetrace", Kind::Bool, "False"),
    float("sensor_tick", "0.0"),
];

impl Description {
    /// A ray-cast lidar (plain or semantic): CARLA's attributes as
    /// simbus's lidar.
    pub(super) fn lidar(
        &self,
        kind: SensorKind,
        position: [f32; 3],
        rotation: [f32; 4],
    ) -> Result<Spawn, BlueprintError> {
        if self.number("horizontal_fov")? != 360.0 {
            return Err(BlueprintError::HorizontalFov(self.id.clone()));
        }
        let channels = self.number("channels")?;
        let frequency = self.number("rotation_frequency")?;
        if !(channels >= 1.0 && frequency > 0.0) {
            return Err(BlueprintError::LidarRates(self.id.clone()));
        }
        // CARLA's points per second over all channels, as points per
        // channel in one full turn.
        let per_turn = (self.number("points_per_second")? / frequency / channels).round();
        let lidar = Lidar {
            channels: channels as u32,
            points: per_turn.max(1.0) as u32,
            range: self.number("range")?,
            upper_fov: self.number("upper_fov")?,
            lower_fov: self.number("lower_fov")?,
            rotation_hz: frequency,
            noise: Default::default(),
        };
        let params = match kind {
            // CARLA's semantic lidar has no noise, drop-off or attenuation.
            SensorKind::SemanticLidar => SensorParams::SemanticLidar(lidar),
            _ => SensorParams::Lidar(Lidar {
                noise: self.lidar_noise()?,
                ..lidar
            }),
        };
        self.sensor(SensorSpec::with_params(position, params), rotation)
    }

    /// A ray-cast lidar's noise, drop-off and attenuation: CARLA's
    /// attributes as simbus's (which also honours `noise_seed`; CARLA
    /// 0.9.16 seeds its lidar before reading it).
    fn lidar_noise(&self) -> Result<LidarNoise, BlueprintError> {
        Ok(LidarNoise {
            noise_stddev: self.number("noise_stddev")?,
            dropoff_general_rate: self.number("dropoff_general_rate")?,
            dropoff_intensity_limit: self.number("dropoff_intensity_limit")?,
            dropoff_zero_intensity: self.number("dropoff_zero_intensity")?,
            atmosphere_attenuation_rate: self.number("atmosphere_attenuation_rate")?,
            seed: self.seed(SensorSpecError::LidarNoise)?,
        })
    }

    /// An obstacle detector: CARLA's distance, hit radius and
    /// only-dynamics flag.
    pub(super) fn obstacle(
        &self,
        position: [f32; 3],
        rotation: [f32; 4],
    ) -> Result<Spawn, BlueprintError> {
        let only_dynamics = match self.values.get("only_dynamics").map(|v| v.trim()) {
            Some("True" | "true" | "1") => true,
            Some("False" | "false" | "0") | None => false,
            Some(text) => {
                return Err(BlueprintError::NotANumber {
                    blueprint: self.id.clone(),
                    name: "only_dynamics".into(),
                    text: text.into(),
                })
            }
        };
        let obstacle = shared_types::Obstacle {
            distance: self.number("distance")?,
            hit_radius: self.number("hit_radius")?,
            only_dynamics,
        };
        self.sensor(SensorSpec::with_params(position, obstacle), rotation)
    }

    /// A GNSS receiver: CARLA's noise attributes as simbus's.
    pub(super) fn gnss(
        &self,
        position: [f32; 3],
        rotation: [f32; 4],
    ) -> Result<Spawn, BlueprintError> {
        let seed = self.seed(SensorSpecError::GnssNoise)?;
        let gnss = Gnss {
            lat_bias: self.number("noise_lat_bias")?,
            lat_stddev: self.number("noise_lat_stddev")?,
            lon_bias: self.number("noise_lon_bias")?,
            lon_stddev: self.number("noise_lon_stddev")?,
            alt_bias: self.number("noise_alt_bias")?,
            alt_stddev: self.number("noise_alt_stddev")?,
            seed,
        };
        self.sensor(SensorSpec::with_params(position, gnss), rotation)
    }

    /// A radar: CARLA's fields of view, range, points per second and seed.
    pub(super) fn radar(
        &self,
        position: [f32; 3],
        rotation: [f32; 4],
    ) -> Result<Spawn, BlueprintError> {
        let points = self.number("points_per_second")?;
        // Not a whole number in range: refused by the spec's check.
        let points_per_second = if points.fract() == 0.0 && points >= 1.0 {
            points.min(u32::MAX as f32) as u32
        } else {
            0
        };
        let radar = Radar {
            horizontal_fov: self.number("horizontal_fov")?,
            vertical_fov: self.number("vertical_fov")?,
            range: self.number("range")?,
            points_per_second,
            seed: self.seed(SensorSpecError::Radar)?,
        };
        self.sensor(SensorSpec::with_params(position, radar), rotation)
    }

    /// `noise_seed`, a whole number in `0..=`[`MAX_GNSS_SEED`]; `refusal`
    /// otherwise.
    fn seed(&self, refusal: SensorSpecError) -> Result<u32, BlueprintError> {
        let seed = self.number("noise_seed")?;
        if !(0.0..=MAX_GNSS_SEED as f32).contains(&seed) || seed.fract() != 0.0 {
            return Err(BlueprintError::Sensor {
                blueprint: self.id.clone(),
                source: refusal,
            });
        }
        Ok(seed as u32)
    }
}
