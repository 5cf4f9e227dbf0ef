//! ROS 2 for a simbus world (`sim-client ros2`, and the CARLA gateway's
//! `--ros2`), over DDS in pure Rust (`ros2-client` on RustDDS: no ROS
//! installation to build or run it). A stock `rclpy` node reads:
//!
//! - `/clock` (`rosgraph_msgs/Clock`), once per frame, the frame's exact
//!   simulation time (integer nanoseconds), for `use_sim_time`;
//! - each sensor under `<namespace>/sensor_<id>/`: cameras as
//!   `sensor_msgs/Image` + `CameraInfo` (`image`, `camera_info`), lidars,
//!   semantic lidars and radars as `PointCloud2` (`point_cloud`), the IMU
//!   (`imu`), GNSS (`gnss`, `NavSatFix`), collisions
//!   (`carla_msgs/CarlaCollisionEvent`);
//! - `/tf` (every actor's pose in `map`), `/tf_static` (sensor mounts,
//!   cameras' optical frames), each vehicle's `nav_msgs/Odometry`, and the
//!   scene as `visualization_msgs/MarkerArray` (`<namespace>/markers`);
//!
//! every message stamped with the simulation time of the frame it was
//! produced in. From ROS it takes each vehicle's control
//! ([`control`]) and, with [`Config::tick_from_ros`], the world's ticks
//! (`<namespace>/tick`, `std_msgs/Empty`: one frame each), as *the*
//! ticker under simbus's single-ticker rule.
//!
//! In synchronous mode the adapter is a lockstep participant: a frame's
//! messages are all written before the world steps past it. In
//! asynchronous mode it never holds the world back and counts the frames
//! it skipped.

mod axes;
mod bridge;
pub mod control;
mod convert;
pub mod dds;
pub mod msg;
mod outputs;
pub mod routes;
mod scene;

use std::time::Duration;

pub use bridge::{run, Bridge};
pub use routes::{Naming, Selection};

/// What to publish, where, and who ticks.
#[derive(Debug, Clone)]
pub struct Config {
    /// The DDS domain (`ROS_DOMAIN_ID`), 0..=232.
    pub domain_id: u16,
    /// How topics and frames are named.
    pub naming: Naming,
    /// What takes part (sensors, vehicles, names).
    pub selection: Selection,
    /// Claim the world's ticker and step one frame per message on the tick
    /// topic, entering synchronous mode with `delta_seconds`.
    pub tick_from_ros: bool,
    /// The fixed step while ticking from ROS.
    pub delta_seconds: f64,
    /// Every publication reliable and blocking, so that a slow DDS reader
    /// holds the world (synchronous mode) instead of missing a frame.
    pub lockstep: bool,
    /// Publish the scene's markers.
    pub markers: bool,
    /// How long to wait for the world's server and for each request.
    pub timeout: Duration,
}

impl Default for Config {
    fn default() -> Self {
        Self {
            domain_id: 0,
            naming: Naming::Simbus {
                namespace: "/simbus".into(),
            },
            selection: Selection::default(),
            tick_from_ros: false,
            delta_seconds: 0.05,
            lockstep: false,
            markers: true,
            timeout: Duration::from_secs(5),
        }
    }
}

/// What the adapter tells its caller as it runs (the CLI prints them).
#[derive(Debug, Clone, PartialEq)]
#[non_exhaustive]
pub enum Event {
    /// The node is up on `domain_id`; `clock` is the clock's topic.
    Ready {
        /// The DDS domain.
        domain_id: u16,
        /// The ROS node's name.
        node: String,
        /// Whether it is the world's ticker.
        ticker: bool,
    },
    /// A sensor's topics were created.
    Publishing {
        /// The sensor.
        sensor: u64,
        /// Its topics' prefix.
        topic: String,
    },
    /// A control message was dropped (malformed, out of range, or for a
    /// vehicle simbus refused); the vehicle keeps its last control.
    ControlDropped {
        /// The vehicle.
        vehicle: u64,
        /// Why.
        reason: String,
        /// Dropped so far, all vehicles.
        dropped: u64,
    },
    /// The world's ticker was claimed for the ROS peer ticking it.
    TickerClaimed,
    /// The world's ticker was let go: its ROS peer left.
    TickerReleased {
        /// Why.
        reason: String,
    },
}

/// What a run published, when it ends.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq)]
pub struct Published {
    /// Frames published (clock, transforms, ...).
    pub frames: u64,
    /// Frames the world made that the adapter never saw (asynchronous
    /// mode: it keeps up with the newest, and counts these).
    pub missed_frames: u64,
    /// Sensor captures published.
    pub captures: u64,
    /// Messages DDS refused to send (a full reliable window).
    pub send_failures: u64,
    /// Control messages dropped.
    pub controls_dropped: u64,
    /// Control messages applied.
    pub controls_applied: u64,
    /// Ticks taken from ROS.
    pub ticks: u64,
}

/// Why the adapter could not start or stopped.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum Ros2Error {
    /// Refused input: nothing was started.
    #[error("{0}")]
    Refused(String),
    /// A vehicle or sensor asked for is not in the world (named).
    #[error("{0}")]
    Unknown(String),
    /// DDS failed.
    #[error("ROS 2: {what}: {reason}")]
    Dds {
        /// What was being done.
        what: String,
        /// DDS's reason.
        reason: String,
    },
    /// A topic could not be made.
    #[error("ROS 2: topic {topic}: {reason}")]
    Topic {
        /// The topic.
        topic: String,
        /// Why.
        reason: String,
    },
    /// The world's server did not answer.
    #[error(transparent)]
    Connect(#[from] sim_client::ConnectError),
    /// The world's sensors could not be listed.
    #[error(transparent)]
    Sensors(#[from] sim_client::SensorError),
    /// The world's frames stopped (its server is gone).
    #[error(transparent)]
    Wait(#[from] sim_client::WaitError),
    /// The ticker could not be claimed or a tick failed (another client
    /// ticks: named).
    #[error(transparent)]
    Tick(#[from] sim_client::TickError),
    /// A request to the world's server failed (joining the lockstep, its
    /// settings).
    #[error(transparent)]
    Request(#[from] sim_client::RequestError),
    /// Synchronous mode could not be entered.
    #[error(transparent)]
    Settings(#[from] sim_client::ApplySettingsError),
}

impl Ros2Error {
    /// Whether the input was refused (nothing was started).
    pub fn is_refused(&self) -> bool {
        matches!(self, Self::Refused(_))
    }
}
