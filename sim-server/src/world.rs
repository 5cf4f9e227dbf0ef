//! The physics world: rapier bodies and the actors that name them.

use rapier3d::prelude::*;
use shared_types::{ActorKind, ActorState};

use crate::clock::SubstepPlan;
use crate::scene::Scene;

/// One actor: a rapier body with a stable simbus id.
#[derive(Debug, Clone)]
struct Actor {
    id: u64,
    kind: ActorKind,
    body: RigidBodyHandle,
    extent: [f32; 3],
    /// Linear velocity at the previous frame, for the acceleration.
    previous_velocity: Vector,
    /// Linear acceleration over the last frame.
    acceleration: Vector,
}

/// The rapier world and its actors, in id order.
pub struct World {
    physics: PhysicsWorld,
    actors: Vec<Actor>,
    next_id: u64,
}

impl World {
    /// A world holding `scene`. Actor ids start at 1 in the scene's order.
    pub fn new(scene: Scene) -> Self {
        let mut world = Self {
            physics: PhysicsWorld::new(),
            actors: Vec::new(),
            next_id: 1,
        };
        for placement in scene.placements() {
            let (body, collider) = placement.build();
            let (body, _) = world.physics.insert(body, collider);
            let e = placement.extent;
            world.actors.push(Actor {
                id: world.next_id,
                kind: placement.kind,
                body,
                extent: [e.x, e.y, e.z],
                previous_velocity: placement.linear_velocity,
                acceleration: Vector::ZERO,
            });
            world.next_id += 1;
        }
        world
    }

    /// Number of actors.
    pub fn actor_count(&self) -> usize {
        self.actors.len()
    }

    /// Advances physics by one frame: `plan.count` rapier steps of
    /// `plan.substep_seconds`, then updates every actor's acceleration.
    pub fn step(&mut self, plan: &SubstepPlan) {
        self.physics.integration_parameters.dt = plan.substep_seconds;
        for _ in 0..plan.count {
            self.physics.step();
        }
        let frame_seconds = plan.substep_seconds * plan.count as f32;
        for actor in &mut self.actors {
            let velocity = self.physics.bodies[actor.body].linvel();
            actor.acceleration = if frame_seconds > 0.0 {
                (velocity - actor.previous_velocity) / frame_seconds
            } else {
                Vector::ZERO
            };
            actor.previous_velocity = velocity;
        }
    }

    /// The state of the actor at `index` (in id order), as published.
    pub fn actor_state(&self, index: usize) -> ActorState {
        let actor = &self.actors[index];
        let body = &self.physics.bodies[actor.body];
        let p = body.translation();
        let q = body.rotation();
        let v = body.linvel();
        let w = body.angvel();
        let a = actor.acceleration;
        ActorState {
            id: actor.id,
            kind: actor.kind as u32,
            flags: if body.is_sleeping() {
                ActorState::SLEEPING
            } else {
                0
            },
            position: p.to_array(),
            rotation: [q.x, q.y, q.z, q.w],
            linear_velocity: v.to_array(),
            angular_velocity: w.to_array(),
            acceleration: a.to_array(),
            extent: actor.extent,
            reserved: 0,
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared_types::WorldSettings;

    fn fixed_plan(dt: f64) -> SubstepPlan {
        let settings = WorldSettings {
            fixed_delta_seconds: Some(dt),
            ..Default::default()
        };
        SubstepPlan::new(settings.fixed_delta_nanos().unwrap(), &settings)
    }

    #[test]
    fn ids_follow_scene_order_from_one() {
        let world = World::new(Scene::Default);
        let ids: Vec<u64> = (0..world.actor_count())
            .map(|i| world.actor_state(i).id)
            .collect();
        assert_eq!(ids, (1..=world.actor_count() as u64).collect::<Vec<_>>());
    }

    #[test]
    fn things_fall_under_gravity() {
        let mut world = World::new(Scene::Default);
        let capsule = (0..world.actor_count())
            .find(|&i| world.actor_state(i).kind == ActorKind::Capsule as u32)
            .unwrap();
        let y0 = world.actor_state(capsule).position[1];
        let plan = fixed_plan(0.05);
        for _ in 0..5 {
            world.step(&plan);
        }
        let state = world.actor_state(capsule);
        assert!(state.position[1] < y0 - 0.2, "the capsule fell");
        // Free fall: acceleration is gravity.
        assert!((state.acceleration[1] + 9.81).abs() < 0.05, "{state:?}");
    }

    #[test]
    fn same_steps_give_identical_states() {
        let run = || {
            let mut world = World::new(Scene::Boxes(50));
            let plan = fixed_plan(0.02);
            for _ in 0..100 {
                world.step(&plan);
            }
            (0..world.actor_count())
                .map(|i| world.actor_state(i))
                .collect::<Vec<_>>()
        };
        let (a, b) = (run(), run());
        assert_eq!(
            bytemuck::cast_slice::<ActorState, u8>(&a),
            bytemuck::cast_slice::<ActorState, u8>(&b)
        );
    }
}
