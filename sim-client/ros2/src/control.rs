//! A vehicle's control from ROS, checked before it reaches simbus: a
//! message with a value out of range (or not a number) is refused with
//! the reason, and the vehicle keeps its last control.
//!
//! Three messages drive a vehicle (`<vehicle>/…`):
//! - `control`, `std_msgs/Float32MultiArray`: `[throttle 0..1, steer
//!   -1..1 (positive left, ROS's convention), brake 0..1, hand_brake 0|1,
//!   reverse 0|1, manual_gear_shift 0|1, gear]`, the first three required;
//! - `vehicle_control_cmd`, `carla_msgs/CarlaEgoVehicleControl` (CARLA's:
//!   steer positive right);
//! - `ackermann_cmd`, `ackermann_msgs/AckermannDriveStamped`: a steering
//!   angle (radians, positive left) and a speed.

use shared_types::limits::MAX_ACKERMANN_SPEED;
use shared_types::Command;

use crate::msg::{AckermannDriveStamped, CarlaEgoVehicleControl, Float32MultiArray};

/// Why a control message was refused.
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
#[non_exhaustive]
pub enum ControlError {
    /// A value out of its range, or not a number.
    #[error("{name} {value} is outside {lo}..={hi}")]
    OutOfRange {
        /// The field.
        name: &'static str,
        /// Its value.
        value: f32,
        /// The least it may be.
        lo: f32,
        /// The most it may be.
        hi: f32,
    },
    /// A 0/1 flag of another value.
    #[error("{name} {value} is neither 0 nor 1")]
    NotAFlag {
        /// The field.
        name: &'static str,
        /// Its value.
        value: f32,
    },
    /// A gear that is not a whole number in -1..=10.
    #[error("gear {0} is not a whole number in -1..=10")]
    Gear(f32),
    /// A control array of the wrong length.
    #[error("{0} values; the control array holds 3 to 7 (throttle, steer, brake, hand_brake, reverse, manual_gear_shift, gear)")]
    Length(usize),
    /// Bytes that are not the topic's message (CDR that does not decode).
    #[error("malformed {message}: {reason}")]
    Malformed {
        /// The message expected.
        message: &'static str,
        /// The decoder's reason.
        reason: String,
    },
}

/// `value` if finite and within `lo..=hi`, else why not.
fn within(name: &'static str, value: f32, lo: f32, hi: f32) -> Result<f32, ControlError> {
    if value.is_finite() && (lo..=hi).contains(&value) {
        Ok(value)
    } else {
        Err(ControlError::OutOfRange {
            name,
            value,
            lo,
            hi,
        })
    }
}

/// A 0/1 flag.
fn flag(name: &'static str, value: f32) -> Result<bool, ControlError> {
    if value == 0.0 {
        Ok(false)
    } else if value == 1.0 {
        Ok(true)
    } else {
        Err(ControlError::NotAFlag { name, value })
    }
}

/// The controls a vehicle takes, whichever message brought them.
fn drive(
    vehicle: u64,
    (throttle, steer_left, brake): (f32, f32, f32),
    hand_brake: bool,
    reverse: bool,
) -> Result<Command, ControlError> {
    let throttle = within("throttle", throttle, 0.0, 1.0)?;
    let steer = within("steer", steer_left, -1.0, 1.0)?;
    let brake = within("brake", brake, 0.0, 1.0)?;
    Ok(Command::vehicle_control(vehicle, throttle, steer, brake, hand_brake).in_reverse(reverse))
}

/// simbus's own control array.
///
/// # Errors
///
/// The reason, naming the value, if the array holds fewer than 3 or more
/// than 7 values or one is out of range (or not a number).
pub fn from_array(vehicle: u64, message: &Float32MultiArray) -> Result<Command, ControlError> {
    let d = &message.data;
    if !(3..=7).contains(&d.len()) {
        return Err(ControlError::Length(d.len()));
    }
    let at = |i: usize| d.get(i).copied().unwrap_or(0.0);
    let hand_brake = flag("hand_brake", at(3))?;
    let reverse = flag("reverse", at(4))?;
    flag("manual_gear_shift", at(5))?;
    let gear = at(6);
    if !(gear.is_finite() && gear.fract() == 0.0 && (-1.0..=10.0).contains(&gear)) {
        return Err(ControlError::Gear(gear));
    }
    drive(vehicle, (d[0], d[1], d[2]), hand_brake, reverse)
}

/// CARLA's control message (steer positive right).
///
/// # Errors
///
/// The reason, naming the field, if one is out of range (or not a number).
pub fn from_carla(vehicle: u64, message: &CarlaEgoVehicleControl) -> Result<Command, ControlError> {
    let steer = within("steer", message.steer, -1.0, 1.0)?;
    drive(
        vehicle,
        (message.throttle, -steer, message.brake),
        message.hand_brake,
        message.reverse,
    )
}

/// An Ackermann target.
///
/// # Errors
///
/// The reason, naming the field, if one is out of range (or not a number).
pub fn from_ackermann(
    vehicle: u64,
    message: &AckermannDriveStamped,
) -> Result<Command, ControlError> {
    let d = &message.drive;
    let half_turn = std::f32::consts::FRAC_PI_2;
    let steer = within("steering_angle", d.steering_angle, -half_turn, half_turn)?;
    let steer_speed = within(
        "steering_angle_velocity",
        d.steering_angle_velocity,
        0.0,
        f32::MAX,
    )?;
    let speed = within("speed", d.speed, -MAX_ACKERMANN_SPEED, MAX_ACKERMANN_SPEED)?;
    let acceleration = within("acceleration", d.acceleration, 0.0, f32::MAX)?;
    within("jerk", d.jerk, 0.0, f32::MAX)?;
    Ok(Command::vehicle_ackermann(
        vehicle,
        steer,
        steer_speed,
        speed,
        acceleration,
    ))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn array(data: &[f32]) -> Float32MultiArray {
        Float32MultiArray {
            data: data.to_vec(),
            ..Float32MultiArray::default()
        }
    }

    #[test]
    fn a_control_array_drives_and_out_of_range_values_are_refused_by_name() {
        let command = from_array(7, &array(&[0.5, 0.25, 0.0, 0.0, 1.0])).unwrap();
        assert_eq!(command.params[..3], [0.5, 0.25, 0.0]);
        assert_eq!(command.flags & Command::REVERSE, Command::REVERSE);
        assert!(from_array(7, &array(&[2.0, 0.0, 0.0]))
            .unwrap_err()
            .to_string()
            .contains("throttle 2"));
        assert!(from_array(7, &array(&[f32::NAN, 0.0, 0.0]))
            .unwrap_err()
            .to_string()
            .contains("throttle NaN"));
        assert!(from_array(7, &array(&[0.0, 0.0]))
            .unwrap_err()
            .to_string()
            .contains("2 values"));
        assert!(from_array(7, &array(&[0.0, 0.0, 0.0, 0.5]))
            .unwrap_err()
            .to_string()
            .contains("hand_brake"));
    }

    #[test]
    fn carla_steers_right_positive_and_simbus_left_positive() {
        let carla = CarlaEgoVehicleControl {
            throttle: 1.0,
            steer: 0.5,
            ..CarlaEgoVehicleControl::default()
        };
        assert_eq!(from_carla(3, &carla).unwrap().params[1], -0.5);
    }
}
