//! The event sensors: the collision sensor reads the contacts its parent
//! started in the frame (rapier's contact events, see
//! `World::contact_starts`); the obstacle detector sweeps a sphere along
//! its own forward axis.

use rapier3d::prelude::{Pose, Vector};
use shared_types::{CollisionEvent, Obstacle, ObstacleDetection, SensorSpec};

use crate::world::World;

/// The contacts `parent` started in the last frame, as its collision
/// sensor reports them.
pub(super) fn collisions(world: &World, parent: u64) -> impl Iterator<Item = CollisionEvent> + '_ {
    world
        .contact_starts
        .iter()
        .filter_map(move |c| c.seen_by(parent))
        .map(|(other_actor, impulse)| CollisionEvent {
            other_actor,
            normal_impulse: impulse.to_array(),
            reserved: 0,
        })
}

/// What an obstacle detector at `pose` sees ahead (its +X), its parent
/// left out.
pub(super) fn obstacle(world: &World, spec: &SensorSpec, pose: Pose) -> Option<ObstacleDetection> {
    let params: Obstacle = spec.obstacle_params()?;
    let (other_actor, distance) = world.sweep_sphere(
        (pose.translation, pose.rotation * Vector::X),
        (params.hit_radius, params.distance),
        world.body_of(spec.attach_to),
        params.only_dynamics,
    )?;
    Some(ObstacleDetection {
        other_actor,
        distance,
        reserved: 0,
    })
}
