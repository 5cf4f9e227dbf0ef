//! Poses in simbus's axes (X forward, Y up, Z right; metres; unit
//! quaternions as `[x, y, z, w]`, the wire's order), on nalgebra: the one
//! place the `sim-client` binary and its adapters (CARLA gateway, Foxglove
//! view, sensor printing) compose, rotate and read orientations.
//!
//! A crate of its own, so that each adapter can use it without depending
//! on another, and the client library does not carry nalgebra.

use nalgebra::{Quaternion, UnitQuaternion, Vector3};

/// A vector as the wire carries it: `[x, y, z]`.
pub type V3 = [f32; 3];
/// A quaternion as the wire carries it: `[x, y, z, w]`.
pub type Q = [f32; 4];

/// The wire's quaternion as nalgebra's (renormalized: a wire value is
/// only nearly unit).
fn unit(q: Q) -> UnitQuaternion<f32> {
    UnitQuaternion::from_quaternion(Quaternion::new(q[3], q[0], q[1], q[2]))
}

/// nalgebra's quaternion in the wire's order.
fn wire(q: UnitQuaternion<f32>) -> Q {
    let c = q.into_inner().coords; // (i, j, k, w)
    [c[0], c[1], c[2], c[3]]
}

/// `v` rotated by `q`.
pub fn rotate(q: Q, v: V3) -> V3 {
    (unit(q) * Vector3::from(v)).into()
}

/// The product `a · b`: `b`, then `a`.
fn multiply(a: Q, b: Q) -> Q {
    wire(unit(a) * unit(b))
}

/// The world pose of something at `offset` (position, orientation) on a
/// body at `parent`.
pub fn compose(parent: (V3, Q), offset: (V3, Q)) -> (V3, Q) {
    let moved = Vector3::from(parent.0) + unit(parent.1) * Vector3::from(offset.0);
    (moved.into(), multiply(parent.1, offset.1))
}

/// The orientation whose body axes X, Y and Z point along `x`, `y` and
/// `z` (world axes; unit and orthogonal, as a rotation matrix's columns).
pub fn from_axes(x: V3, y: V3, z: V3) -> Q {
    let basis = [Vector3::from(x), Vector3::from(y), Vector3::from(z)];
    let q = UnitQuaternion::from_basis_unchecked(&basis);
    // Axes computed in f32 are only nearly orthonormal: renormalized.
    wire(UnitQuaternion::new_normalize(q.into_inner()))
}

/// The orientation of yaw about Y, then pitch about Z, then roll about X
/// (degrees; yaw outermost), as the sensor commands spell it.
pub fn from_yaw_pitch_roll(yaw: f32, pitch: f32, roll: f32) -> Q {
    let about = |axis: Vector3<f32>, deg: f32| {
        UnitQuaternion::from_axis_angle(&nalgebra::Unit::new_normalize(axis), deg.to_radians())
    };
    wire(about(Vector3::y(), yaw) * about(Vector3::z(), pitch) * about(Vector3::x(), roll))
}

/// The compass of a body at orientation `q`: radians clockwise from north,
/// in `0..2π`. North is simbus's -Z (CARLA's -y), east +X, as
/// `carla.IMUMeasurement.compass` reads it.
pub fn compass(q: Q) -> f32 {
    let forward = rotate(q, [1.0, 0.0, 0.0]);
    forward[0]
        .atan2(-forward[2])
        .rem_euclid(std::f32::consts::TAU)
}

#[cfg(test)]
mod tests {
    use super::*;

    fn close(a: &[f32], b: &[f32]) -> bool {
        a.iter().zip(b).all(|(x, y)| (x - y).abs() < 1e-5)
    }

    #[test]
    fn a_quarter_turn_about_up_turns_forward_to_the_left() {
        let yaw = from_yaw_pitch_roll(90.0, 0.0, 0.0);
        // +90° about Y (up) takes X (forward) to -Z (left of forward).
        assert!(close(&rotate(yaw, [1.0, 0.0, 0.0]), &[0.0, 0.0, -1.0]));
        // North is -Z: facing +X is east, +Z south, -X west.
        let identity = [0.0, 0.0, 0.0, 1.0];
        assert!(close(&[compass(identity)], &[std::f32::consts::FRAC_PI_2]));
        let south = from_yaw_pitch_roll(-90.0, 0.0, 0.0);
        assert!(close(&[compass(south)], &[std::f32::consts::PI]));
        let west = from_yaw_pitch_roll(180.0, 0.0, 0.0);
        assert!(close(
            &[compass(west)],
            &[3.0 * std::f32::consts::FRAC_PI_2]
        ));
    }

    #[test]
    fn composing_applies_the_offset_in_the_parents_frame() {
        let parent = ([1.0, 2.0, 3.0], from_yaw_pitch_roll(90.0, 0.0, 0.0));
        let offset = ([2.0, 0.0, 0.0], from_yaw_pitch_roll(0.0, 0.0, 0.0));
        let (position, rotation) = compose(parent, offset);
        assert!(close(&position, &[1.0, 2.0, 1.0]));
        assert!(close(&rotation, &parent.1));
        // Yaw, then pitch, then roll multiply in that order.
        let q = from_yaw_pitch_roll(30.0, 20.0, 10.0);
        let steps = multiply(
            multiply(
                from_yaw_pitch_roll(30.0, 0.0, 0.0),
                from_yaw_pitch_roll(0.0, 20.0, 0.0),
            ),
            from_yaw_pitch_roll(0.0, 0.0, 10.0),
        );
        assert!(close(&q, &steps));
    }

    #[test]
    fn axes_give_the_orientation_that_turns_the_body_onto_them() {
        // Forward along -Z, up along Y, right along X: a quarter turn left.
        let q = from_axes([0.0, 0.0, -1.0], [0.0, 1.0, 0.0], [1.0, 0.0, 0.0]);
        assert!(close(&q, &from_yaw_pitch_roll(90.0, 0.0, 0.0)));
        let identity = from_axes([1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, 1.0]);
        assert!(close(&identity, &[0.0, 0.0, 0.0, 1.0]));
    }
}
