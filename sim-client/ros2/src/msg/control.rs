//! What ROS sends simbus (vehicle control, ticks) and CARLA's own event
//! layouts (`carla_msgs`, which CARLA's ROS users already read).

use serde::{Deserialize, Serialize};

use super::{messages, Header, Vector3};

/// `std_msgs/msg/Empty`: CDR writes an empty structure as one byte
/// (rosidl's `structure_needs_at_least_one_field`). One tick per message.
#[derive(Debug, Clone, Copy, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct Empty {
    /// Always 0.
    pub structure_needs_at_least_one_field: u8,
}

/// `std_msgs/msg/MultiArrayDimension`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MultiArrayDimension {
    /// Its name.
    pub label: String,
    /// Elements.
    pub size: u32,
    /// Stride.
    pub stride: u32,
}

/// `std_msgs/msg/MultiArrayLayout`.
#[derive(Debug, Clone, Default, PartialEq, Eq, Serialize, Deserialize)]
pub struct MultiArrayLayout {
    /// Dimensions (ignored: the data is read flat).
    pub dim: Vec<MultiArrayDimension>,
    /// Elements before the data (ignored).
    pub data_offset: u32,
}

/// `std_msgs/msg/Float32MultiArray`: simbus's own control topic reads
/// `[throttle, steer, brake, hand_brake, reverse, manual_gear_shift,
/// gear]` from its data (at least the first three; the book's ROS 2
/// chapter documents it).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct Float32MultiArray {
    /// The layout.
    pub layout: MultiArrayLayout,
    /// The values.
    pub data: Vec<f32>,
}

/// `ackermann_msgs/msg/AckermannDrive`.
#[derive(Debug, Clone, Copy, Default, PartialEq, Serialize, Deserialize)]
pub struct AckermannDrive {
    /// Radians, positive left.
    pub steering_angle: f32,
    /// Radians per second (0: at once).
    pub steering_angle_velocity: f32,
    /// Metres per second, negative backwards.
    pub speed: f32,
    /// Metres per second squared (0: as hard as it can).
    pub acceleration: f32,
    /// Metres per second cubed (accepted, not followed).
    pub jerk: f32,
}

/// `ackermann_msgs/msg/AckermannDriveStamped`.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct AckermannDriveStamped {
    /// Stamp and frame (not read).
    pub header: Header,
    /// The target.
    pub drive: AckermannDrive,
}

/// `carla_msgs/msg/CarlaEgoVehicleControl`: CARLA's control of a vehicle,
/// in CARLA's convention (steer positive to the right).
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CarlaEgoVehicleControl {
    /// Stamp and frame (not read).
    pub header: Header,
    /// 0..1.
    pub throttle: f32,
    /// -1..1, positive right.
    pub steer: f32,
    /// 0..1.
    pub brake: f32,
    /// Hand brake on.
    pub hand_brake: bool,
    /// Reverse gear.
    pub reverse: bool,
    /// The gear, with `manual_gear_shift`.
    pub gear: i32,
    /// Whether `gear` is used.
    pub manual_gear_shift: bool,
}

/// `carla_msgs/msg/CarlaCollisionEvent`: a collision sensor's parent hit
/// another actor.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CarlaCollisionEvent {
    /// The frame's time and the sensor's frame.
    pub header: Header,
    /// The other actor.
    pub other_actor_id: u32,
    /// The contact's impulse, N·s, in `map`.
    pub normal_impulse: Vector3,
}

/// `carla_msgs/msg/CarlaLaneInvasionEvent`: lane markings crossed.
#[derive(Debug, Clone, Default, PartialEq, Serialize, Deserialize)]
pub struct CarlaLaneInvasionEvent {
    /// The frame's time and the sensor's frame.
    pub header: Header,
    /// CARLA's `LaneMarkingType` codes of the markings crossed.
    pub crossed_lane_markings: Vec<i32>,
}

messages! {
    Empty => "std_msgs", "Empty";
    Float32MultiArray => "std_msgs", "Float32MultiArray";
    AckermannDriveStamped => "ackermann_msgs", "AckermannDriveStamped";
    CarlaEgoVehicleControl => "carla_msgs", "CarlaEgoVehicleControl";
    CarlaCollisionEvent => "carla_msgs", "CarlaCollisionEvent";
    CarlaLaneInvasionEvent => "carla_msgs", "CarlaLaneInvasionEvent";
}
