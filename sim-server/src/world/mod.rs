//! The physics world: rapier bodies and the actors that name them. What
//! each wire command does to them is in [`crate::commands`]; the vehicles
//! are in [`crate::vehicles`].

use std::sync::Mutex;
use std::time::{Duration, Instant};

use rapier3d::prelude::*;
use serde::{Deserialize, Serialize};
use shared_types::{ActorKind, ActorState};
use simbus_recording::RecordedCollision;

use crate::clock::SubstepPlan;
use crate::scene::Placement;
use crate::vehicles::Vehicles;

mod check;
pub use check::Inconsistency;

/// One actor: a rapier body with a stable simbus id.
#[derive(Debug, Clone, Serialize, Deserialize)]
pub(crate) struct Actor {
    pub(crate) id: u64,
    pub(crate) kind: ActorKind,
    pub(crate) body: RigidBodyHandle,
    pub(crate) extent: [f32; 3],
    /// Linear velocity at the previous frame, for the acceleration.
    previous_velocity: Vector,
    /// Linear acceleration over the last frame.
    acceleration: Vector,
}

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
}

/// The rapier world and its actors, in id order. All of it serializes
/// (a recording's keyframe): restored, it steps exactly as the original.
#[derive(Serialize, Deserialize)]
pub struct World {
    pub(crate) physics: PhysicsWorld,
    pub(crate) actors: Vec<Actor>,
    pub(crate) vehicles: Vehicles,
    /// Bodies given a one-frame force or torque, cleared after the frame.
    pub(crate) pushed: Vec<RigidBodyHandle>,
    /// Bodies held at a constant velocity in their own axes (CARLA's
    /// `enable_constant_velocity`), set again before every physics step.
    #[serde(default)]
    pub(crate) held: Vec<(RigidBodyHandle, Vector)>,
    /// The sun that lights RGB cameras (a weather's).
    #[serde(default)]
    pub(crate) sun: shared_types::Sun,
    /// The id of this world's first actor (the scene's first placement).
    first_id: u64,
    next_id: u64,
    /// Bodies were moved without a step ([`World::set_states`]): ray casts
    /// need [`World::sync_queries`] first.
    #[serde(skip)]
    queries_stale: bool,
}

impl std::fmt::Debug for World {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("World")
            .field("actors", &self.actors.len())
            .field("vehicles", &self.vehicles)
            .field("first_id", &self.first_id)
            .field("next_id", &self.next_id)
            .finish()
    }
}

impl World {
    /// A world holding `placements`, with actor ids from `first_id` in
    /// their order. A server passes the previous world's
    /// [`World::next_id`], so ids are never reused within its life.
    pub fn new(placements: &[Placement], first_id: u64) -> Self {
        let first_id = first_id.max(1);
        let mut world = Self {
            physics: PhysicsWorld::new(),
            actors: Vec::new(),
            vehicles: Vehicles::default(),
            pushed: Vec::new(),
            held: Vec::new(),
            sun: shared_types::Sun::default(),
            first_id,
            next_id: first_id,
            queries_stale: false,
        };
        for placement in placements {
            world.insert(placement);
        }
        world
    }

    pub(crate) fn insert(&mut self, placement: &Placement) -> u64 {
        let (mut body, collider) = placement.build();
        let id = self.next_id;
        // The body knows its actor, so contacts name actors.
        body.user_data = u128::from(id);
        let (body, _) = self.physics.insert(body, collider);
        self.next_id = self.next_id.saturating_add(1);
        let e = placement.extent;
        self.actors.push(Actor {
            id,
            kind: placement.kind,
            body,
            extent: [e.x, e.y, e.z],
            previous_velocity: placement.linear_velocity,
            acceleration: Vector::ZERO,
        });
        if placement.kind == ActorKind::Vehicle {
            self.vehicles
                .add(id, body, &shared_types::VehicleSpec::default());
        }
        id
    }

    /// The id of this world's first actor.
    pub fn first_id(&self) -> u64 {
        self.first_id
    }

    /// The id the next actor will get.
    pub fn next_id(&self) -> u64 {
        self.next_id
    }

    /// Number of actors.
    pub fn actor_count(&self) -> usize {
        self.actors.len()
    }

    pub(crate) fn index_of(&self, id: u64) -> Option<usize> {
        self.actors.binary_search_by_key(&id, |a| a.id).ok()
    }

    /// Advances physics by one frame: `plan.count` rapier steps of
    /// `plan.substep_seconds` (vehicles updated before each), then updates
    /// every actor's acceleration.
    pub fn step(&mut self, plan: &SubstepPlan) {
        self.step_with_collisions(plan, None);
    }

    /// [`World::step`], adding every contact that started to `collisions`
    /// (with frame and time left 0 for the caller) when it is given.
    pub fn step_with_collisions(
        &mut self,
        plan: &SubstepPlan,
        collisions: Option<&mut Vec<RecordedCollision>>,
    ) {
        self.step_timed(plan, collisions, None);
    }

    /// [`World::step_with_collisions`], adding the time spent inside
    /// rapier's pipeline step (nothing else) to `physics` when it is given;
    /// without it no clock is read.
    pub(crate) fn step_timed(
        &mut self,
        plan: &SubstepPlan,
        mut collisions: Option<&mut Vec<RecordedCollision>>,
        mut physics: Option<&mut Duration>,
    ) {
        self.physics.integration_parameters.dt = plan.substep_seconds;
        let started = ContactStarts::default();
        for _ in 0..plan.count {
            self.vehicles
                .update(&mut self.physics, plan.substep_seconds);
            for &(handle, local) in &self.held {
                if let Some(body) = self.physics.bodies.get_mut(handle) {
                    let velocity = body.rotation() * local;
                    body.set_linvel(velocity, true);
                }
            }
            let clock = physics.is_some().then(Instant::now);
            match collisions {
                Some(_) => self.physics.step_with_events(&(), &started),
                None => self.physics.step(),
            }
            if let (Some(total), Some(clock)) = (physics.as_deref_mut(), clock) {
                *total += clock.elapsed();
            }
            if let Some(out) = collisions.as_deref_mut() {
                self.collect_collisions(&started, out);
            }
        }
        for handle in self.pushed.drain(..) {
            if let Some(body) = self.physics.bodies.get_mut(handle) {
                body.reset_forces(false);
                body.reset_torques(false);
            }
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

    /// Turns the contacts that started in the last physics step into
    /// collisions between actors, with the impulse the solver applied.
    fn collect_collisions(&self, started: &ContactStarts, out: &mut Vec<RecordedCollision>) {
        let pairs = std::mem::take(&mut *started.pairs.lock().unwrap_or_else(|e| e.into_inner()));
        for (c1, c2) in pairs {
            let actor = |c: ColliderHandle| {
                let body = self.physics.colliders.get(c)?.parent()?;
                let id = self.physics.bodies.get(body)?.user_data as u64;
                let kind = self.actors.get(self.index_of(id)?)?.kind;
                Some((id, kind))
            };
            let (Some(a), Some(b)) = (actor(c1), actor(c2)) else {
                continue;
            };
            let ((actor_a, kind_a), (actor_b, kind_b)) = if a.0 <= b.0 { (a, b) } else { (b, a) };
            let impulse = self
                .physics
                .contact_pair(c1, c2)
                .map_or(0.0, |pair| pair.total_impulse_magnitude());
            out.push(RecordedCollision {
                frame: 0,
                elapsed_ns: 0,
                actor_a,
                actor_b,
                impulse,
                kind_a: kind_a as u32,
                kind_b: kind_b as u32,
                reserved: 0,
            });
        }
    }

    /// Sets every actor named in `states` to its recorded pose and
    /// velocities (a replay); actors not named keep theirs.
    pub fn set_states(&mut self, states: &[ActorState]) {
        for state in states {
            let Some(index) = self.index_of(state.id) else {
                continue;
            };
            let actor = &mut self.actors[index];
            let Some(body) = self.physics.bodies.get_mut(actor.body) else {
                continue;
            };
            let [x, y, z, w] = state.rotation;
            body.set_position(
                Pose::from_parts(
                    Vector::from_array(state.position),
                    Rotation::from_xyzw(x, y, z, w),
                ),
                false,
            );
            body.set_linvel(Vector::from_array(state.linear_velocity), false);
            body.set_angvel(Vector::from_array(state.angular_velocity), false);
            actor.acceleration = Vector::from_array(state.acceleration);
            actor.previous_velocity = Vector::from_array(state.linear_velocity);
        }
        self.queries_stale = true;
    }

    /// Brings colliders and the query structure to the bodies' poses after
    /// [`World::set_states`], so ray casts (sensors) see them; nothing is
    /// integrated. Costs a collision-detection pass, so a replay only pays
    /// it when a sensor looks.
    pub fn sync_queries(&mut self) {
        if std::mem::take(&mut self.queries_stale) {
            self.physics.detect_collisions(&(), &());
        }
    }

    /// The rapier body of actor `id`.
    pub fn body_of(&self, id: u64) -> Option<RigidBodyHandle> {
        self.index_of(id).map(|i| self.actors[i].body)
    }

    /// Whether `collider` is out of the physics only because its body's
    /// simulation is off (CARLA's `set_simulate_physics(False)`): the actor
    /// is still there, and sensors see it.
    fn held_still(&self, collider: &Collider) -> bool {
        collider
            .parent()
            .and_then(|b| self.physics.bodies.get(b))
            .is_some_and(|b| !b.is_enabled())
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

    /// The pose of actor `id`.
    pub fn pose_of(&self, id: u64) -> Option<Pose> {
        self.body_of(id).map(|b| *self.physics.bodies[b].position())
    }

    /// Linear acceleration over the last frame and angular velocity of actor
    /// `id` (world frame); zeros for id 0, the world itself.
    pub fn motion_of(&self, id: u64) -> Option<(Vector, Vector)> {
        if id == 0 {
            return Some((Vector::ZERO, Vector::ZERO));
        }
        let actor = &self.actors[self.index_of(id)?];
        Some((actor.acceleration, self.physics.bodies[actor.body].angvel()))
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
                }
            })
    }

    /// Every actor's state, in id order, as published.
    pub fn states(&self) -> Vec<ActorState> {
        (0..self.actor_count())
            .map(|i| self.actor_state(i))
            .collect()
    }

    /// The state of the actor at `index` (in id order), as published.
    pub fn actor_state(&self, index: usize) -> ActorState {
        let actor = &self.actors[index];
        let body = &self.physics.bodies[actor.body];
        let q = body.rotation();
        let mut flags = 0;
        if body.is_sleeping() {
            flags |= ActorState::SLEEPING;
        }
        if !body.is_enabled() {
            flags |= ActorState::PHYSICS_DISABLED;
        }
        ActorState {
            id: actor.id,
            kind: actor.kind as u32,
            flags,
            position: body.translation().to_array(),
            rotation: [q.x, q.y, q.z, q.w],
            linear_velocity: body.linvel().to_array(),
            angular_velocity: body.angvel().to_array(),
            acceleration: actor.acceleration.to_array(),
            extent: actor.extent,
            reserved: 0,
        }
    }
}

/// Collects the collider pairs whose contact started during a step.
#[derive(Default)]
struct ContactStarts {
    pairs: Mutex<Vec<(ColliderHandle, ColliderHandle)>>,
}

impl EventHandler for ContactStarts {
    fn handle_collision_event(
        &self,
        _bodies: &RigidBodySet,
        _colliders: &ColliderSet,
        event: CollisionEvent,
        _contact_pair: Option<&ContactPair>,
    ) {
        if let CollisionEvent::Started(a, b, _) = event {
            self.pairs
                .lock()
                .unwrap_or_else(|e| e.into_inner())
                .push((a, b));
        }
    }

    fn handle_contact_force_event(
        &self,
        _dt: Real,
        _bodies: &RigidBodySet,
        _colliders: &ColliderSet,
        _contact_pair: &ContactPair,
        _total_force_magnitude: Real,
    ) {
    }

    fn handle_soft_body_tear_event(&self, _soft_bodies: &SoftBodySet, _event: &SoftBodyTearEvent) {}
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;
    use shared_types::WorldSettings;
    use shared_types::{Command, CommandStatus};

    fn fixed_plan(dt: f64) -> SubstepPlan {
        let settings = WorldSettings {
            fixed_delta_seconds: Some(dt),
            ..Default::default()
        };
        SubstepPlan::new(settings.fixed_delta_nanos().unwrap(), &settings)
    }

    fn state_of(world: &World, id: u64) -> ActorState {
        world.actor_state(world.index_of(id).expect("actor exists"))
    }

    #[test]
    fn ids_follow_scene_order_from_one() {
        let world = World::new(&Scene::Default.placements(0), 1);
        let ids: Vec<u64> = (0..world.actor_count())
            .map(|i| world.actor_state(i).id)
            .collect();
        assert_eq!(ids, (1..=world.actor_count() as u64).collect::<Vec<_>>());
    }

    #[test]
    fn things_fall_under_gravity() {
        let mut world = World::new(&Scene::Default.placements(0), 1);
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
            let mut world = World::new(&Scene::Boxes(50).placements(0), 1);
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

    #[test]
    fn spawned_ids_are_new_and_never_reused() {
        let mut world = World::new(&Scene::Empty.placements(0), 1);
        let a = world.apply(&Command::spawn_box([0.0, 1.0, 0.0], [0.5; 3]));
        let b = world.apply(&Command::spawn_sphere([2.0, 1.0, 0.0], 0.5));
        assert_eq!((a.actor, b.actor), (1, 2));
        assert_eq!(
            world.apply(&Command::destroy(2)).status,
            CommandStatus::Ok as u32
        );
        let c = world.apply(&Command::spawn_capsule([0.0, 3.0, 0.0], 0.3, 0.5));
        assert_eq!(c.actor, 3, "id 2 is not reused");
        let again = world.apply(&Command::destroy(2));
        assert_eq!(again.status, CommandStatus::UnknownActor as u32);
        assert_eq!(world.actor_count(), 2);
    }

    #[test]
    fn bad_commands_are_refused_and_change_nothing() {
        let mut world = World::new(&Scene::Default.placements(0), 1);
        let before: Vec<_> = (0..world.actor_count())
            .map(|i| world.actor_state(i))
            .collect();
        let cases = [
            (
                Command::apply_force(999, [1.0, 0.0, 0.0]),
                CommandStatus::UnknownActor,
            ),
            (
                Command::apply_force(3, [f32::NAN, 0.0, 0.0]),
                CommandStatus::InvalidArgument,
            ),
            (
                Command::spawn_box([0.0; 3], [-1.0, 1.0, 1.0]),
                CommandStatus::InvalidArgument,
            ),
            (
                Command::spawn_sphere([0.0; 3], f32::INFINITY),
                CommandStatus::InvalidArgument,
            ),
            (
                Command::vehicle_control(3, 0.5, 0.0, 0.0, false),
                CommandStatus::NotAVehicle,
            ),
            (
                Command::apply_impulse(1, [0.0, 1.0, 0.0]),
                CommandStatus::StaticActor,
            ),
            (
                Command::set_transform(3, [0.0; 3], [f32::NAN, 0.0, 0.0, 1.0]),
                CommandStatus::InvalidArgument,
            ),
            (
                Command {
                    kind: 99,
                    ..Command::destroy(3)
                },
                CommandStatus::UnknownCommand,
            ),
        ];
        for (command, status) in cases {
            assert_eq!(world.apply(&command).status, status as u32, "{command:?}");
        }
        let after: Vec<_> = (0..world.actor_count())
            .map(|i| world.actor_state(i))
            .collect();
        assert_eq!(before, after);
    }

    #[test]
    fn forces_last_one_frame_and_impulses_act_at_once() {
        let mut world = World::new(&Scene::Empty.placements(0), 1);
        let id = world
            .apply(&Command::spawn_box([0.0, 10.0, 0.0], [0.5; 3]))
            .actor;
        world.apply(&Command::set_gravity(id, false));
        world.apply(&Command::apply_force(id, [8.0, 0.0, 0.0])); // 1 kg box: 8 m/s²
        let plan = fixed_plan(0.1);
        world.step(&plan);
        let v1 = state_of(&world, id).linear_velocity[0];
        assert!((v1 - 0.8).abs() < 1e-3, "{v1}");
        world.step(&plan);
        let v2 = state_of(&world, id).linear_velocity[0];
        assert!((v2 - v1).abs() < 1e-4, "the force lasted one frame: {v2}");
        world.apply(&Command::apply_impulse(id, [0.0, 2.0, 0.0]));
        assert!((state_of(&world, id).linear_velocity[1] - 2.0).abs() < 1e-4);
    }

    #[test]
    fn a_vehicle_drives_forward_with_throttle_and_turns_with_steer() {
        let mut world = crate::commands::tests::world_on_ground();
        let id = world.apply(&Command::spawn_vehicle([0.0, 1.0, 0.0])).actor;
        let plan = fixed_plan(0.02);
        for _ in 0..50 {
            world.step(&plan); // settle on the suspension
        }
        let start = state_of(&world, id).position;
        world.apply(&Command::vehicle_control(id, 1.0, 0.0, 0.0, false));
        for _ in 0..100 {
            world.step(&plan);
        }
        let moved = state_of(&world, id).position;
        assert!(
            moved[0] - start[0] > 2.0,
            "drove forward: {start:?} -> {moved:?}"
        );
        world.apply(&Command::vehicle_control(id, 1.0, 1.0, 0.0, false));
        for _ in 0..100 {
            world.step(&plan);
        }
        let turned = state_of(&world, id).position;
        assert!(
            (turned[2] - moved[2]).abs() > 0.5,
            "steered: {moved:?} -> {turned:?}"
        );
    }
}
