//! ROS 2's messages as Rust types, field for field in the order of their
//! `.msg` definitions (ROS 2 Kilted), so that serde's CDR serializer writes
//! the bytes an `rclpy` node reads. The one place this crate defines a
//! foreign layout; each type names its ROS package and message.
//!
//! `uint8[]` fields are [`serde_bytes`] buffers: CDR's length and the raw
//! bytes, not one serde call per byte.

mod control;
mod geometry;
mod scene;
mod sensor;

pub use control::{
    AckermannDrive, AckermannDriveStamped, CarlaCollisionEvent, CarlaEgoVehicleControl,
    CarlaLaneInvasionEvent, Empty, Float32MultiArray, MultiArrayDimension, MultiArrayLayout,
};
pub use geometry::{
    Covariance, Odometry, Point, Pose, PoseWithCovariance, Quaternion, TfMessage, Transform,
    TransformStamped, Twist, TwistWithCovariance, Vector3,
};
pub use scene::{ColorRgba, Marker, MarkerArray, MeshFile, UvCoordinate};
pub use sensor::{
    CameraInfo, CompressedImage, Image, Imu, NavSatFix, NavSatStatus, PointCloud2, PointField,
    RegionOfInterest,
};

use serde::{Deserialize, Serialize};

/// A ROS 2 message type: its package and name (`sensor_msgs`, `Image`),
/// from which DDS's type name (`sensor_msgs::msg::dds_::Image_`) is made.
pub trait Message: Serialize + for<'de> Deserialize<'de> + 'static {
    /// The ROS package.
    const PACKAGE: &'static str;
    /// The message's name in its package.
    const NAME: &'static str;
}

/// Implements [`Message`] for each `type => package, name`.
macro_rules! messages {
    ($($ty:ty => $package:literal, $name:literal;)*) => {
        $(impl $crate::msg::Message for $ty {
            const PACKAGE: &'static str = $package;
            const NAME: &'static str = $name;
        })*
    };
}
pub(crate) use messages;

/// `builtin_interfaces/msg/Time`: seconds and nanoseconds.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Time {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds past them, `0..1_000_000_000`.
    pub nanosec: u32,
}

impl Time {
    /// The time `ns` nanoseconds after zero, exactly (seconds saturate at
    /// `i32::MAX`, 68 years of simulation).
    pub fn from_ns(ns: u64) -> Self {
        Self {
            sec: i32::try_from(ns / 1_000_000_000).unwrap_or(i32::MAX),
            nanosec: (ns % 1_000_000_000) as u32,
        }
    }

    /// Nanoseconds since zero (a negative time reads as zero).
    pub fn as_ns(&self) -> u64 {
        u64::try_from(self.sec).unwrap_or(0) * 1_000_000_000 + u64::from(self.nanosec)
    }
}

/// `builtin_interfaces/msg/Duration`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Duration {
    /// Whole seconds.
    pub sec: i32,
    /// Nanoseconds past them.
    pub nanosec: u32,
}

/// `std_msgs/msg/Header`: a stamp and a frame of reference.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Header {
    /// When the data was produced: simbus's frame time.
    pub stamp: Time,
    /// The frame the data is in.
    pub frame_id: String,
}

impl Header {
    /// A header stamped `ns` in `frame_id`.
    pub fn new(ns: u64, frame_id: &str) -> Self {
        Self {
            stamp: Time::from_ns(ns),
            frame_id: frame_id.to_owned(),
        }
    }
}

/// `rosgraph_msgs/msg/Clock`: the simulation's time, on `/clock`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Clock {
    /// The time.
    pub clock: Time,
}

messages! {
    Time => "builtin_interfaces", "Time";
    Header => "std_msgs", "Header";
    Clock => "rosgraph_msgs", "Clock";
}
