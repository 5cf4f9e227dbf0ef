//! Sensors: their specification, the header of every capture, and the
//! payload element of each kind. Each sensor publishes on its own service
//! (`ServiceNames::sensor`), written by the server straight into shared memory.

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

use crate::wire::wire_enum;
use crate::wire::PROTOCOL_VERSION;

/// The largest capture a sensor may publish (its shared memory holds a few
/// dozen of them).
pub const MAX_CAPTURE_BYTES: usize = 32 * 1024 * 1024;
/// The most pixels on each side of a depth image ([`SensorSpec::check`]
/// also bounds their product by [`MAX_CAPTURE_BYTES`]).
pub const MAX_IMAGE_SIDE: u32 = 8192;
/// The most lidar channels ([`SensorSpec::check`] also bounds channels ×
/// points by [`MAX_CAPTURE_BYTES`]).
pub const MAX_LIDAR_CHANNELS: u32 = 256;
/// The most lidar points per channel.
pub const MAX_LIDAR_POINTS: u32 = 65_536;

wire_enum! {
    /// What a sensor measures.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
    pub enum SensorKind {
        /// Ray-cast depth camera: one `f32` planar depth (metres) per pixel,
        /// row by row from the top left; `far` where nothing is hit.
        Depth = 1,
        /// Ray-cast lidar: [`LidarPoint`]s in the sensor frame.
        Lidar = 2,
        /// Inertial measurement unit: one [`ImuMeasurement`].
        Imu = 3,
        /// GNSS receiver: one [`GnssMeasurement`](crate::gnss::GnssMeasurement).
        Gnss = 4,
        /// Ray-cast RGB camera: one [`Bgra`](crate::camera::Bgra) per pixel, row by row
        /// from the top left, each surface lit by the sun.
        Rgb = 5,
        /// Ray-cast semantic segmentation camera: one [`Bgra`](crate::camera::Bgra) per
        /// pixel, CARLA's [`SemanticTag`](crate::camera::SemanticTag) in red.
        Semantic = 6,
        /// Ray-cast instance segmentation camera: one [`Bgra`](crate::camera::Bgra) per
        /// pixel, the tag in red, the actor's id in green (low byte) and
        /// blue (high byte).
        Instance = 7,
        /// Collision sensor: [`CollisionEvent`](crate::events::CollisionEvent)s, one per contact
        /// its parent started this frame; published only on such frames,
        /// whatever its `sensor_tick`.
        Collision = 8,
        /// Obstacle detector: one [`ObstacleDetection`](crate::events::ObstacleDetection), published
        /// only on frames where something is ahead.
        Obstacle = 9,
        /// Ray-cast semantic lidar: [`SemanticLidarPoint`](crate::ranging::SemanticLidarPoint)s in the
        /// sensor frame, each naming the actor and tag it met.
        SemanticLidar = 10,
        /// Radar: [`RadarDetection`](crate::ranging::RadarDetection)s, rays spread at random over
        /// its field of view, each with the radial velocity of what it met.
        Radar = 11,
    }
}

impl SensorKind {
    /// The lower-case name used on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Depth => "depth",
            Self::Lidar => "lidar",
            Self::Imu => "imu",
            Self::Gnss => "gnss",
            Self::Rgb => "rgb",
            Self::Semantic => "semantic",
            Self::Instance => "instance",
            Self::Collision => "collision",
            Self::Obstacle => "obstacle",
            Self::SemanticLidar => "semantic-lidar",
            Self::Radar => "radar",
        }
    }

    /// Whether it is a lidar (plain or semantic: the same parameters).
    pub fn is_lidar(&self) -> bool {
        matches!(self, Self::Lidar | Self::SemanticLidar)
    }

    /// Whether it is a camera (its captures are images).
    pub fn is_camera(&self) -> bool {
        matches!(
            self,
            Self::Depth | Self::Rgb | Self::Semantic | Self::Instance
        )
    }

    /// `kinds`' names as a sentence lists them: `depth`, `depth or rgb`,
    /// `depth, rgb or semantic`.
    pub fn listed(kinds: &[Self]) -> String {
        match kinds.split_last() {
            None => String::new(),
            Some((last, [])) => last.name().to_owned(),
            Some((last, rest)) => {
                let rest: Vec<&str> = rest.iter().map(|k| k.name()).collect();
                format!("{} or {}", rest.join(", "), last.name())
            }
        }
    }

    /// The kind named `name`.
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }
}

/// How to build a sensor. Frames: X forward, Y up, Z right of the sensor
/// (its rotation turns that into the parent's frame).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::SensorSpec/2")]
pub struct SensorSpec {
    /// [`SensorKind`] as `u32`.
    pub kind: u32,
    /// Zero.
    pub reserved: u32,
    /// The actor it rides on (0: fixed in the world).
    pub attach_to: u64,
    /// Position relative to the parent.
    pub position: [f32; 3],
    /// Zero.
    pub reserved2: u32,
    /// Orientation relative to the parent, quaternion (x, y, z, w); zeros = identity.
    pub rotation: [f32; 4],
    /// Capture period in simulation seconds (0: every frame).
    pub sensor_tick: f64,
    /// The kind's parameters in their wire form; read and write them through
    /// their typed views ([`SensorSpec::sensor_params`],
    /// [`SensorSpec::depth_camera`], [`SensorSpec::lidar_params`],
    /// [`SensorSpec::set_params`]). Depth: width, height, horizontal field of
    /// view (degrees), far range. Lidar: channels, points per channel,
    /// range, upper fov, lower fov (degrees), rotation frequency (Hz; 0 = a
    /// full turn every capture), then its noise ([`LidarNoise`](crate::sensor_params::LidarNoise)).
    pub params: [f32; SENSOR_PARAMS],
}

/// How many `f32` parameters a [`SensorSpec`] carries (16 since protocol 4;
/// [`LEGACY_SENSOR_PARAMS`](crate::sensor::LEGACY_SENSOR_PARAMS) before).
pub const SENSOR_PARAMS: usize = 16;

/// How many parameters a `simbus::SensorSpec/1` (protocol 3) carried.
pub const LEGACY_SENSOR_PARAMS: usize = 8;

impl SensorSpec {
    /// Attached to actor `id`.
    pub fn attached_to(mut self, id: u64) -> Self {
        self.attach_to = id;
        self
    }

    /// Captures every `seconds` of simulation time (0: every frame).
    pub fn every(mut self, seconds: f64) -> Self {
        self.sensor_tick = seconds;
        self
    }

    /// The kind, if known.
    pub fn sensor_kind(&self) -> Option<SensorKind> {
        SensorKind::from_u32(self.kind)
    }
}

/// The longest capture period: the clock's range (`u64` nanoseconds).
pub const MAX_SENSOR_TICK_SECONDS: f64 = 18_446_744_073.0;

wire_enum! {
    /// Why a sensor's stream ended (in the header of its last capture,
    /// flagged [`SensorHeader::END_OF_STREAM`]).
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum SensorEnd {
        /// Destroyed on request.
        Destroyed = 1,
        /// The actor it rode on was destroyed (a sensor dies with its parent).
        ParentDestroyed = 2,
        /// The world was loaded or reloaded: a new episode has no old sensors.
        EpisodeEnded = 3,
        /// The server stopped.
        ServerStopped = 4,
    }
}

impl std::fmt::Display for SensorEnd {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Destroyed => "it was destroyed",
            Self::ParentDestroyed => "the actor it rode on was destroyed",
            Self::EpisodeEnded => {
                "the world was loaded or reloaded (a new episode starts without sensors)"
            }
            Self::ServerStopped => "the server stopped",
        })
    }
}

/// One lidar return in the sensor frame, and its intensity (1 near, 0 at range).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::LidarPoint/1")]
pub struct LidarPoint {
    /// Forward.
    pub x: f32,
    /// Up.
    pub y: f32,
    /// Right.
    pub z: f32,
    /// 1 at the sensor, 0 at the range limit.
    pub intensity: f32,
}

/// One IMU reading, in the sensor frame.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::ImuMeasurement/1")]
pub struct ImuMeasurement {
    /// Specific force (m/s²): acceleration minus gravity, so at rest it reads +9.81 up.
    pub accelerometer: [f32; 3],
    /// Angular velocity (rad/s).
    pub gyroscope: [f32; 3],
}

/// The user header of every capture.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::SensorHeader/2")]
pub struct SensorHeader {
    /// [`PROTOCOL_VERSION`] of the server.
    pub protocol_version: u32,
    /// [`SensorKind`] as `u32`.
    pub kind: u32,
    /// The sensor's id.
    pub sensor_id: u64,
    /// The frame captured.
    pub frame: u64,
    /// Its simulation time, in nanoseconds.
    pub elapsed_ns: u64,
    /// Its episode.
    pub episode: u64,
    /// Captures of this sensor so far, this one included (gaps = missed).
    pub sequence: u64,
    /// Sensor position in the world at capture.
    pub position: [f32; 3],
    /// Valid payload elements (lidar: returns; the rest of the slice is zero).
    pub count: u32,
    /// Sensor orientation in the world at capture (x, y, z, w).
    pub rotation: [f32; 4],
    /// Cameras: width and height in pixels. Lidar: channels and points per channel.
    pub size: [u32; 2],
    /// [`SensorHeader::END_OF_STREAM`] and future flags.
    pub flags: u32,
    /// With [`SensorHeader::END_OF_STREAM`]: why, as [`SensorEnd`].
    pub end_reason: u32,
    /// Wall-clock seconds since the Unix epoch when the capture was published.
    pub platform_timestamp: f64,
}

impl SensorHeader {
    /// Flag: the sensor is gone and this empty capture is its last; the
    /// reason is in `end_reason`.
    pub const END_OF_STREAM: u32 = 1;

    /// Why the stream ended, if this is its last (empty) capture.
    pub fn end(&self) -> Option<SensorEnd> {
        (self.flags & Self::END_OF_STREAM != 0)
            .then(|| SensorEnd::from_u32(self.end_reason).unwrap_or(SensorEnd::Destroyed))
    }

    /// A header for `kind` from sensor `sensor_id`.
    pub fn new(kind: SensorKind, sensor_id: u64) -> Self {
        Self {
            protocol_version: PROTOCOL_VERSION,
            kind: kind as u32,
            sensor_id,
            ..Self::default()
        }
    }
}

/// What the server knows about one sensor (answer of spawn and list).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::SensorInfo/1")]
pub struct SensorInfo {
    /// The sensor's id (sensor ids are their own sequence, from 1).
    pub id: u64,
    /// How it was built.
    pub spec: SensorSpec,
    /// Captures so far.
    pub captures: u64,
}

wire_enum! {
    /// What a [`SensorRequest`] asks for.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum SensorRequestKind {
        /// Build a sensor from `spec`.
        Spawn = 1,
        /// Remove sensor `id`.
        Destroy = 2,
        /// List every sensor.
        List = 3,
    }
}

/// A request on the sensor service.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::SensorRequest/1")]
pub struct SensorRequest {
    /// [`PROTOCOL_VERSION`] of the sender.
    pub protocol_version: u32,
    /// [`SensorRequestKind`] as `u32`.
    pub kind: u32,
    /// The sensor to destroy.
    pub id: u64,
    /// The sensor to spawn.
    pub spec: SensorSpec,
}

impl SensorRequest {
    /// A request of `kind`.
    pub fn new(kind: SensorRequestKind, id: u64, spec: SensorSpec) -> Self {
        Self {
            protocol_version: PROTOCOL_VERSION,
            kind: kind as u32,
            id,
            spec,
        }
    }
}

/// The user header of a sensor-service answer (its payload: [`SensorInfo`]s).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::SensorResponseHeader/1")]
pub struct SensorResponseHeader {
    /// [`PROTOCOL_VERSION`] of the server.
    pub protocol_version: u32,
    /// [`ResponseStatus`](crate::wire::ResponseStatus) as `u32`.
    pub status: u32,
    /// With [`ResponseStatus::Refused`](crate::wire::ResponseStatus::Refused): why, as [`SensorRefusal`].
    pub error: u32,
    /// Zero.
    pub reserved: u32,
}

crate::wire::responses!(SensorResponseHeader);

wire_enum! {
    /// Why the server refused a sensor request ([`SensorResponseHeader::error`]).
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum SensorRefusal {
        /// The spec breaks a rule ([`SensorSpec::check`] says which).
        InvalidSpec = 1,
        /// `attach_to` names no actor.
        UnknownActor = 2,
        /// No sensor has this id (never had, or it ended).
        UnknownSensor = 3,
        /// The shared memory for its captures could not be had.
        NoMemory = 4,
    }
}

impl std::fmt::Display for SensorRefusal {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::InvalidSpec => "invalid sensor specification",
            Self::UnknownActor => "unknown actor to attach to",
            Self::UnknownSensor => "unknown sensor",
            Self::NoMemory => "no shared memory for the sensor's captures",
        })
    }
}

#[cfg(test)]
#[path = "sensor_tests.rs"]
mod tests;
