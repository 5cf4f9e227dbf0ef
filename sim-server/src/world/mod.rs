//! The physics world: rapier bodies and the actors that name them. What
//! each wire command does to them is in `commands.rs`; the vehicles are
//! in `vehicles.rs`, the walkers in `walkers.rs`.

use std::time::{Duration, Instant};

use rapier3d::prelude::*;
use serde::{Deserialize, Serialize};
use shared_types::{ActorKind, ActorState};
use simbus_recording::RecordedCollision;

use crate::clock::SubstepPlan;
use crate::scene::PlacedSignal;
use crate::scene::Placement;
use crate::traffic_lights::TrafficLights;
use crate::vehicles::{Ackermann, Vehicles};
use crate::walkers::Walkers;

mod check;
mod contacts;
mod queries;
pub use check::Inconsistency;
pub(crate) use contacts::ContactStart;
use contacts::ContactStarts;

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
    /// The contacts between actors that started in the last frame, kept
    /// while [`World::watch_contacts`] is set (collision sensors read them).
    #[serde(skip)]
    pub(crate) contact_starts: Vec<ContactStart>,
    /// Whether to keep [`World::contact_starts`].
    #[serde(skip)]
    pub(crate) watch_contacts: bool,
    /// Contacts started within rapier's prediction distance that have not
    /// pushed yet (`contacts::collect_contacts`).
    #[serde(skip)]
    pending_contacts: Vec<(ColliderHandle, ColliderHandle)>,
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
    /// The walkers. Last but one, so a keyframe of before walkers
    /// (layout 2) reads with an empty list appended (`keyframe.rs`).
    pub(crate) walkers: Walkers,
    /// The traffic lights and signs. Last but one, so a keyframe of
    /// before them (layout 3) reads with empty lists appended.
    pub(crate) lights: TrafficLights,
    /// The vehicles driven by an Ackermann target. Last, so a keyframe of
    /// before them (layout 4) reads with an empty list appended.
    pub(crate) ackermann: Vec<Ackermann>,
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
            walkers: Walkers::default(),
            lights: TrafficLights::default(),
            ackermann: Vec::new(),
            pushed: Vec::new(),
            held: Vec::new(),
            contact_starts: Vec::new(),
            watch_contacts: false,
            pending_contacts: Vec::new(),
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

    /// A copy that steps exactly as this world: every rapier set cloned,
    /// the pipelines (scratch space, no state) new, and what a keyframe
    /// leaves out left out — a keyframe without the encoding, which is how
    /// a snapshot restores a 1 000-actor world in a few milliseconds.
    pub(crate) fn duplicate(&self) -> Self {
        let p = &self.physics;
        Self {
            physics: PhysicsWorld {
                gravity: p.gravity,
                integration_parameters: p.integration_parameters,
                islands: p.islands.clone(),
                broad_phase: p.broad_phase.clone(),
                narrow_phase: p.narrow_phase.clone(),
                bodies: p.bodies.clone(),
                colliders: p.colliders.clone(),
                impulse_joints: p.impulse_joints.clone(),
                multibody_joints: p.multibody_joints.clone(),
                soft_bodies: p.soft_bodies.clone(),
                ..PhysicsWorld::default()
            },
            actors: self.actors.clone(),
            vehicles: self.vehicles.clone(),
            walkers: self.walkers.clone(),
            lights: self.lights.clone(),
            ackermann: self.ackermann.clone(),
            pushed: self.pushed.clone(),
            held: self.held.clone(),
            contact_starts: Vec::new(),
            watch_contacts: false,
            pending_contacts: Vec::new(),
            sun: self.sun,
            first_id: self.first_id,
            next_id: self.next_id,
            queries_stale: self.queries_stale,
        }
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
        match placement.kind {
            ActorKind::Vehicle => {
                self.vehicles
                    .add(id, body, &shared_types::VehicleSpec::default());
            }
            ActorKind::Walker => self.walkers.add(id, body, e.x, e.y),
            _ => {}
        }
        match placement.signal {
            Some(PlacedSignal::Light { junction, pole }) => self.lights.add(id, junction, pole),
            Some(PlacedSignal::Sign(sign)) => self.lights.add_sign(id, sign),
            None => {}
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
    /// `plan.substep_seconds` (vehicles and walkers updated before each), then updates
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
        collisions: Option<&mut Vec<RecordedCollision>>,
        mut physics: Option<&mut Duration>,
    ) {
        self.physics.integration_parameters.dt = plan.substep_seconds;
        let started = ContactStarts::default();
        self.contact_starts.clear();
        let events = collisions.is_some() || self.watch_contacts;
        if !events {
            // Nobody watches: what was pending is forgotten, not reported
            // late when somebody starts watching.
            self.pending_contacts.clear();
        }
        // The contacts of this frame (kept in `contact_starts`, which
        // collision sensors read, or taken for the recorder).
        let mut contacts = std::mem::take(&mut self.contact_starts);
        for _ in 0..plan.count {
            self.vehicles
                .update(&mut self.physics, plan.substep_seconds, &mut self.ackermann);
            self.walkers.update(&mut self.physics, plan.substep_seconds);
            for &(handle, local) in &self.held {
                if let Some(body) = self.physics.bodies.get_mut(handle) {
                    let velocity = body.rotation() * local;
                    body.set_linvel(velocity, true);
                }
            }
            let clock = physics.is_some().then(Instant::now);
            if events {
                self.physics.step_with_events(&(), &started);
            } else {
                self.physics.step();
            }
            if let (Some(total), Some(clock)) = (physics.as_deref_mut(), clock) {
                *total += clock.elapsed();
            }
            if events {
                let mut pending = std::mem::take(&mut self.pending_contacts);
                self.collect_contacts(&started, &mut pending, &mut contacts);
                self.pending_contacts = pending;
            }
        }
        if let Some(out) = collisions {
            out.extend(contacts.iter().map(ContactStart::recorded));
        }
        if self.watch_contacts {
            self.contact_starts = contacts;
        }
        for handle in self.pushed.drain(..) {
            if let Some(body) = self.physics.bodies.get_mut(handle) {
                body.reset_forces(false);
                body.reset_torques(false);
            }
        }
        // The lights keep the frame's time, not physics' (which a clamped
        // frame cuts short).
        self.lights.advance(plan.frame_ns);
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
            if let Some(light) = state.light() {
                self.lights.restore(state.id, light);
            }
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
        let mut state = ActorState {
            id: actor.id,
            kind: actor.kind as u32,
            flags,
            position: body.translation().to_array(),
            rotation: [q.x, q.y, q.z, q.w],
            linear_velocity: body.linvel().to_array(),
            angular_velocity: body.angvel().to_array(),
            acceleration: actor.acceleration.to_array(),
            extent: actor.extent,
            detail: 0,
        };
        match actor.kind {
            ActorKind::TrafficLight => {
                if let Some(light) = self.lights.reading(actor.id) {
                    state.set_light(light);
                }
            }
            ActorKind::TrafficSign => {
                if let Some(sign) = self.lights.sign(actor.id) {
                    state.set_sign(sign);
                }
            }
            _ => {}
        }
        state
    }
}

#[cfg(test)]
mod tests;
