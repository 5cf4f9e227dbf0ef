//! simbus's axes (X forward, Y up, Z right) to ROS's (REP 103: X forward,
//! Y left, Z up; both right-handed): `(x, y, z)` → `(x, -z, y)`, and a
//! quaternion's vector part the same way.

use crate::msg::{Point, Quaternion, Vector3};

/// A vector (position, velocity, force) in ROS's axes, as `[x, y, z]`.
pub(crate) fn vector(v: [f32; 3]) -> [f64; 3] {
    [f64::from(v[0]), -f64::from(v[2]), f64::from(v[1])]
}

/// A vector in ROS's axes as `geometry_msgs/Vector3`.
pub(crate) fn vector3(v: [f32; 3]) -> Vector3 {
    let [x, y, z] = vector(v);
    Vector3 { x, y, z }
}

/// A position in ROS's axes as `geometry_msgs/Point`.
pub(crate) fn point(v: [f32; 3]) -> Point {
    let [x, y, z] = vector(v);
    Point { x, y, z }
}

/// An orientation (`[x, y, z, w]`, simbus's axes) in ROS's axes; a zero
/// quaternion (a spec with no rotation given) is the identity.
pub(crate) fn quaternion(q: [f32; 4]) -> Quaternion {
    if q == [0.0; 4] {
        return Quaternion::default();
    }
    Quaternion {
        x: f64::from(q[0]),
        y: -f64::from(q[2]),
        z: f64::from(q[1]),
        w: f64::from(q[3]),
    }
}

/// The rotation from a camera's body frame (ROS axes: X forward, Y left,
/// Z up) to its optical frame (REP 103's `_optical`: Z forward, X right,
/// Y down), as the optical frame's orientation in the body frame.
pub(crate) const OPTICAL: Quaternion = Quaternion {
    x: -0.5,
    y: 0.5,
    z: -0.5,
    w: 0.5,
};

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn up_is_z_and_right_is_minus_y() {
        assert_eq!(vector([1.0, 2.0, 3.0]), [1.0, -3.0, 2.0]);
    }

    #[test]
    fn a_quarter_turn_left_about_up_stays_a_quarter_turn_left() {
        // simbus: a yaw of +90 degrees about Y (up) turns X (forward) to
        // -Z (left); in ROS it is +90 degrees about Z.
        let h = std::f32::consts::FRAC_1_SQRT_2;
        let q = quaternion([0.0, h, 0.0, h]);
        assert!((q.z - f64::from(h)).abs() < 1e-9 && q.x == 0.0 && q.y == 0.0);
    }

    #[test]
    fn the_optical_frame_looks_along_x_with_x_right_and_y_down() {
        // Rotate the optical axes into the body frame: optical Z (view)
        // must be body X, optical X body -Y (right), optical Y body -Z.
        let rotate = |v: [f64; 3]| {
            let Quaternion { x, y, z, w } = OPTICAL;
            let (u, s) = ([x, y, z], w);
            let dot = u[0] * v[0] + u[1] * v[1] + u[2] * v[2];
            let cross = [
                u[1] * v[2] - u[2] * v[1],
                u[2] * v[0] - u[0] * v[2],
                u[0] * v[1] - u[1] * v[0],
            ];
            let uu = u[0] * u[0] + u[1] * u[1] + u[2] * u[2];
            std::array::from_fn::<f64, 3, _>(|i| {
                2.0 * dot * u[i] + (s * s - uu) * v[i] + 2.0 * s * cross[i]
            })
        };
        let close = |a: [f64; 3], b: [f64; 3]| a.iter().zip(b).all(|(a, b)| (a - b).abs() < 1e-9);
        assert!(close(rotate([0.0, 0.0, 1.0]), [1.0, 0.0, 0.0]));
        assert!(close(rotate([1.0, 0.0, 0.0]), [0.0, -1.0, 0.0]));
        assert!(close(rotate([0.0, 1.0, 0.0]), [0.0, 0.0, -1.0]));
    }
}
