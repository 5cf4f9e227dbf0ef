//! simbus frames (X forward, Y up, Z right; right-handed; radians,
//! quaternions) to CARLA's (x forward, y right, z up; left-handed; degrees,
//! pitch/yaw/roll in Unreal's convention) and back.

use shared_types::ActorState;
pub(crate) use simbus_pose::{compass, compose};
use simbus_pose::{from_axes, rotate};

use crate::wire::{CarlaActorState, CarlaTransform};

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

/// Unreal's (pitch, yaw, roll) in degrees as a simbus orientation
/// (quaternion x, y, z, w): the inverse of [`rotation`].
pub(crate) fn quaternion(pitch_yaw_roll: V3) -> [f32; 4] {
    let [p, y, r] = pitch_yaw_roll.map(f32::to_radians);
    let (sp, cp, sy, cy, sr, cr) = (p.sin(), p.cos(), y.sin(), y.cos(), r.sin(), r.cos());
    // Unreal's FRotationMatrix: the body's axes in CARLA's world axes.
    let forward = [cp * cy, cp * sy, sp];
    let right = [sr * sp * cy - cr * sy, sr * sp * sy + cr * cy, -sr * cp];
    let up = [-(cr * sp * cy + sr * sy), cy * sr - cr * sp * sy, cr * cp];
    // simbus body axes X (forward), Y (up), Z (right) in simbus world axes.
    from_axes(vector(forward), vector(up), vector(right))
}

/// A CARLA transform as a simbus pose.
pub(crate) fn pose(t: &CarlaTransform) -> (V3, [f32; 4]) {
    (vector(t.location), quaternion(t.rotation))
}

/// A CARLA angular velocity (deg/s) as simbus's (rad/s).
pub(crate) fn angular_velocity_from_carla(w: V3) -> V3 {
    let [x, y, z] = vector(w);
    [-x.to_radians(), -y.to_radians(), -z.to_radians()]
}

/// A simbus pose as a CARLA transform.
pub(crate) fn transform(position: V3, q: [f32; 4]) -> CarlaTransform {
    CarlaTransform {
        location: vector(position),
        rotation: rotation(q),
    }
}

/// A simbus actor id as CARLA's (32 bits; ids past them read as the last).
pub(crate) fn actor_id(id: u64) -> u32 {
    u32::try_from(id).unwrap_or(u32::MAX)
}

/// An actor's state as CARLA's world state carries it.
pub(crate) fn actor(state: &ActorState) -> CarlaActorState {
    CarlaActorState {
        id: actor_id(state.id),
        transform: transform(state.position, state.rotation),
        velocity: vector(state.linear_velocity),
        angular_velocity: angular_velocity(state.angular_velocity),
        acceleration: vector(state.acceleration),
        ..CarlaActorState::default()
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

    #[test]
    fn carla_rotations_round_trip() {
        for pyr in [
            [0.0, 0.0, 0.0],
            [0.0, -90.0, 0.0],
            [30.0, 0.0, 0.0],
            [0.0, 0.0, 45.0],
            [-20.0, 135.0, 10.0],
            [60.0, -170.0, -80.0],
        ] {
            let back = rotation(quaternion(pyr));
            assert!(close(back, pyr), "{pyr:?} came back as {back:?}");
        }
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let q = quaternion([0.0, -90.0, 0.0]);
        assert!(close([q[0], q[1], q[2]], [0.0, h, 0.0]) && (q[3] - h).abs() < 1e-3);
    }

    #[test]
    fn a_sensor_on_a_turned_body_sits_turned_with_it() {
        // A body yawed 90° left (simbus +Y); a sensor 1 m ahead of it.
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let body = ([10.0, 0.0, 0.0], [0.0, h, 0.0, h]);
        let (position, q) = compose(body, ([1.0, 0.0, 0.0], [0.0, 0.0, 0.0, 1.0]));
        // Ahead of the body is -Z (left of simbus's forward).
        assert!(close(position, [10.0, 0.0, -1.0]));
        assert!(close(rotation(q), [0.0, -90.0, 0.0]));
        // Facing CARLA's west (-x) reads 270°, north (-y) 0.
        assert!((compass(quaternion([0.0, 180.0, 0.0])) - 1.5 * std::f32::consts::PI).abs() < 1e-3);
        let north = compass(quaternion([0.0, -90.0, 0.0]));
        assert!(north.min(std::f32::consts::TAU - north) < 1e-3, "{north}");
    }
}
