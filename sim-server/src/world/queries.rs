//! What sensors ask of the world: rays, the colliders a ray can meet
//! (with their actors), whether a point is inside a body.

use rapier3d::parry::query::{intersection_test, ShapeCastOptions};
use rapier3d::prelude::*;
use shared_types::ActorKind;

use super::World;
use crate::scene::Placement;

/// How far a new body may reach into another and still be spawned: a body
/// placed resting on the ground or on another body touches it.
pub(crate) const SPAWN_SKIN: f32 = 0.01;

/// How far above the ground a walker is spawned: beyond its character
/// controller's 1 cm gap, so it starts clear of the ground and settles.
const STANDING_GAP: f32 = 0.02;

/// A collider a sensor's ray can meet, and the actor it belongs to.
#[derive(Clone, Copy)]
pub(crate) struct RayTarget<'a> {
    /// Its shape.
    pub(crate) shape: &'a dyn Shape,
    /// Where it is.
    pub(crate) pose: &'a Pose,
    /// Its actor's id (0: none).
    pub(crate) actor: u64,
    /// Its actor's kind.
    pub(crate) kind: Option<ActorKind>,
    /// Its actor's half extents.
    pub(crate) extent: [f32; 3],
    /// What it shows, if it is a traffic light.
    pub(crate) light: Option<shared_types::LightState>,
}

impl World {
    /// Whether `collider` is out of the physics only because its body's
    /// simulation is off (CARLA's `set_simulate_physics(False)`): the actor
    /// is still there, and sensors see it.
    fn held_still(&self, collider: &Collider) -> bool {
        collider
            .parent()
            .and_then(|b| self.physics.bodies.get(b))
            .is_some_and(|b| !b.is_enabled())
    }

    /// The actor whose body a body placed as `placement` would overlap
    /// (deeper than [`SPAWN_SKIN`]), if any: why a spawn is refused, as
    /// CARLA refuses one "because of collision at spawn position".
    ///
    /// Every body is tested where it is now, including bodies spawned or
    /// moved earlier in the same batch, which the query pipeline only
    /// learns of at the next step. Each actor is first passed over by a
    /// bounding sphere around its body (a subtraction and a comparison,
    /// from the actor's extent), so a spawn among n bodies costs n of
    /// those and a shape test for each near one.
    pub(crate) fn occupant(&self, placement: &Placement) -> Option<u64> {
        let (pose, shape) = placement.probe(SPAWN_SKIN);
        let bounds = shape.compute_aabb(&pose);
        let reach = bounding_radius(placement.extent.to_array());
        self.actors.iter().find_map(|actor| {
            let body = self.physics.bodies.get(actor.body)?;
            let near = reach + bounding_radius(actor.extent);
            if (body.translation() - placement.position).length_squared() > near * near {
                return None;
            }
            body.colliders().iter().find_map(|&handle| {
                let c = self.physics.colliders.get(handle)?;
                if c.is_sensor() {
                    return None;
                }
                let at = c
                    .position_wrt_parent()
                    .map_or(*body.position(), |local| *body.position() * *local);
                if !bounds.intersects(&c.shape().compute_aabb(&at)) {
                    return None;
                }
                // Every shape the world builds is convex, which the test
                // supports; an unsupported pair is not taken as a collision.
                let hit = intersection_test(&pose, &*shape, &at, c.shape()).ok()?;
                hit.intersecting.then_some(actor.id)
            })
        })
    }

    /// Where a body placed as `placement` (a walker) stands, 2 cm above
    /// the static geometry under it, when its head is above that geometry:
    /// the highest surface that five rays down from its head's height
    /// (through its axis and four points around it) meet within its height.
    /// `None` when they meet nothing, or start inside static geometry.
    pub(crate) fn standing_on_ground(&self, placement: &Placement) -> Option<Vector> {
        let half_height = placement.extent.y;
        let radius = placement.extent.x * 0.7;
        let top = placement.position.y + half_height;
        let reach = 2.0 * half_height;
        let mut ground: Option<f32> = None;
        for (dx, dz) in [
            (0.0, 0.0),
            (radius, 0.0),
            (-radius, 0.0),
            (0.0, radius),
            (0.0, -radius),
        ] {
            let origin = Vector::new(placement.position.x + dx, top, placement.position.z + dz);
            let ray = Ray::new(origin, -Vector::Y);
            for actor in self.actors.iter().filter(|a| a.kind == ActorKind::Static) {
                let Some(body) = self.physics.bodies.get(actor.body) else {
                    continue;
                };
                for &handle in body.colliders() {
                    let Some(c) = self.physics.colliders.get(handle) else {
                        continue;
                    };
                    let at = c
                        .position_wrt_parent()
                        .map_or(*body.position(), |local| *body.position() * *local);
                    let Some(toi) = c.shape().cast_ray(&at, &ray, reach, true) else {
                        continue;
                    };
                    if toi <= 0.0 {
                        return None;
                    }
                    let y = top - toi;
                    ground = Some(ground.map_or(y, |g: f32| g.max(y)));
                }
            }
        }
        ground.map(|y| {
            Vector::new(
                placement.position.x,
                y + half_height + STANDING_GAP,
                placement.position.z,
            )
        })
    }

    /// Whether world point `point` is inside one of `body`'s colliders.
    pub(crate) fn body_contains(&self, body: RigidBodyHandle, point: Vector) -> bool {
        self.physics.bodies.get(body).is_some_and(|b| {
            b.colliders().iter().any(|&c| {
                self.physics
                    .colliders
                    .get(c)
                    .is_some_and(|c| c.shape().contains_point(c.position(), point))
            })
        })
    }

    /// Distance to the first collider along `direction` (unit) from `origin`,
    /// up to `max`, ignoring the body `exclude`.
    pub fn cast_ray(
        &self,
        origin: Vector,
        direction: Vector,
        max: f32,
        exclude: Option<RigidBodyHandle>,
    ) -> Option<f32> {
        let mut filter = QueryFilter::default();
        if let Some(body) = exclude {
            filter = filter.exclude_rigid_body(body);
        }
        self.physics
            .cast_ray(&Ray::new(origin, direction), max, true, filter)
            .map(|(_, distance)| distance)
    }

    /// What sensors' rays meet: every collider not on the excluded body,
    /// with its pose and actor. The enabled ones are what
    /// [`World::cast_ray`] with `exclude` tests (casting against each with
    /// `Shape::cast_ray` and keeping the nearest hit below the range is the
    /// same answer, bit for bit); those of bodies whose simulation is off
    /// are there too (the actor is still in the world).
    pub(crate) fn ray_targets(
        &self,
        exclude: Option<RigidBodyHandle>,
    ) -> impl Iterator<Item = RayTarget<'_>> + '_ {
        self.physics
            .colliders
            .iter()
            .filter(move |(_, c)| exclude.is_none() || c.parent() != exclude)
            .filter(|(_, c)| c.is_enabled() || self.held_still(c))
            .map(|(_, c)| {
                let actor = c
                    .parent()
                    .and_then(|body| self.physics.bodies.get(body))
                    .and_then(|body| self.index_of(body.user_data as u64))
                    .map(|i| &self.actors[i]);
                RayTarget {
                    shape: c.shape(),
                    pose: c.position(),
                    actor: actor.map_or(0, |a| a.id),
                    kind: actor.map(|a| a.kind),
                    extent: actor.map_or([0.0; 3], |a| a.extent),
                    light: actor
                        .filter(|a| a.kind == ActorKind::TrafficLight)
                        .and_then(|a| self.lights.reading(a.id))
                        .map(|reading| reading.state),
                }
            })
    }

    /// The velocity (world frame, m/s) of actor `id`'s body at world point
    /// `point`: its linear velocity plus its spin's; zero for id 0 (the
    /// world itself) and an actor that is gone.
    pub(crate) fn velocity_at(&self, id: u64, point: Vector) -> Vector {
        self.body_of(id)
            .and_then(|body| self.physics.bodies.get(body))
            .map_or(Vector::ZERO, |body| body.velocity_at_point(point))
    }

    /// The nearest actor a sphere of `radius` swept from `origin` along
    /// `direction` (unit) meets within `max`, and how far the sphere
    /// travelled; `exclude`'s body left out, and fixed bodies too when
    /// `only_dynamic`. A body the sphere starts in is passed through
    /// unless it is moving into it.
    pub(crate) fn sweep_sphere(
        &self,
        (origin, direction): (Vector, Vector),
        (radius, max): (f32, f32),
        exclude: Option<RigidBodyHandle>,
        only_dynamic: bool,
    ) -> Option<(u64, f32)> {
        let mut filter = if only_dynamic {
            QueryFilter::exclude_fixed()
        } else {
            QueryFilter::default()
        };
        if let Some(body) = exclude {
            filter = filter.exclude_rigid_body(body);
        }
        let options = ShapeCastOptions {
            max_time_of_impact: max,
            target_distance: 0.0,
            stop_at_penetration: false,
            compute_impact_geometry_on_penetration: false,
        };
        let (collider, hit) = self.physics.query_pipeline_with_filter(filter).cast_shape(
            &Pose::from_translation(origin),
            direction,
            &Ball::new(radius),
            options,
        )?;
        let body = self.physics.colliders.get(collider)?.parent()?;
        let actor = self.physics.bodies.get(body)?.user_data as u64;
        Some((actor, hit.time_of_impact))
    }
}

/// A radius around a body's centre that holds all of it, whatever its
/// kind, from its extent (half extents; a sphere's radius first; a
/// capsule's radius, half height, radius): their sum, never less than the
/// farthest point (a box's half diagonal, a capsule's half height plus
/// radius).
fn bounding_radius(extent: [f32; 3]) -> f32 {
    extent.iter().map(|e| e.abs()).sum()
}
