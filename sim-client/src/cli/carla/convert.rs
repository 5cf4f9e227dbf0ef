//! simbus frames (X forward, Y up, Z right; right-handed; radians,
//! quaternions) to CARLA's (x forward, y right, z up; left-handed; degrees,
//! pitch/yaw/roll in Unreal's convention) and back.

use shared_types::carla::{CarlaActorState, CarlaTransform};
use shared_types::ActorState;

type V3 = [f32; 3];

/// A simbus vector in CARLA's axes.
pub(crate) fn vector(v: V3) -> V3 {
    [v[0], v[2], v[1]]
}

/// A simbus angular velocity (rad/s) in CARLA's axes and units (deg/s):
/// swapping two axes flips a pseudo-vector's sign.
pub(crate) fn angular_velocity(w: V3) -> V3 {
    let [x, y, z] = vector(w);
    [-x.to_degrees(), -y.to_degrees(), -z.to_degrees()]
}

/// `v` rotated by the unit quaternion `q` (x, y, z, w).
fn rotate(q: [f32; 4], v: V3) -> V3 {
    let [qx, qy, qz, qw] = q;
    let u = [qx, qy, qz];
    let cross = |a: V3, b: V3| {
        [
            a[1] * b[2] - a[2] * b[1],
            a[2] * b[0] - a[0] * b[2],
            a[0] * b[1] - a[1] * b[0],
        ]
    };
    let t = cross(u, v).map(|c| 2.0 * c);
    let ut = cross(u, t);
    [0, 1, 2].map(|i| v[i] + qw * t[i] + ut[i])
}

/// A simbus orientation as Unreal's (pitch, yaw, roll) in degrees.
pub(crate) fn rotation(q: [f32; 4]) -> V3 {
    // The body's forward, right and up axes in CARLA's world axes.
    let forward = vector(rotate(q, [1.0, 0.0, 0.0]));
    let up = vector(rotate(q, [0.0, 1.0, 0.0]));
    let right = vector(rotate(q, [0.0, 0.0, 1.0]));
    let pitch = forward[2].atan2((forward[0] * forward[0] + forward[1] * forward[1]).sqrt());
    let yaw = forward[1].atan2(forward[0]);
    // Unreal's FMatrix::Rotator: roll from the un-rolled right axis.
    let unrolled_right = [-yaw.sin(), yaw.cos(), 0.0];
    let dot = |a: V3, b: V3| a[0] * b[0] + a[1] * b[1] + a[2] * b[2];
    let roll = dot(up, unrolled_right).atan2(dot(right, unrolled_right));
    [pitch.to_degrees(), yaw.to_degrees(), roll.to_degrees()]
}

/// A simbus pose as a CARLA transform.
pub(crate) fn transform(position: V3, q: [f32; 4]) -> CarlaTransform {
    CarlaTransform {
        location: vector(position),
        rotation: rotation(q),
    }
}

/// An actor's state as CARLA's world state carries it.
pub(crate) fn actor(state: &ActorState) -> CarlaActorState {
    CarlaActorState {
        id: u32::try_from(state.id).unwrap_or(u32::MAX),
        transform: transform(state.position, state.rotation),
        velocity: vector(state.linear_velocity),
        angular_velocity: angular_velocity(state.angular_velocity),
        acceleration: vector(state.acceleration),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: V3, b: V3) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-3)
    }

    #[test]
    fn axes_map_to_carla() {
        // 1 m forward, 2 m up, 3 m right.
        assert_eq!(vector([1.0, 2.0, 3.0]), [1.0, 3.0, 2.0]);
        assert!(close(rotation([0.0, 0.0, 0.0, 1.0]), [0.0, 0.0, 0.0]));
        // simbus yaw +90° (about Y, positive turns left) is CARLA yaw -90°.
        let h = std::f32::consts::FRAC_1_SQRT_2;
        assert!(close(rotation([0.0, h, 0.0, h]), [0.0, -90.0, 0.0]));
        // Nose up 30° (about simbus Z) is CARLA pitch +30°.
        let (s, c) = (15f32.to_radians().sin(), 15f32.to_radians().cos());
        assert!(close(rotation([0.0, 0.0, s, c]), [30.0, 0.0, 0.0]));
    }
}
