//! Typed views of a [`SensorSpec`]'s parameters.
//!
//! On the wire a sensor's parameters are the [`SENSOR_PARAMS`] `f32` of
//! [`SensorSpec::params`], whose meaning depends on its kind; code reads and
//! writes them through these views, never by index.
//!
//! ```
//! use shared_types::{Camera, SensorSpec};
//!
//! let camera = Camera { width: 64, height: 48, fov: 90.0, range: 50.0 };
//! let spec = SensorSpec::with_params([0.0, 1.0, 0.0], camera);
//! assert_eq!(spec.camera(), Some(camera));
//! assert_eq!(spec.lidar_params(), None);
//! ```

use crate::events::{Collision, Obstacle};
use crate::gnss::Gnss;
use crate::ranging::Radar;
use crate::sensor::{SensorKind, SensorSpec, SENSOR_PARAMS};

/// A ray-cast camera's parameters: the depth camera's, and the RGB,
/// semantic and instance segmentation cameras' (cameras of one parent,
/// pose, size and field of view share one ray cast per frame).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Camera {
    /// Image width in pixels.
    pub width: u32,
    /// Image height in pixels.
    pub height: u32,
    /// Horizontal field of view, degrees.
    pub fov: f32,
    /// Far range in metres: what a depth pixel reads where nothing is hit;
    /// the other cameras see the sky beyond it.
    pub range: f32,
}

/// A ray-cast lidar's parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct Lidar {
    /// Vertical channels (lasers).
    pub channels: u32,
    /// Points per channel in one full turn.
    pub points: u32,
    /// Range in metres.
    pub range: f32,
    /// Upper field of view, degrees (0 = horizontal).
    pub upper_fov: f32,
    /// Lower field of view, degrees.
    pub lower_fov: f32,
    /// Rotation frequency in Hz; 0 takes a full turn every capture.
    pub rotation_hz: f32,
    /// Noise and drop-off (all zero: exact, simbus's default; a semantic
    /// lidar has none, as in CARLA).
    pub noise: LidarNoise,
}

/// A lidar's noise, drop-off and attenuation: CARLA's `sensor.lidar.ray_cast`
/// attributes, applied as CARLA's `RayCastLidar.cpp` applies them. Every
/// random draw comes from a generator seeded with `seed`, the capture and
/// the ray, so the same seed gives the same points, run after run, on any
/// number of render threads.
#[derive(Debug, Clone, Copy, PartialEq, Default)]
pub struct LidarNoise {
    /// Standard deviation of a normal error added along each ray, metres.
    pub noise_stddev: f32,
    /// The share of rays dropped at random before they are cast, 0..=1.
    pub dropoff_general_rate: f32,
    /// Returns above this intensity are never dropped for it, 0..=1.
    pub dropoff_intensity_limit: f32,
    /// The chance a return of intensity 0 is dropped, 0..=1 (between 0 and
    /// the limit it falls linearly to 0).
    pub dropoff_zero_intensity: f32,
    /// Intensity falls as `exp(-rate × distance)` (CARLA's); 0 keeps
    /// simbus's `1 - distance / range`.
    pub atmosphere_attenuation_rate: f32,
    /// The generator's seed, `0..=`[`crate::gnss::MAX_GNSS_SEED`].
    pub seed: u32,
}

impl LidarNoise {
    /// Whether nothing is added or dropped (the intensity may still
    /// follow the attenuation rate).
    pub fn is_exact(&self) -> bool {
        self.noise_stddev == 0.0
            && self.dropoff_general_rate == 0.0
            && (self.dropoff_zero_intensity == 0.0 || self.dropoff_intensity_limit == 0.0)
    }

    /// Whether every value is in range: a finite deviation and rate >= 0,
    /// drop-off values in 0..=1, a whole seed in
    /// `0..=`[`crate::gnss::MAX_GNSS_SEED`] (checked as sent:
    /// `seed_on_wire`).
    pub(crate) fn valid(&self, seed_on_wire: f32) -> bool {
        let share = |v: f32| (0.0..=1.0).contains(&v);
        let non_negative = |v: f32| v.is_finite() && v >= 0.0;
        non_negative(self.noise_stddev)
            && non_negative(self.atmosphere_attenuation_rate)
            && share(self.dropoff_general_rate)
            && share(self.dropoff_intensity_limit)
            && share(self.dropoff_zero_intensity)
            && (0.0..=crate::gnss::MAX_GNSS_SEED as f32).contains(&seed_on_wire)
            && seed_on_wire.fract() == 0.0
    }
}

/// An inertial measurement unit: it has no parameters.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub struct Imu;

/// A sensor's kind with its parameters.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SensorParams {
    /// A depth camera.
    Depth(Camera),
    /// An RGB camera.
    Rgb(Camera),
    /// A semantic segmentation camera.
    Semantic(Camera),
    /// An instance segmentation camera.
    Instance(Camera),
    /// A lidar.
    Lidar(Lidar),
    /// A semantic lidar (a lidar's parameters).
    SemanticLidar(Lidar),
    /// A radar.
    Radar(Radar),
    /// An IMU.
    Imu(Imu),
    /// A GNSS receiver.
    Gnss(Gnss),
    /// A collision sensor.
    Collision(Collision),
    /// An obstacle detector.
    Obstacle(Obstacle),
}

impl SensorParams {
    /// The kind these parameters are for.
    pub fn kind(&self) -> SensorKind {
        match self {
            Self::Depth(_) => SensorKind::Depth,
            Self::Rgb(_) => SensorKind::Rgb,
            Self::Semantic(_) => SensorKind::Semantic,
            Self::Instance(_) => SensorKind::Instance,
            Self::Lidar(_) => SensorKind::Lidar,
            Self::SemanticLidar(_) => SensorKind::SemanticLidar,
            Self::Radar(_) => SensorKind::Radar,
            Self::Imu(_) => SensorKind::Imu,
            Self::Gnss(_) => SensorKind::Gnss,
            Self::Collision(_) => SensorKind::Collision,
            Self::Obstacle(_) => SensorKind::Obstacle,
        }
    }

    /// The capture's size as [`SensorHeader::size`](crate::sensor::SensorHeader::size) states it: a
    /// camera's width and height, a lidar's channels and points per
    /// channel; zeros for the others (a radar's and an event sensor's
    /// captures say their count).
    pub fn size(&self) -> [u32; 2] {
        match self {
            Self::Depth(d) | Self::Rgb(d) | Self::Semantic(d) | Self::Instance(d) => {
                [d.width, d.height]
            }
            Self::Lidar(l) | Self::SemanticLidar(l) => [l.channels, l.points],
            Self::Imu(_)
            | Self::Gnss(_)
            | Self::Collision(_)
            | Self::Obstacle(_)
            | Self::Radar(_) => [0, 0],
        }
    }

    /// A camera of `kind` with `camera`'s parameters; `None` for a kind
    /// that is not a camera.
    pub fn camera_of(kind: SensorKind, camera: Camera) -> Option<Self> {
        match kind {
            SensorKind::Depth => Some(Self::Depth(camera)),
            SensorKind::Rgb => Some(Self::Rgb(camera)),
            SensorKind::Semantic => Some(Self::Semantic(camera)),
            SensorKind::Instance => Some(Self::Instance(camera)),
            _ => None,
        }
    }

    /// The camera's parameters, if these are a camera's of any kind.
    pub fn camera(&self) -> Option<Camera> {
        match *self {
            Self::Depth(c) | Self::Rgb(c) | Self::Semantic(c) | Self::Instance(c) => Some(c),
            _ => None,
        }
    }

    /// The wire form: the [`SENSOR_PARAMS`] `f32` of [`SensorSpec::params`],
    /// zeros past the kind's own.
    pub fn to_wire(&self) -> [f32; SENSOR_PARAMS] {
        let mut wire = [0.0; SENSOR_PARAMS];
        let own: &[f32] = match *self {
            Self::Depth(d) | Self::Rgb(d) | Self::Semantic(d) | Self::Instance(d) => {
                &[d.width as f32, d.height as f32, d.fov, d.range]
            }
            Self::Lidar(l) | Self::SemanticLidar(l) => {
                let n = l.noise;
                &[
                    l.channels as f32,
                    l.points as f32,
                    l.range,
                    l.upper_fov,
                    l.lower_fov,
                    l.rotation_hz,
                    n.noise_stddev,
                    n.dropoff_general_rate,
                    n.dropoff_intensity_limit,
                    n.dropoff_zero_intensity,
                    n.atmosphere_attenuation_rate,
                    n.seed as f32,
                ]
            }
            Self::Imu(Imu) | Self::Collision(Collision) => &[],
            Self::Radar(r) => &[
                r.horizontal_fov,
                r.vertical_fov,
                r.range,
                r.points_per_second as f32,
                r.seed as f32,
            ],
            Self::Obstacle(o) => &[
                o.distance,
                o.hit_radius,
                if o.only_dynamics { 1.0 } else { 0.0 },
            ],
            Self::Gnss(g) => &[
                g.lat_bias,
                g.lat_stddev,
                g.lon_bias,
                g.lon_stddev,
                g.alt_bias,
                g.alt_stddev,
                g.seed as f32,
            ],
        };
        wire[..own.len()].copy_from_slice(own);
        wire
    }

    /// Reads the wire form of a sensor of `kind`. Sizes that are not whole
    /// numbers in `u32`'s range read truncated and saturated
    /// ([`SensorSpec::check`] refuses them).
    pub fn from_wire(kind: SensorKind, p: [f32; SENSOR_PARAMS]) -> Self {
        match kind {
            SensorKind::Depth => Self::Depth(Camera::from_wire(p)),
            SensorKind::Rgb => Self::Rgb(Camera::from_wire(p)),
            SensorKind::Semantic => Self::Semantic(Camera::from_wire(p)),
            SensorKind::Instance => Self::Instance(Camera::from_wire(p)),
            SensorKind::Lidar => Self::Lidar(Lidar::from_wire(p)),
            SensorKind::SemanticLidar => Self::SemanticLidar(Lidar::from_wire(p)),
            SensorKind::Radar => Self::Radar(Radar {
                horizontal_fov: p[0],
                vertical_fov: p[1],
                range: p[2],
                points_per_second: p[3] as u32,
                seed: p[4] as u32,
            }),
            SensorKind::Imu => Self::Imu(Imu),
            SensorKind::Collision => Self::Collision(Collision),
            SensorKind::Obstacle => Self::Obstacle(Obstacle {
                distance: p[0],
                hit_radius: p[1],
                only_dynamics: p[2] != 0.0,
            }),
            SensorKind::Gnss => Self::Gnss(Gnss {
                lat_bias: p[0],
                lat_stddev: p[1],
                lon_bias: p[2],
                lon_stddev: p[3],
                alt_bias: p[4],
                alt_stddev: p[5],
                seed: p[6] as u32,
            }),
        }
    }
}

impl Lidar {
    fn from_wire(p: [f32; SENSOR_PARAMS]) -> Self {
        Self {
            channels: p[0] as u32,
            points: p[1] as u32,
            range: p[2],
            upper_fov: p[3],
            lower_fov: p[4],
            rotation_hz: p[5],
            noise: LidarNoise {
                noise_stddev: p[6],
                dropoff_general_rate: p[7],
                dropoff_intensity_limit: p[8],
                dropoff_zero_intensity: p[9],
                atmosphere_attenuation_rate: p[10],
                seed: p[11] as u32,
            },
        }
    }
}

impl Camera {
    fn from_wire(p: [f32; SENSOR_PARAMS]) -> Self {
        Self {
            width: p[0] as u32,
            height: p[1] as u32,
            fov: p[2],
            range: p[3],
        }
    }
}

/// A depth camera (see [`SensorParams::camera`] for the other cameras).
impl From<Camera> for SensorParams {
    fn from(value: Camera) -> Self {
        Self::Depth(value)
    }
}

impl From<Lidar> for SensorParams {
    fn from(value: Lidar) -> Self {
        Self::Lidar(value)
    }
}

impl From<Radar> for SensorParams {
    fn from(value: Radar) -> Self {
        Self::Radar(value)
    }
}

impl From<Imu> for SensorParams {
    fn from(value: Imu) -> Self {
        Self::Imu(value)
    }
}

impl From<Collision> for SensorParams {
    fn from(value: Collision) -> Self {
        Self::Collision(value)
    }
}

impl From<Obstacle> for SensorParams {
    fn from(value: Obstacle) -> Self {
        Self::Obstacle(value)
    }
}

impl From<Gnss> for SensorParams {
    fn from(value: Gnss) -> Self {
        Self::Gnss(value)
    }
}

impl SensorSpec {
    /// A sensor at `position` (relative to its parent) with `params`, which
    /// also give its kind.
    pub fn with_params(position: [f32; 3], params: impl Into<SensorParams>) -> Self {
        let mut spec = Self {
            position,
            ..Self::default()
        };
        spec.set_params(params);
        spec
    }

    /// Replaces the kind and parameters with `params`.
    pub fn set_params(&mut self, params: impl Into<SensorParams>) {
        let params = params.into();
        self.kind = params.kind() as u32;
        self.params = params.to_wire();
    }

    /// The kind and its parameters; `None` for an unknown kind.
    pub fn sensor_params(&self) -> Option<SensorParams> {
        self.sensor_kind()
            .map(|kind| SensorParams::from_wire(kind, self.params))
    }

    /// The camera's parameters, if this is a camera of any kind.
    pub fn camera(&self) -> Option<Camera> {
        self.sensor_params()?.camera()
    }

    /// The GNSS receiver's parameters, if this is one.
    pub fn gnss_params(&self) -> Option<Gnss> {
        match self.sensor_params()? {
            SensorParams::Gnss(gnss) => Some(gnss),
            _ => None,
        }
    }

    /// The obstacle detector's parameters, if this is one.
    pub fn obstacle_params(&self) -> Option<Obstacle> {
        match self.sensor_params()? {
            SensorParams::Obstacle(o) => Some(o),
            _ => None,
        }
    }

    /// The lidar's parameters, if this is a lidar (plain or semantic).
    pub fn lidar_params(&self) -> Option<Lidar> {
        match self.sensor_params()? {
            SensorParams::Lidar(lidar) | SensorParams::SemanticLidar(lidar) => Some(lidar),
            _ => None,
        }
    }

    /// The radar's parameters, if this is a radar.
    pub fn radar_params(&self) -> Option<Radar> {
        match self.sensor_params()? {
            SensorParams::Radar(radar) => Some(radar),
            _ => None,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn views_keep_the_wire_layout() {
        let depth = SensorSpec::depth([0.0; 3], 64, 48, 90.0, 50.0);
        assert_eq!(depth.params[..5], [64.0, 48.0, 90.0, 50.0, 0.0]);
        let camera = depth.camera().expect("a depth camera");
        assert_eq!((camera.width, camera.height), (64, 48));
        assert_eq!((camera.fov, camera.range), (90.0, 50.0));
        assert_eq!(SensorSpec::with_params([0.0; 3], camera), depth);

        let lidar = SensorSpec::lidar([0.0; 3], 16, 500, 40.0, 10.0, -30.0).rotating(20.0);
        assert_eq!(
            lidar.params[..7],
            [16.0, 500.0, 40.0, 10.0, -30.0, 20.0, 0.0]
        );
        let view = lidar.lidar_params().expect("a lidar");
        assert_eq!(
            (view.channels, view.points, view.rotation_hz),
            (16, 500, 20.0)
        );
        assert_eq!((view.upper_fov, view.lower_fov), (10.0, -30.0));
        assert_eq!(SensorSpec::with_params([0.0; 3], view), lidar);
        assert_eq!(lidar.camera(), None);

        let imu = SensorSpec::imu([1.0, 2.0, 3.0]);
        assert_eq!(imu.sensor_params(), Some(SensorParams::Imu(Imu)));
        assert_eq!(SensorSpec::with_params([1.0, 2.0, 3.0], Imu), imu);
        let gnss = Gnss {
            lat_stddev: 1e-6,
            seed: 42,
            ..Gnss::default()
        };
        let spec = SensorSpec::with_params([0.0; 3], gnss);
        assert_eq!(spec.params[..8], [0.0, 1e-6, 0.0, 0.0, 0.0, 0.0, 42.0, 0.0]);
        assert_eq!(spec.gnss_params(), Some(gnss));
        assert_eq!(
            SensorSpec::gnss([0.0; 3]).gnss_params(),
            Some(Gnss::default())
        );
        let unknown = SensorSpec { kind: 99, ..imu };
        assert_eq!(unknown.sensor_params(), None);
    }

    #[test]
    fn sizes_out_of_range_read_saturated() {
        let mut spec = SensorSpec::depth([0.0; 3], 1, 1, 90.0, 1.0);
        spec.params[0] = 1e30;
        spec.params[1] = -5.0;
        let camera = spec.camera().expect("a depth camera");
        assert_eq!((camera.width, camera.height), (u32::MAX, 0));
        assert!(spec.check().is_err());
    }
}
