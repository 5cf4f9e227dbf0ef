//! What each wire command does to the world: spawn, destroy, set a pose or
//! a velocity, push, switch physics or gravity, drive a vehicle. A command
//! that is invalid (NaN, out of range, unknown actor, static actor, not a
//! vehicle) changes nothing and says why in its result.

use rapier3d::prelude::*;
use shared_types::limits::{MAX_ACTOR_EXTENT, MAX_ACTOR_POSITION};
use shared_types::{ActorKind, Command, CommandKind, CommandResult, CommandStatus};

use crate::scene::Placement;
use crate::vehicles::VEHICLE_HALF_EXTENTS;
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
                self.vehicles.remove(id);
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
                vehicle.set_control(throttle, steer, brake, command.flags & Command::ON != 0);
                body.wake_up(true);
            }
            CommandKind::SpawnBox
            | CommandKind::SpawnSphere
            | CommandKind::SpawnCapsule
            | CommandKind::SpawnVehicle => return self.spawn(kind, command),
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
}
