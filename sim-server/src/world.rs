//! The physics world: rapier bodies, the actors that name them, vehicles,
//! and the commands that change them.

use rapier3d::control::{DynamicRayCastVehicleController, WheelTuning};
use rapier3d::prelude::*;
use shared_types::limits::{MAX_ACTOR_EXTENT, MAX_ACTOR_POSITION};
use shared_types::{ActorKind, ActorState, Command, CommandKind, CommandResult, CommandStatus};

use crate::clock::SubstepPlan;
use crate::scene::Placement;

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

/// A vehicle's controller and the control it holds until told otherwise.
struct Vehicle {
    actor: u64,
    controller: DynamicRayCastVehicleController,
    throttle: f32,
    steer: f32,
    brake: f32,
    hand_brake: bool,
}

/// Chassis half extents of a spawned vehicle: 2 m long (X), 0.5 m high, 1 m wide.
const VEHICLE_HALF_EXTENTS: [f32; 3] = [1.0, 0.25, 0.5];
/// Engine force per driven (rear) wheel at full throttle, newtons.
const MAX_ENGINE_FORCE: f32 = 300.0;
/// Brake force per wheel at full brake.
const MAX_BRAKE: f32 = 40.0;
/// Front-wheel angle at full steer, radians.
const MAX_STEER: f32 = 0.5;

/// The rapier world and its actors, in id order.
pub struct World {
    physics: PhysicsWorld,
    actors: Vec<Actor>,
    vehicles: Vec<Vehicle>,
    /// Bodies given a one-frame force or torque, cleared after the frame.
    pushed: Vec<RigidBodyHandle>,
    /// The id of this world's first actor (the scene's first placement).
    first_id: u64,
    next_id: u64,
}

fn finite(values: &[f32]) -> bool {
    values.iter().all(|v| v.is_finite())
}

/// `q` as a unit quaternion; all zeros means identity. `None` if unusable.
fn rotation_of(q: [f32; 4]) -> Option<Rotation> {
    if q == [0.0; 4] {
        return Some(Rotation::IDENTITY);
    }
    let rotation = Rotation::from_xyzw(q[0], q[1], q[2], q[3]);
    let length = rotation.length();
    (finite(&q) && length > 1e-6).then(|| rotation / length)
}

fn result(actor: u64, status: CommandStatus) -> CommandResult {
    CommandResult {
        actor,
        status: status as u32,
        reserved: 0,
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
            vehicles: Vec::new(),
            pushed: Vec::new(),
            first_id,
            next_id: first_id,
        };
        for placement in placements {
            world.insert(placement);
        }
        world
    }

    fn insert(&mut self, placement: &Placement) -> u64 {
        let (body, collider) = placement.build();
        let (body, _) = self.physics.insert(body, collider);
        let id = self.next_id;
        self.next_id += 1;
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
            self.vehicles.push(Vehicle {
                actor: id,
                controller: vehicle_controller(body, e),
                throttle: 0.0,
                steer: 0.0,
                brake: 0.0,
                hand_brake: false,
            });
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

    fn index_of(&self, id: u64) -> Option<usize> {
        self.actors.binary_search_by_key(&id, |a| a.id).ok()
    }

    /// Applies one command; its result names the actor (the new one for a
    /// spawn) and what went wrong, if anything. A failed command changes nothing.
    pub fn apply(&mut self, command: &Command) -> CommandResult {
        let Some(kind) = CommandKind::from_u32(command.kind) else {
            return result(command.actor, CommandStatus::UnknownCommand);
        };
        if !finite(&command.vector) || !finite(&command.rotation) || !finite(&command.params) {
            return result(command.actor, CommandStatus::InvalidArgument);
        }
        if kind.spawns() {
            return self.spawn(kind, command);
        }
        let Some(index) = self.index_of(command.actor) else {
            return result(command.actor, CommandStatus::UnknownActor);
        };
        let actor = &self.actors[index];
        let (id, handle) = (actor.id, actor.body);
        if actor.kind == ActorKind::Static && kind != CommandKind::Destroy {
            return result(id, CommandStatus::StaticActor);
        }
        let v = Vector::from_array(command.vector);
        let body = &mut self.physics.bodies[handle];
        match kind {
            CommandKind::Destroy => {
                self.physics.remove_body(handle);
                self.actors.remove(index);
                self.vehicles.retain(|vehicle| vehicle.actor != id);
            }
            CommandKind::SetTransform => {
                let Some(rotation) = rotation_of(command.rotation) else {
                    return result(id, CommandStatus::InvalidArgument);
                };
                body.set_position(Pose::from_parts(v, rotation), true);
            }
            CommandKind::SetTargetVelocity => {
                let [x, y, z, _] = command.rotation;
                body.set_linvel(v, true);
                body.set_angvel(Vector::new(x, y, z), true);
            }
            CommandKind::ApplyForce => {
                body.add_force(v, true);
                self.pushed.push(handle);
            }
            CommandKind::ApplyImpulse => body.apply_impulse(v, true),
            CommandKind::ApplyTorque => {
                body.add_torque(v, true);
                self.pushed.push(handle);
            }
            CommandKind::SetPhysics => body.set_enabled(command.flags & 1 != 0),
            CommandKind::SetGravity => {
                body.set_gravity_scale(if command.flags & 1 != 0 { 1.0 } else { 0.0 }, true)
            }
            CommandKind::VehicleControl => {
                let [throttle, steer, brake, _] = command.params;
                if !((0.0..=1.0).contains(&throttle)
                    && (-1.0..=1.0).contains(&steer)
                    && (0.0..=1.0).contains(&brake))
                {
                    return result(id, CommandStatus::InvalidArgument);
                }
                let Some(vehicle) = self.vehicles.iter_mut().find(|v| v.actor == id) else {
                    return result(id, CommandStatus::NotAVehicle);
                };
                vehicle.throttle = throttle;
                vehicle.steer = steer;
                vehicle.brake = brake;
                vehicle.hand_brake = command.flags & 1 != 0;
                body.wake_up(true);
            }
            CommandKind::SpawnBox
            | CommandKind::SpawnSphere
            | CommandKind::SpawnCapsule
            | CommandKind::SpawnVehicle => unreachable!("spawns handled above"),
        }
        result(id, CommandStatus::Ok)
    }

    fn spawn(&mut self, kind: CommandKind, command: &Command) -> CommandResult {
        let [a, b, c, _] = command.params;
        let (actor_kind, extent) = match kind {
            CommandKind::SpawnBox => (ActorKind::Box, [a, b, c]),
            CommandKind::SpawnSphere => (ActorKind::Sphere, [a, a, a]),
            CommandKind::SpawnCapsule => (ActorKind::Capsule, [a, b, a]),
            _ => (ActorKind::Vehicle, VEHICLE_HALF_EXTENTS),
        };
        let position = command.vector;
        if extent.iter().any(|e| !(*e > 0.0 && *e <= MAX_ACTOR_EXTENT))
            || position.iter().any(|p| p.abs() > MAX_ACTOR_POSITION)
        {
            return result(0, CommandStatus::InvalidArgument);
        }
        let Some(rotation) = rotation_of(command.rotation) else {
            return result(0, CommandStatus::InvalidArgument);
        };
        let placement = Placement {
            kind: actor_kind,
            extent: Vector::from_array(extent),
            position: Vector::from_array(position),
            rotation: rotation.to_scaled_axis(),
            linear_velocity: Vector::ZERO,
            density: if actor_kind == ActorKind::Vehicle {
                100.0
            } else {
                1.0
            },
        };
        result(self.insert(&placement), CommandStatus::Ok)
    }

    /// Advances physics by one frame: `plan.count` rapier steps of
    /// `plan.substep_seconds` (vehicles updated before each), then updates
    /// every actor's acceleration.
    pub fn step(&mut self, plan: &SubstepPlan) {
        self.physics.integration_parameters.dt = plan.substep_seconds;
        for _ in 0..plan.count {
            self.update_vehicles(plan.substep_seconds);
            self.physics.step();
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

    fn update_vehicles(&mut self, dt: f32) {
        for vehicle in &mut self.vehicles {
            let chassis = vehicle.controller.chassis;
            for (i, wheel) in vehicle.controller.wheels_mut().iter_mut().enumerate() {
                let front = i < 2;
                wheel.steering = if front {
                    vehicle.steer * MAX_STEER
                } else {
                    0.0
                };
                wheel.engine_force = if front {
                    0.0
                } else {
                    vehicle.throttle * MAX_ENGINE_FORCE
                };
                wheel.brake = if vehicle.hand_brake && !front {
                    MAX_BRAKE * 4.0
                } else {
                    vehicle.brake * MAX_BRAKE
                };
            }
            let queries = self.physics.broad_phase.as_query_pipeline_mut(
                self.physics.narrow_phase.query_dispatcher(),
                &mut self.physics.bodies,
                &mut self.physics.colliders,
                QueryFilter::exclude_dynamic().exclude_rigid_body(chassis),
            );
            vehicle.controller.update_vehicle(dt, queries);
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

/// A four-wheeled controller for the chassis `body` with half extents `half`.
fn vehicle_controller(body: RigidBodyHandle, half: Vector) -> DynamicRayCastVehicleController {
    let mut controller = DynamicRayCastVehicleController::new(body);
    let tuning = WheelTuning {
        suspension_stiffness: 40.0,
        suspension_damping: 4.0,
        friction_slip: 1.5,
        ..WheelTuning::default()
    };
    let (x, y, z) = (half.x * 0.7, -half.y, half.z);
    // Front wheels first (steered), then the driven rear wheels.
    for position in [
        Vector::new(x, y, z),
        Vector::new(x, y, -z),
        Vector::new(-x, y, z),
        Vector::new(-x, y, -z),
    ] {
        controller.add_wheel(position, -Vector::Y, Vector::Z, 0.3, 0.3, &tuning);
    }
    controller
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::scene::Scene;
    use shared_types::WorldSettings;

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
        let mut world = World::new(&Scene::Empty.placements(0), 1);
        world.insert(&Placement {
            kind: ActorKind::Static,
            extent: Vector::new(100.0, 0.5, 100.0),
            position: Vector::new(0.0, -0.5, 0.0),
            rotation: Vector::ZERO,
            linear_velocity: Vector::ZERO,
            density: 1.0,
        });
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
