//! What each wire command does to the world: spawn, destroy, set a pose or
//! a velocity, push, switch physics or gravity, drive a vehicle, walk a
//! walker, set a traffic light. A command that is invalid (NaN, out of
//! range, unknown actor, static actor, not a vehicle, walker or light)
//! changes nothing and says why in its result.

use rapier3d::prelude::*;
use shared_types::limits::{
    MAX_ACKERMANN_SPEED, MAX_ACTOR_EXTENT, MAX_ACTOR_POSITION, MAX_LIGHT_SECONDS,
    MAX_WALKER_HALF_HEIGHT, MAX_WALKER_RADIUS, MAX_WALKER_SPEED, MIN_WALKER_RADIUS,
};
use shared_types::{
    ActorKind, Command, CommandKind, CommandResult, CommandStatus, LightState, VehicleSpec,
};
use tracing::debug;

use crate::scene::Placement;
use crate::vehicles::Ackermann;
use crate::world::World;

/// Whether every value is finite.
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

/// A command's result.
fn result(actor: u64, status: CommandStatus) -> CommandResult {
    CommandResult {
        actor,
        status: status as u32,
        reserved: 0,
    }
}

impl World {
    /// Moves the sun (no actor).
    fn set_sun(&mut self, command: &Command) -> CommandResult {
        let [azimuth, altitude, ..] = command.params;
        let sun = shared_types::Sun { azimuth, altitude };
        if !sun.valid() {
            return result(0, CommandStatus::InvalidArgument);
        }
        self.sun = sun;
        result(0, CommandStatus::Ok)
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
        if kind == CommandKind::SetSun {
            return self.set_sun(command);
        }
        if kind.sets_lights() {
            return self.set_lights(kind, command);
        }
        let Some(index) = self.index_of(command.actor) else {
            return result(command.actor, CommandStatus::UnknownActor);
        };
        let actor = &self.actors[index];
        let (id, handle) = (actor.id, actor.body);
        let signal = matches!(actor.kind, ActorKind::TrafficLight | ActorKind::TrafficSign);
        // Lights and signs are the roads' (as in CARLA's towns): they
        // stay, and stay put.
        if signal || (actor.kind == ActorKind::Static && kind != CommandKind::Destroy) {
            return result(id, CommandStatus::StaticActor);
        }
        let v = Vector::from_array(command.vector);
        let body = &mut self.physics.bodies[handle];
        match kind {
            CommandKind::Destroy => {
                self.held.retain(|&(h, _)| h != handle);
                self.physics.remove_body(handle);
                self.actors.remove(index);
                self.vehicles.remove(id);
                self.ackermann.retain(|a| a.actor != id);
                self.walkers.remove(id);
            }
            CommandKind::SetTransform => {
                let Some(rotation) = rotation_of(command.rotation) else {
                    return result(id, CommandStatus::InvalidArgument);
                };
                if command.vector.iter().any(|p| p.abs() > MAX_ACTOR_POSITION) {
                    return result(id, CommandStatus::InvalidArgument);
                }
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
            CommandKind::SetPhysics => body.set_enabled(command.flags & Command::ON != 0),
            CommandKind::SetGravity => body.set_gravity_scale(
                if command.flags & Command::ON != 0 {
                    1.0
                } else {
                    0.0
                },
                true,
            ),
            CommandKind::ConstantVelocity => {
                self.held.retain(|&(h, _)| h != handle);
                if command.flags & Command::ON != 0 {
                    self.held.push((handle, v));
                }
                body.wake_up(true);
            }
            CommandKind::VehicleControl => {
                let [throttle, steer, brake, _] = command.params;
                if !((0.0..=1.0).contains(&throttle)
                    && (-1.0..=1.0).contains(&steer)
                    && (0.0..=1.0).contains(&brake))
                {
                    return result(id, CommandStatus::InvalidArgument);
                }
                let Some(vehicle) = self.vehicles.get_mut(id) else {
                    return result(id, CommandStatus::NotAVehicle);
                };
                // A control replaces any Ackermann target.
                self.ackermann.retain(|a| a.actor != id);
                vehicle.set_control(
                    throttle,
                    steer,
                    brake,
                    command.flags & Command::ON != 0,
                    command.flags & Command::REVERSE != 0,
                );
                body.wake_up(true);
            }
            CommandKind::VehicleAckermann => {
                let [steer, steer_speed, speed, acceleration] = command.params;
                let jerk = command.rotation[0];
                let valid = steer.abs() <= std::f32::consts::FRAC_PI_2
                    && speed.abs() <= MAX_ACKERMANN_SPEED
                    && steer_speed >= 0.0
                    && acceleration >= 0.0
                    && jerk >= 0.0;
                if !valid {
                    return result(id, CommandStatus::InvalidArgument);
                }
                if self.vehicles.get_mut(id).is_none() {
                    return result(id, CommandStatus::NotAVehicle);
                }
                let target = Ackermann::new(id, command.params, self.vehicles.steering(id));
                self.ackermann.retain(|a| a.actor != id);
                self.ackermann.push(target);
                body.wake_up(true);
            }
            CommandKind::WalkerControl => {
                let speed = command.params[0];
                if !(0.0..=MAX_WALKER_SPEED).contains(&speed) {
                    return result(id, CommandStatus::InvalidArgument);
                }
                let Some(walker) = self.walkers.get_mut(id) else {
                    return result(id, CommandStatus::NotAWalker);
                };
                walker.set_control(v, speed, command.flags & Command::ON != 0);
                body.wake_up(true);
            }
            CommandKind::SpawnBox
            | CommandKind::SpawnSphere
            | CommandKind::SpawnCapsule
            | CommandKind::SpawnVehicle
            | CommandKind::SpawnWalker => return self.spawn(kind, command),
            CommandKind::SetSun => return self.set_sun(command),
            CommandKind::TrafficLightState
            | CommandKind::TrafficLightTimes
            | CommandKind::FreezeTrafficLights
            | CommandKind::ResetTrafficLights => return self.set_lights(kind, command),
        }
        result(id, CommandStatus::Ok)
    }

    /// A traffic-light command: on one light, or (freeze, reset) with
    /// actor 0 on all of them.
    fn set_lights(&mut self, kind: CommandKind, command: &Command) -> CommandResult {
        let actor = command.actor;
        let lights = &mut self.lights;
        let done = match kind {
            CommandKind::TrafficLightState => {
                let code = command.params[0];
                let state = (code.fract() == 0.0 && code >= 0.0)
                    .then(|| LightState::from_u32(code as u32))
                    .flatten();
                let Some(state) = state else {
                    return result(actor, CommandStatus::InvalidArgument);
                };
                lights.set_state(actor, state)
            }
            CommandKind::TrafficLightTimes => {
                let mut times = [None; 3];
                for (i, time) in times.iter_mut().enumerate() {
                    if command.flags & (1 << i) != 0 {
                        let seconds = command.params[i];
                        if !(0.0..=MAX_LIGHT_SECONDS).contains(&seconds) {
                            return result(actor, CommandStatus::InvalidArgument);
                        }
                        *time = Some(seconds);
                    }
                }
                lights.set_times(actor, times)
            }
            CommandKind::FreezeTrafficLights => {
                lights.freeze(actor, command.flags & Command::ON != 0)
            }
            _ => lights.reset(actor),
        };
        let status = if done {
            CommandStatus::Ok
        } else if self.index_of(actor).is_some() {
            CommandStatus::NotATrafficLight
        } else {
            CommandStatus::UnknownActor
        };
        result(actor, status)
    }

    fn spawn(&mut self, kind: CommandKind, command: &Command) -> CommandResult {
        let [a, b, c, _] = command.params;
        let mut vehicle = None;
        let (actor_kind, extent) = match kind {
            CommandKind::SpawnBox => (ActorKind::Box, [a, b, c]),
            CommandKind::SpawnSphere => (ActorKind::Sphere, [a, a, a]),
            CommandKind::SpawnCapsule => (ActorKind::Capsule, [a, b, a]),
            CommandKind::SpawnWalker => {
                if !((MIN_WALKER_RADIUS..=MAX_WALKER_RADIUS).contains(&a)
                    && b > a
                    && b <= MAX_WALKER_HALF_HEIGHT)
                {
                    return result(0, CommandStatus::InvalidArgument);
                }
                (ActorKind::Walker, [a, b, a])
            }
            _ => match VehicleSpec::from_params(command.params) {
                Ok(spec) => {
                    vehicle = Some(spec);
                    (ActorKind::Vehicle, spec.half_extents)
                }
                Err(e) => {
                    debug!("SpawnVehicle refused: {e}");
                    return result(0, CommandStatus::InvalidArgument);
                }
            },
        };
        let position = command.vector;
        if extent.iter().any(|e| !(*e > 0.0 && *e <= MAX_ACTOR_EXTENT))
            || position.iter().any(|p| p.abs() > MAX_ACTOR_POSITION)
        {
            return result(0, CommandStatus::InvalidArgument);
        }
        let Some(mut rotation) = rotation_of(command.rotation) else {
            return result(0, CommandStatus::InvalidArgument);
        };
        if actor_kind == ActorKind::Walker {
            // Upright: only the turn about Y is kept.
            let facing = rotation * Vector::X;
            rotation = Rotation::from_rotation_y((-facing.z).atan2(facing.x));
        }
        let mut placement = Placement {
            kind: actor_kind,
            extent: Vector::from_array(extent),
            position: Vector::from_array(position),
            rotation: rotation.to_scaled_axis(),
            linear_velocity: Vector::ZERO,
            density: vehicle.as_ref().map_or(1.0, VehicleSpec::density),
            signal: None,
        };
        if actor_kind == ActorKind::Walker {
            // A walker asked for with its feet in (or on) the ground stands
            // just above it (CARLA's navigation points are on the ground).
            if let Some(standing) = self.standing_on_ground(&placement) {
                if standing.y >= placement.position.y {
                    placement.position = standing;
                }
            }
        }
        if let Some(occupant) = self.occupant(&placement) {
            // The result names what is there instead of a new actor.
            return result(occupant, CommandStatus::SpawnCollision);
        }
        let id = self.insert(&placement);
        if let (Some(spec), Some(actor)) = (vehicle, self.actors.last()) {
            // `insert` built the original vehicle: this one is built as its
            // params say.
            let body = actor.body;
            self.vehicles.remove(id);
            self.vehicles.add(id, body, &spec);
        }
        result(id, CommandStatus::Ok)
    }
}

#[cfg(test)]
pub(crate) mod tests {
    use super::*;
    use crate::clock::SubstepPlan;
    use crate::scene::Scene;
    use shared_types::{ActorState, WorldSettings};

    /// A world with a 200 × 200 m ground.
    pub(crate) fn world_on_ground() -> World {
        let mut world = World::new(&Scene::Empty.placements(0), 1);
        world.insert(&Placement {
            kind: ActorKind::Static,
            extent: Vector::new(100.0, 0.5, 100.0),
            position: Vector::new(0.0, -0.5, 0.0),
            rotation: Vector::ZERO,
            linear_velocity: Vector::ZERO,
            density: 1.0,
            signal: None,
        });
        world
    }

    /// A 1 850 kg sedan of CARLA's size, standing on the ground at the origin.
    fn sedan() -> Command {
        Command::spawn_sized_vehicle([0.0, 1.1, 0.0], [2.4, 0.74, 1.08], 1850.0)
    }

    /// Steps `world` `frames` frames of 0.05 s (substeps of 0.01 s).
    pub(crate) fn step(world: &mut World, frames: usize) {
        let settings = WorldSettings {
            fixed_delta_seconds: Some(0.05),
            ..Default::default()
        };
        let plan = SubstepPlan::new(settings.fixed_delta_nanos().unwrap(), &settings);
        for _ in 0..frames {
            world.step(&plan);
        }
    }

    /// Actor `id`'s state, as published.
    pub(crate) fn state(world: &World, id: u64) -> ActorState {
        world.actor_state(world.index_of(id).expect("actor exists"))
    }

    #[test]
    fn a_sized_vehicle_has_its_size_rests_on_its_wheels_and_drives() {
        for (half, mass) in [([2.4, 0.74, 1.08], 1850.0), ([5.1, 2.1, 1.97], 10_000.0)] {
            let mut world = world_on_ground();
            let at = [0.0, half[1] + 0.3, 0.0];
            let r = world.apply(&Command::spawn_sized_vehicle(at, half, mass));
            assert_eq!(r.status, CommandStatus::Ok as u32);
            assert_eq!(state(&world, r.actor).extent, half);
            step(&mut world, 40);
            let rest = state(&world, r.actor).position;
            // On its wheels: the chassis's bottom just above the ground.
            let clearance = rest[1] - half[1];
            assert!((0.0..0.3).contains(&clearance), "{mass} kg: {clearance}");
            world.apply(&Command::vehicle_control(r.actor, 1.0, 0.0, 0.0, false));
            step(&mut world, 40);
            // At least 1 m/s² for 2 s, forward (+X).
            let moved = state(&world, r.actor).position[0] - rest[0];
            assert!(moved > 1.5, "{mass} kg moved {moved} m in 2 s");
        }
    }

    /// A car at 10 m/s slows by about a tenth of a full brake under a
    /// brake of 0.1, and by about `FULL_BRAKE_DECELERATION` under a full
    /// one (CARLA's cars brake at about that), whatever the physics step.
    #[test]
    fn a_brake_slows_a_car_in_proportion_to_how_hard_it_is_pressed() {
        let half = [2.4, 0.74, 1.08];
        let decelerations: Vec<f32> = [0.1, 0.5, 1.0]
            .into_iter()
            .map(|brake| {
                let mut world = world_on_ground();
                let r = world.apply(&Command::spawn_sized_vehicle([0.0, 1.1, 0.0], half, 1850.0));
                step(&mut world, 20);
                world.apply(&Command::set_target_velocity(
                    r.actor,
                    [10.0, 0.0, 0.0],
                    [0.0; 3],
                ));
                step(&mut world, 1);
                let before = state(&world, r.actor).linear_velocity[0];
                world.apply(&Command::vehicle_control(r.actor, 0.0, 0.0, brake, false));
                step(&mut world, 10);
                let after = state(&world, r.actor).linear_velocity[0];
                (before - after) / 0.5
            })
            .collect();
        let full = shared_types::FULL_BRAKE_DECELERATION;
        assert!(
            (0.05 * full..0.2 * full).contains(&decelerations[0]),
            "{decelerations:?}"
        );
        assert!(
            (0.35 * full..0.65 * full).contains(&decelerations[1]),
            "{decelerations:?}"
        );
        assert!(
            (0.8 * full..1.25 * full).contains(&decelerations[2]),
            "{decelerations:?}"
        );
    }

    /// A parked car that rapier put to sleep reads at rest: no velocity
    /// left over from its suspension's impulses (CARLA's client read
    /// +0.59 m/s up for ever); a control wakes it and it drives.
    #[test]
    fn a_sleeping_parked_car_stays_still_and_a_control_wakes_it() {
        let mut world = world_on_ground();
        let r = world.apply(&sedan());
        step(&mut world, 100);
        let body = world.body_of(r.actor).expect("a body");
        world.physics.bodies[body].sleep();
        step(&mut world, 40);
        let parked = state(&world, r.actor);
        assert_eq!(parked.flags & ActorState::SLEEPING, ActorState::SLEEPING);
        assert_eq!(
            (parked.linear_velocity, parked.angular_velocity),
            ([0.0; 3], [0.0; 3])
        );
        world.apply(&Command::vehicle_control(r.actor, 1.0, 0.0, 0.0, false));
        step(&mut world, 20);
        assert!(state(&world, r.actor).linear_velocity[0] > 1.0);
    }

    /// In the reverse gear the throttle drives a car backwards; out of it,
    /// forwards again.
    #[test]
    fn the_reverse_gear_drives_a_car_backwards() {
        let mut world = world_on_ground();
        let r = world.apply(&sedan());
        step(&mut world, 20);
        let start = state(&world, r.actor).position[0];
        world.apply(&Command::vehicle_control(r.actor, 1.0, 0.0, 0.0, false).in_reverse(true));
        step(&mut world, 40);
        let back = state(&world, r.actor).position[0];
        assert!(back < start - 1.5, "{start} -> {back}");
        world.apply(&Command::vehicle_control(r.actor, 1.0, 0.0, 0.0, false));
        step(&mut world, 80);
        assert!(state(&world, r.actor).linear_velocity[0] > 1.0);
    }

    /// An Ackermann target drives a car to its speed and holds it there,
    /// backwards too, and a plain control takes the car back.
    #[test]
    fn an_ackermann_target_reaches_its_speed_and_a_control_ends_it() {
        let mut world = world_on_ground();
        let r = world.apply(&sedan());
        step(&mut world, 20);
        let ok = world.apply(&Command::vehicle_ackermann(r.actor, 0.0, 0.0, 6.0, 2.0));
        assert_eq!(ok.status, CommandStatus::Ok as u32);
        // 2 m/s² for 3 s, then held.
        step(&mut world, 40);
        let climbing = state(&world, r.actor).linear_velocity[0];
        assert!((3.0..5.0).contains(&climbing), "{climbing}");
        step(&mut world, 100);
        let held = state(&world, r.actor).linear_velocity[0];
        assert!((held - 6.0).abs() < 0.3, "{held}");
        world.apply(&Command::vehicle_ackermann(r.actor, 0.0, 0.0, -2.0, 0.0));
        step(&mut world, 160);
        let back = state(&world, r.actor).linear_velocity[0];
        assert!((back + 2.0).abs() < 0.3, "{back}");
        world.apply(&Command::vehicle_control(r.actor, 0.0, 0.0, 1.0, false));
        step(&mut world, 60);
        assert!(state(&world, r.actor).linear_velocity[0].abs() < 0.1);
        let bad = [
            Command::vehicle_ackermann(r.actor, 2.0, 0.0, 1.0, 0.0),
            Command::vehicle_ackermann(r.actor, 0.0, -1.0, 1.0, 0.0),
            Command::vehicle_ackermann(r.actor, 0.0, 0.0, 101.0, 0.0),
        ];
        for command in bad {
            assert_eq!(
                world.apply(&command).status,
                CommandStatus::InvalidArgument as u32
            );
        }
        let ground = world.first_id();
        assert_eq!(
            world
                .apply(&Command::vehicle_ackermann(ground, 0.0, 0.0, 1.0, 0.0))
                .status,
            CommandStatus::StaticActor as u32
        );
    }

    #[test]
    fn vehicle_params_that_are_partial_or_absurd_are_refused() {
        let mut world = world_on_ground();
        for (half, mass) in [
            ([2.0, 0.7, 1.0], 0.0),
            ([2.0, 0.7, 1.0], -5.0),
            ([2.0, 0.7, 1.0], 1e9),
            ([200.0, 0.7, 1.0], 1500.0),
            ([2.0, f32::NAN, 1.0], 1500.0),
        ] {
            let r = world.apply(&Command::spawn_sized_vehicle([0.0, 2.0, 0.0], half, mass));
            assert_eq!(
                r.status,
                CommandStatus::InvalidArgument as u32,
                "{half:?} {mass}"
            );
            assert_eq!(r.actor, 0);
        }
        // All zero: the original vehicle.
        let r = world.apply(&Command::spawn_vehicle([0.0, 2.0, 0.0]));
        assert_eq!(state(&world, r.actor).extent, [1.0, 0.25, 0.5]);
    }
}
