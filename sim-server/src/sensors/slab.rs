//! The cameras' fast path: a pixel grid's rays worked out by additions,
//! and a box met by the slab test in the box's own frame, with the face the
//! ray enters through.
//!
//! A camera's rays share their origin and sweep the image row by row, so
//! in any frame fixed to the capture (the world's, or a box's) pixel (u,
//! v)'s unnormalised direction is a row's vector plus `right(u)` times a
//! column step: three multiply-adds, where a rotation per ray and per box
//! took a quaternion product each. The slab test is parry's
//! (`Aabb::cast_local_ray`) on that unnormalised direction, so its time of
//! impact is in units of the ray's length; the distance is that time the
//! length. The face it returns gives the normal without a second cast.

use rapier3d::prelude::{Rotation, Vector};

/// A pinhole camera's rays in one frame: pixel (u, v), looking along
/// (focal, up, right) in the camera frame, leaves along the unnormalised
/// [`Grid::ray`]`(`[`Grid::row`]`(up), right)`.
#[derive(Debug, Clone, Copy)]
pub(super) struct Grid {
    forward: Vector,
    upward: Vector,
    across: Vector,
}

impl Grid {
    /// The rays of a camera whose frame is rotated by `rotation` from this
    /// one, with focal length `focal` (pixels).
    pub(super) fn new(rotation: Rotation, focal: f32) -> Self {
        Self {
            forward: rotation * (Vector::X * focal),
            upward: rotation * Vector::Y,
            across: rotation * Vector::Z,
        }
    }

    /// The row of pixels `up` above the image's centre.
    pub(super) fn row(&self, up: f32) -> Vector {
        self.forward + self.upward * up
    }

    /// The ray of the pixel `right` of the centre on `row`.
    pub(super) fn ray(&self, row: Vector, right: f32) -> Vector {
        row + self.across * right
    }
}

/// Which face of a box a ray enters through: `+k` the face at the box's
/// maximum along axis `k − 1`, `−k` the one at its minimum, 0 none (the
/// ray starts inside).
pub(super) type Face = i8;

/// A box of half extents `h` seen from a point `o` of its own frame: the
/// slab test's per-capture constants.
#[derive(Debug, Clone, Copy)]
pub(super) struct Slab {
    /// The camera's rays in the box's frame.
    pub(super) grid: Grid,
    /// `−h − o` and `h − o`: the box's faces as seen from the origin.
    low: Vector,
    high: Vector,
}

impl Slab {
    /// The box of half extents `half` met from `origin` (both in the box's
    /// frame) by a camera's rays `grid` (in the box's frame).
    pub(super) fn new(half: Vector, origin: Vector, grid: Grid) -> Self {
        Self {
            grid,
            low: -half - origin,
            high: half - origin,
        }
    }

    /// Where the ray along `direction` (this box's frame, any length) first
    /// meets the box within `max` (in units of the direction's length),
    /// and the face it enters through: parry's solid `Aabb::cast_local_ray`.
    pub(super) fn cast(&self, direction: Vector, max: f32) -> Option<(f32, Face)> {
        let (mut near, mut far, mut face) = (0.0f32, max, 0);
        for axis in 0..3 {
            let d = direction[axis];
            let (low, high) = (self.low[axis], self.high[axis]);
            if d == 0.0 {
                if low > 0.0 || high < 0.0 {
                    return None;
                }
                continue;
            }
            let inverse = 1.0 / d;
            let (mut enter, mut leave) = (low * inverse, high * inverse);
            // Entering through the low face unless the ray runs backwards.
            let mut entered = -(axis as Face + 1);
            if enter > leave {
                std::mem::swap(&mut enter, &mut leave);
                entered = -entered;
            }
            if enter > near {
                near = enter;
                face = entered;
            }
            far = far.min(leave);
            if near > far {
                return None;
            }
        }
        Some((near, face))
    }
}

/// The unit normal, in the box's frame, of `face` (zero for none).
pub(super) fn normal(face: Face) -> Vector {
    let mut n = Vector::ZERO;
    if face != 0 {
        n[usize::from(face.unsigned_abs()) - 1] = f32::from(face.signum());
    }
    n
}

#[cfg(test)]
mod tests {
    use super::*;
    use rapier3d::parry::query::{Ray, RayCast};
    use rapier3d::parry::shape::Cuboid;

    #[test]
    fn the_slab_test_meets_a_box_where_parry_does_through_the_face_parry_names() {
        let half = Vector::new(1.0, 0.5, 2.0);
        let cuboid = Cuboid::new(half);
        let mut checked = 0;
        for i in 0..4000 {
            let a = i as f32 * 0.731;
            let origin = Vector::new(3.0 * a.sin(), 2.0 * (a * 1.7).cos(), 4.0 * (a * 0.3).sin());
            let direction = Vector::new((a * 2.3).cos(), (a * 0.9).sin(), (a * 1.3).cos()) * 2.5;
            let unit = direction.normalize();
            let want = cuboid.cast_local_ray_and_get_normal(&Ray::new(origin, unit), 100.0, true);
            let slab = Slab::new(half, origin, Grid::new(Rotation::IDENTITY, 1.0));
            let got = slab.cast(direction, 100.0 / direction.length());
            assert_eq!(got.is_some(), want.is_some(), "{origin:?} {direction:?}");
            let (Some((time, face)), Some(want)) = (got, want) else {
                continue;
            };
            let distance = time * direction.length();
            assert!(
                (distance - want.time_of_impact).abs() <= 1e-5 * (1.0 + distance),
                "{distance} against {}",
                want.time_of_impact
            );
            if want.time_of_impact > 0.0 {
                assert!((normal(face) - want.normal).length() < 1e-6, "{face}");
                checked += 1;
            } else {
                assert_eq!(face, 0, "inside the box no face is entered");
            }
        }
        assert!(checked > 100, "only {checked} hits from outside");
    }

    #[test]
    fn a_grid_s_rays_are_the_rotated_camera_directions() {
        let rotation = Rotation::from_euler(rapier3d::glamx::EulerRot::YXZ, 0.7, -0.3, 0.1);
        let grid = Grid::new(rotation, 400.0);
        for (up, right) in [(0.0, 0.0), (299.5, -399.5), (-12.5, 250.5)] {
            let want = rotation * Vector::new(400.0, up, right);
            let got = grid.ray(grid.row(up), right);
            assert!((got - want).length() < 1e-3, "{got:?} against {want:?}");
        }
    }
}
