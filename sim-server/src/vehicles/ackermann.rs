//! CARLA's Ackermann control: a steering angle reached at a steering
//! speed, and a speed (negative: backwards) reached at an acceleration,
//! turned every physics step into the throttle, steer, brake and gear the
//! vehicle's controller takes. The speed loop is proportional: the
//! acceleration asked for is the speed error over [`SPEED_TIME`], bounded
//! by the acceleration given and by what the engine and brakes can do.

use serde::{Deserialize, Serialize};

/// The time the speed loop closes an error in, seconds.
const SPEED_TIME: f32 = 0.5;
/// Below this speed, m/s, a target of zero holds the vehicle on its
/// brakes.
const STANDSTILL: f32 = 0.1;

/// One vehicle's Ackermann target and how far its steering has turned.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub(crate) struct Ackermann {
    pub(crate) actor: u64,
    /// The steering angle wanted, radians, positive left.
    steer: f32,
    /// How fast the steering turns to it, rad/s (0: at once).
    steer_speed: f32,
    /// The speed wanted, m/s along the vehicle (negative: backwards).
    speed: f32,
    /// The most acceleration to get there with, m/s² (0: all there is).
    acceleration: f32,
    /// The steering angle reached.
    steering: f32,
}

/// The control that drives a vehicle toward its target for one step.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Drive {
    pub(crate) throttle: f32,
    /// -1..=1 of the vehicle's steer, positive left.
    pub(crate) steer: f32,
    pub(crate) brake: f32,
    pub(crate) reverse: bool,
}

impl Ackermann {
    /// A target for `actor` (values checked by the caller), its steering
    /// starting where `steering` (radians) is.
    pub(crate) fn new(
        actor: u64,
        [steer, steer_speed, speed, acceleration]: [f32; 4],
        steering: f32,
    ) -> Self {
        Self {
            actor,
            steer,
            steer_speed,
            speed,
            acceleration,
            steering,
        }
    }

    /// The control for a step of `dt` seconds of a vehicle going
    /// `forward_speed` m/s, whose steer turns its wheels `max_steer`
    /// radians and whose full throttle and full brake accelerate it by
    /// `full_throttle` and `full_brake` m/s²; turns the steering on.
    pub(crate) fn drive(
        &mut self,
        forward_speed: f32,
        max_steer: f32,
        full_throttle: f32,
        full_brake: f32,
        dt: f32,
    ) -> Drive {
        let turn = self.steer - self.steering;
        self.steering = if self.steer_speed > 0.0 {
            self.steering + turn.clamp(-self.steer_speed * dt, self.steer_speed * dt)
        } else {
            self.steer
        };
        let steer = (self.steering / max_steer.max(1e-3)).clamp(-1.0, 1.0);
        if self.speed == 0.0 && forward_speed.abs() < STANDSTILL {
            return Drive {
                throttle: 0.0,
                steer,
                brake: 1.0,
                reverse: false,
            };
        }
        let limit = if self.acceleration > 0.0 {
            self.acceleration
        } else {
            f32::INFINITY
        };
        let wanted = ((self.speed - forward_speed) / SPEED_TIME).clamp(-limit, limit);
        // Backwards, the engine pushes the other way; either way, a wanted
        // acceleration against the travel is braking.
        let reverse = self.speed < 0.0;
        let push = if reverse { -wanted } else { wanted };
        let moving_with_target = forward_speed * self.speed.signum() >= -STANDSTILL;
        if push >= 0.0 && moving_with_target {
            Drive {
                throttle: (push / full_throttle.max(1e-3)).clamp(0.0, 1.0),
                steer,
                brake: 0.0,
                reverse,
            }
        } else {
            Drive {
                throttle: 0.0,
                steer,
                brake: (wanted.abs() / full_brake.max(1e-3)).clamp(0.0, 1.0),
                reverse,
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn target(speed: f32, acceleration: f32) -> Ackermann {
        Ackermann::new(1, [0.2, 0.0, speed, acceleration], 0.0)
    }

    #[test]
    fn below_its_speed_it_throttles_above_it_brakes_and_at_zero_it_holds() {
        let d = target(10.0, 0.0).drive(5.0, 0.5, 3.5, 8.0, 0.01);
        assert_eq!((d.throttle, d.brake, d.reverse), (1.0, 0.0, false));
        assert!((d.steer - 0.4).abs() < 1e-6);
        let d = target(10.0, 1.0).drive(5.0, 0.5, 3.5, 8.0, 0.01);
        assert!((d.throttle - 1.0 / 3.5).abs() < 1e-6, "{d:?}");
        let d = target(5.0, 0.0).drive(6.0, 0.5, 3.5, 8.0, 0.01);
        assert!(d.throttle == 0.0 && (d.brake - 0.25).abs() < 1e-6, "{d:?}");
        let d = target(0.0, 0.0).drive(0.05, 0.5, 3.5, 8.0, 0.01);
        assert_eq!((d.throttle, d.brake), (0.0, 1.0));
        // Backwards: the reverse gear; still rolling forwards, brakes first.
        let d = target(-3.0, 0.0).drive(0.0, 0.5, 3.5, 8.0, 0.01);
        assert!(d.reverse && d.throttle > 0.0 && d.brake == 0.0, "{d:?}");
        let d = target(-3.0, 0.0).drive(4.0, 0.5, 3.5, 8.0, 0.01);
        assert!(d.throttle == 0.0 && d.brake > 0.0, "{d:?}");
    }

    #[test]
    fn the_steering_turns_at_its_speed() {
        let mut a = Ackermann::new(1, [0.4, 1.0, 0.0, 0.0], 0.0);
        let first = a.drive(0.0, 0.5, 3.5, 8.0, 0.1);
        assert!((first.steer - 0.2).abs() < 1e-6, "{first:?}");
        for _ in 0..10 {
            a.drive(0.0, 0.5, 3.5, 8.0, 0.1);
        }
        assert!((a.steering - 0.4).abs() < 1e-6);
    }
}
