//! Culling for sensors whose rays all leave one point.
//!
//! A query through rapier's pipeline walks the scene's BVH from the root for
//! every ray (~110 ns per ray per core here). A camera's or a lidar's rays
//! share their origin, so the culling can be done once per capture instead:
//! each collider's oriented bounding box is projected onto a view's image
//! plane, and a ray is cast only against the shapes whose projection can
//! hold it — with the same parry `Shape::cast_ray` the pipeline calls, the
//! nearest hit kept, so the result is the pipeline's, bit for bit (the
//! lidar's tests hold it so). The cameras meet boxes with the same slab
//! test on rays added up per row (`slab`): the pipeline's surfaces, to
//! within rounding (the camera's test holds it so).

use std::ops::RangeInclusive;

use rapier3d::prelude::{Aabb, Pose, Ray, RigidBodyHandle, Rotation, Shape, Vector};
use shared_types::{ActorKind, LightState};

use super::slab::{self, Face, Grid, Slab};
use crate::world::World;

/// A pinhole view from the sensor's origin: a point `q` in the sensor frame
/// is at `forward = q·F`, and at `right/forward`, `up/forward` on its image
/// plane (`R`, `U` the view's other axes).
#[derive(Debug, Clone, Copy)]
pub(super) struct View {
    /// Forward, up, right, in the sensor frame (right = forward × up).
    axes: [Vector; 3],
    /// The smallest forward component of any unit ray the view serves.
    least_forward: f32,
}

/// The sensor frame's own axes as a view: +X forward, +Y up, +Z right.
const FORWARD_X: [Vector; 3] = [Vector::X, Vector::Y, Vector::Z];

/// The six faces of a cube around the sensor, each a view of 90° by 90°:
/// every direction is served by the face of its largest component.
const CUBE: [[Vector; 3]; 6] = [
    FORWARD_X,
    [Vector::NEG_X, Vector::Y, Vector::NEG_Z],
    [Vector::Y, Vector::NEG_X, Vector::Z],
    [Vector::NEG_Y, Vector::X, Vector::Z],
    [Vector::Z, Vector::Y, Vector::NEG_X],
    [Vector::NEG_Z, Vector::Y, Vector::X],
];

/// Where on a view's image plane a shape can be met: `right/forward` and
/// `up/forward` of every point of it a ray can reach lie in these ranges.
#[derive(Debug, Clone, PartialEq)]
pub(super) struct Bounds {
    pub(super) right: RangeInclusive<f32>,
    pub(super) up: RangeInclusive<f32>,
}

impl Bounds {
    const WHOLE: Bounds = Bounds {
        right: f32::NEG_INFINITY..=f32::INFINITY,
        up: f32::NEG_INFINITY..=f32::INFINITY,
    };

    pub(super) fn contains(&self, right: f32, up: f32) -> bool {
        self.right.contains(&right) && self.up.contains(&up)
    }
}

impl View {
    /// A camera looking along the sensor's +X with the given largest
    /// image-plane offsets (half the image over the focal length).
    pub(super) fn camera(half_width: f32, half_height: f32) -> Self {
        Self {
            axes: FORWARD_X,
            least_forward: 1.0 / Vector::new(1.0, half_height, half_width).length(),
        }
    }

    /// Face `i` of the cube around the sensor.
    fn face(i: usize) -> Self {
        Self {
            axes: CUBE[i],
            least_forward: 1.0 / 3f32.sqrt(),
        }
    }

    /// `q` (sensor frame) as (forward, up, right) in this view.
    fn coordinates(&self, q: Vector) -> Vector {
        let [f, u, r] = self.axes;
        Vector::new(q.dot(f), q.dot(u), q.dot(r))
    }

    /// Where a shape with local bounding box `local` at `at` can be met
    /// within `far` by this view's rays from `sensor`; `None` when it is out
    /// of view or out of range.
    ///
    /// The box is oriented with its shape, so a rotated ramp's bounds are the
    /// ramp's. A point of the box is at least `near` (the box's distance from
    /// the sensor) away, so a ray can only meet it where the point's forward
    /// coordinate is at least `near × least_forward`: the box is clipped to
    /// that half-space, and its remaining corners and edge crossings bound
    /// it on the image plane, widened by a rounding margin. The whole plane
    /// when the sensor is inside the box.
    fn bounds(&self, sensor: &Pose, at: &Pose, local: &Aabb, far: f32) -> Option<Bounds> {
        let origin = at.inverse_transform_point(sensor.translation);
        let near = origin.clamp(local.mins, local.maxs).distance(origin);
        if near > far {
            return None;
        }
        if near <= 0.0 {
            return Some(Bounds::WHOLE);
        }
        let clip = near * self.least_forward * 0.999;
        let corners = local
            .vertices()
            .map(|c| self.coordinates(sensor.inverse_transform_point(at.transform_point(c))));
        let mut right = (f32::MAX, f32::MIN);
        let mut up = (f32::MAX, f32::MIN);
        let mut project = |c: Vector| {
            let (r, u) = (c.z / c.x, c.y / c.x);
            right = (right.0.min(r), right.1.max(r));
            up = (up.0.min(u), up.1.max(u));
        };
        for &c in corners.iter().filter(|c| c.x >= clip) {
            project(c);
        }
        // Where an edge crosses the clip plane, the crossing is a corner of
        // the clipped box.
        for (i, j) in BOX_EDGES {
            let (a, b) = (corners[i], corners[j]);
            if (a.x < clip) != (b.x < clip) {
                project(a + (b - a) * ((clip - a.x) / (b.x - a.x)));
            }
        }
        if right.0 > right.1 {
            return None; // nothing in front of the clip plane
        }
        let widen = |(low, high): (f32, f32)| {
            let margin = 1e-4 * (1.0 + low.abs().max(high.abs()));
            low - margin..=high + margin
        };
        Some(Bounds {
            right: widen(right),
            up: widen(up),
        })
    }
}

/// The twelve edges of a box, as pairs of corners in parry's
/// `Aabb::vertices` order: the face at `mins.z`, the face at `maxs.z`, and
/// the four edges between them.
const BOX_EDGES: [(usize, usize); 12] = [
    (0, 1),
    (1, 2),
    (2, 3),
    (3, 0),
    (4, 5),
    (5, 6),
    (6, 7),
    (7, 4),
    (0, 4),
    (1, 5),
    (2, 6),
    (3, 7),
];

/// A collider a view may see, and where.
pub(super) struct Target<'a> {
    shape: &'a dyn Shape,
    /// The inverse of the collider's rotation, and the sensor's origin in
    /// the collider's frame: the parts of parry's `Ray::inverse_transform_by`
    /// that are the same for every ray of a capture, computed once.
    inverse: Rotation,
    origin: Vector,
    pub(super) bounds: Bounds,
    /// Its actor's id (0: none), kind and half extents.
    pub(super) actor: u64,
    pub(super) kind: Option<ActorKind>,
    pub(super) extent: [f32; 3],
    /// What it shows, if it is a traffic light.
    pub(super) light: Option<LightState>,
}

impl Target<'_> {
    /// The ray along `direction` (world frame) from the sensor, in this
    /// target's frame.
    fn local_ray(&self, direction: Vector) -> Ray {
        Ray::new(self.origin, self.inverse * direction)
    }

    /// Where the ray along unit `direction` (world frame) from the sensor
    /// first meets this target within `max`: parry's solid cast.
    pub(super) fn distance(&self, direction: Vector, max: f32) -> Option<f32> {
        self.shape
            .cast_local_ray(&self.local_ray(direction), max, true)
    }

    /// The slab test of this target for a camera rotated by `camera` with
    /// focal length `focal`, if it is a box.
    pub(super) fn slab(&self, camera: Rotation, focal: f32) -> Option<Slab> {
        let cuboid = self.shape.as_cuboid()?;
        let grid = Grid::new(self.inverse * camera, focal);
        Some(Slab::new(cuboid.half_extents, self.origin, grid))
    }

    /// The unit normal (world frame) of a box target's `face`.
    pub(super) fn face_normal(&self, face: Face) -> Vector {
        self.inverse.inverse() * slab::normal(face)
    }

    /// The outward unit normal (world frame) where the ray along
    /// `direction` meets this target at `distance`, or `None` if parry
    /// finds none there.
    pub(super) fn normal(&self, direction: Vector, distance: f32) -> Option<Vector> {
        let hit = self.shape.cast_local_ray_and_get_normal(
            &self.local_ray(direction),
            distance * 1.001 + 1e-4,
            true,
        )?;
        Some(self.inverse.inverse() * hit.normal)
    }
}

/// The colliders `view` from `sensor` may see within `far`, `exclude`'s
/// left out (what `World::cast_ray` with `exclude` would test).
pub(super) fn targets<'a>(
    world: &'a World,
    view: &View,
    sensor: &Pose,
    far: f32,
    exclude: Option<RigidBodyHandle>,
) -> Vec<Target<'a>> {
    world
        .ray_targets(exclude)
        .filter_map(|t| {
            let bounds = view.bounds(sensor, t.pose, &t.shape.compute_local_aabb(), far)?;
            Some(Target {
                shape: t.shape,
                inverse: t.pose.rotation.inverse(),
                origin: t.pose.inverse_transform_point(sensor.translation),
                bounds,
                actor: t.actor,
                kind: t.kind,
                extent: t.extent,
                light: t.light,
            })
        })
        .collect()
}

/// The nearest hit below `far` of the ray along `direction` (world frame)
/// from the sensor among `targets`, as rapier's `cast_ray` would find it:
/// parry's `Shape::cast_ray` is `cast_local_ray` of the ray in the shape's
/// frame, which is what this casts.
/// Returns the distance and the target met.
pub(super) fn nearest_target<'t, 'a: 't>(
    targets: impl Iterator<Item = &'t Target<'a>>,
    direction: Vector,
    far: f32,
) -> Option<(f32, &'t Target<'a>)> {
    let mut nearest = far;
    let mut met = None;
    for target in targets {
        if let Some(distance) = target.distance(direction, nearest) {
            if distance < nearest || met.is_none() {
                met = Some(target);
            }
            nearest = nearest.min(distance);
        }
    }
    met.filter(|_| nearest < far).map(|t| (nearest, t))
}

/// A lidar's view: the cube's six faces and each one's targets.
pub(super) struct Cube<'a> {
    faces: [Vec<Target<'a>>; 6],
}

/// Which cube face serves sensor-frame direction `d`, and where on it.
pub(super) fn cube_face(d: Vector) -> (u8, f32, f32) {
    let face = (0..6)
        .max_by(|&a, &b| {
            let (a, b) = (CUBE[a][0].dot(d), CUBE[b][0].dot(d));
            a.total_cmp(&b)
        })
        .unwrap_or(0);
    let c = View::face(face).coordinates(d);
    (face as u8, c.z / c.x, c.y / c.x)
}

impl<'a> Cube<'a> {
    pub(super) fn new(
        world: &'a World,
        sensor: &Pose,
        far: f32,
        exclude: Option<RigidBodyHandle>,
    ) -> Self {
        Self {
            faces: std::array::from_fn(|i| targets(world, &View::face(i), sensor, far, exclude)),
        }
    }

    /// The targets a ray on `face` at (`right`, `up`) may meet.
    pub(super) fn along(
        &self,
        (face, right, up): (u8, f32, f32),
    ) -> impl Iterator<Item = &Target<'a>> {
        self.faces[usize::from(face)]
            .iter()
            .filter(move |t| t.bounds.contains(right, up))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn every_direction_has_a_face_whose_coordinates_are_within_one() {
        for i in 0..2000 {
            let (s, c) = (i as f32 * 0.37).sin_cos();
            let d = Vector::new(c * (i as f32 * 0.11).cos(), s, c * (i as f32 * 0.11).sin())
                .normalize();
            let (face, right, up) = cube_face(d);
            let forward = View::face(usize::from(face)).coordinates(d).x;
            assert!(forward >= 1.0 / 3f32.sqrt() - 1e-6, "{d:?}: {forward}");
            assert!(right.abs() <= 1.0 + 1e-5 && up.abs() <= 1.0 + 1e-5, "{d:?}");
        }
    }

    #[test]
    fn each_face_is_a_right_handed_frame() {
        for [f, u, r] in CUBE {
            assert_eq!(f.cross(u), r);
        }
    }
}
