//! Commands on actors, sent in batches; one result per command.

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

use crate::wire::wire_enum;
use crate::wire::PROTOCOL_VERSION;

wire_enum! {
    /// What a [`Command`] does. Vectors are in world coordinates (Y up).
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum CommandKind {
        /// Spawn a dynamic box: `vector` = position, `rotation` = quaternion
        /// (x, y, z, w; all zero = identity), `params[0..3]` = half extents.
        SpawnBox = 1,
        /// Spawn a dynamic sphere: `params[0]` = radius.
        SpawnSphere = 2,
        /// Spawn a dynamic capsule along Y: `params[0]` = radius, `params[1]` = half height.
        SpawnCapsule = 3,
        /// Spawn a four-wheeled ray-cast vehicle facing +X: `params[0..3]` =
        /// chassis half extents (X length, Y height, Z width, metres),
        /// `params[3]` = mass (kg); all four zero = the original vehicle
        /// (chassis 2 × 0.5 × 1 m, 100 kg). Wheels, engine and brakes follow
        /// from them ([`VehicleSpec`](crate::vehicle::VehicleSpec)); a partial or out-of-range set
        /// is refused with [`CommandStatus::InvalidArgument`].
        SpawnVehicle = 4,
        /// Remove `actor`.
        Destroy = 5,
        /// Teleport `actor`: `vector` = position, `rotation` = quaternion.
        SetTransform = 6,
        /// Set `actor`'s velocity: `vector` = linear (m/s), `rotation[0..3]` = angular (rad/s).
        SetTargetVelocity = 7,
        /// Push `actor` with `vector` newtons during the next frame.
        ApplyForce = 8,
        /// Kick `actor` with an impulse of `vector` N·s, at once.
        ApplyImpulse = 9,
        /// Twist `actor` with `vector` N·m during the next frame.
        ApplyTorque = 10,
        /// Enable (`flags` bit 0 set) or disable `actor`'s physics simulation.
        SetPhysics = 11,
        /// Enable (`flags` bit 0 set) or disable gravity on `actor`.
        SetGravity = 12,
        /// Drive a vehicle: `params` = throttle 0..1, steer -1..1 (positive
        /// left), brake 0..1; `flags` bit 0 = hand brake, bit 1
        /// ([`Command::REVERSE`]) = the reverse gear (the throttle drives
        /// it backwards). Holds until changed.
        VehicleControl = 13,
        /// Hold `actor` at a constant velocity, `vector` (m/s) in the
        /// actor's own axes, every physics step until switched off
        /// (`flags` bit 0 set: on; clear: off). CARLA's
        /// `enable_constant_velocity`.
        ConstantVelocity = 14,
        /// Move the sun that lights RGB cameras (`actor` 0): `params[0]` =
        /// azimuth, `params[1]` = altitude, degrees, any finite angles
        /// (CARLA's `sun_azimuth_angle`, `sun_altitude_angle`).
        SetSun = 15,
        /// Spawn a walker (a pedestrian) standing at `vector`, facing as
        /// `rotation` says (only its turn about Y is kept): `params[0]` =
        /// radius, `params[1]` = half height (its round ends included,
        /// larger than the radius), metres.
        SpawnWalker = 16,
        /// Walk: `vector` = direction (world axes; its horizontal part is
        /// used, normalised; zero stands still), `params[0]` = speed, m/s
        /// (0..=[`MAX_WALKER_SPEED`](crate::limits::MAX_WALKER_SPEED));
        /// `flags` bit 0 = jump (once, from the ground). Holds until
        /// changed. CARLA's `WalkerControl`.
        WalkerControl = 17,
        /// Show `params[0]` (a [`LightState`](crate::LightState) code) on
        /// traffic light `actor` until its group's cycle moves on (at
        /// once if frozen: until unfrozen). CARLA's `set_state`.
        TrafficLightState = 18,
        /// Set how long traffic light `actor` stays green (`params[0]`),
        /// yellow (`params[1]`) and red (`params[2]`), seconds, each
        /// 0..=[`MAX_LIGHT_SECONDS`](crate::limits::MAX_LIGHT_SECONDS);
        /// `flags` bits 0, 1, 2 say which of the three are set.
        TrafficLightTimes = 19,
        /// Freeze (`flags` bit 0 set) or unfreeze traffic lights where
        /// they are: `actor`'s junction group, or with `actor` 0 every
        /// group.
        FreezeTrafficLights = 20,
        /// Start `actor`'s junction group's cycle again (its first light
        /// green, the others red, times from zero), or with `actor` 0
        /// every group's.
        ResetTrafficLights = 21,
        /// Drive a vehicle to a steering angle and a speed (CARLA's
        /// `VehicleAckermannControl`): `params` = steering angle (radians,
        /// positive left, within ±π/2), steering speed (rad/s, 0: at once),
        /// speed (m/s along the vehicle, negative backwards, within
        /// ±[`MAX_ACKERMANN_SPEED`](crate::limits::MAX_ACKERMANN_SPEED)),
        /// acceleration (m/s², 0: as hard as the vehicle can); `rotation[0]`
        /// = jerk (m/s³, accepted, not followed). Holds until a
        /// `VehicleControl` or another target replaces it.
        VehicleAckermann = 22,
    }
}

impl CommandKind {
    /// Whether the command sets traffic lights.
    pub fn sets_lights(&self) -> bool {
        matches!(
            self,
            Self::TrafficLightState
                | Self::TrafficLightTimes
                | Self::FreezeTrafficLights
                | Self::ResetTrafficLights
        )
    }

    /// Whether the command creates an actor.
    pub fn spawns(&self) -> bool {
        matches!(
            self,
            Self::SpawnBox
                | Self::SpawnSphere
                | Self::SpawnCapsule
                | Self::SpawnVehicle
                | Self::SpawnWalker
        )
    }
}

/// One command in a batch. Build it with the constructors.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::Command/1")]
pub struct Command {
    /// [`CommandKind`] as `u32`.
    pub kind: u32,
    /// Kind-specific flags (see [`CommandKind`]).
    pub flags: u32,
    /// The actor acted on (0 for spawns).
    pub actor: u64,
    /// Position, velocity, force, impulse or torque.
    pub vector: [f32; 3],
    /// Zero.
    pub reserved: u32,
    /// Orientation (x, y, z, w), or angular velocity in the first three.
    pub rotation: [f32; 4],
    /// Sizes or vehicle control.
    pub params: [f32; 4],
}

impl Command {
    /// The flag bit that switches on what a command switches: physics
    /// (`SetPhysics`), gravity (`SetGravity`), the hand brake
    /// (`VehicleControl`).
    pub const ON: u32 = 1;
    /// The flag bit of `VehicleControl` that engages the reverse gear.
    pub const REVERSE: u32 = 2;

    fn new(kind: CommandKind, actor: u64) -> Self {
        Self {
            kind: kind as u32,
            actor,
            ..Self::default()
        }
    }

    /// Move the sun that lights RGB cameras to `sun`.
    pub fn set_sun(sun: crate::camera::Sun) -> Self {
        Self {
            params: [sun.azimuth, sun.altitude, 0.0, 0.0],
            ..Self::new(CommandKind::SetSun, 0)
        }
    }

    /// Spawn a box with half extents `half` at `at`.
    pub fn spawn_box(at: [f32; 3], half: [f32; 3]) -> Self {
        Self {
            vector: at,
            params: [half[0], half[1], half[2], 0.0],
            ..Self::new(CommandKind::SpawnBox, 0)
        }
    }

    /// Spawn a sphere of `radius` at `at`.
    pub fn spawn_sphere(at: [f32; 3], radius: f32) -> Self {
        Self {
            vector: at,
            params: [radius, 0.0, 0.0, 0.0],
            ..Self::new(CommandKind::SpawnSphere, 0)
        }
    }

    /// Spawn a capsule along Y at `at`.
    pub fn spawn_capsule(at: [f32; 3], radius: f32, half_height: f32) -> Self {
        Self {
            vector: at,
            params: [radius, half_height, 0.0, 0.0],
            ..Self::new(CommandKind::SpawnCapsule, 0)
        }
    }

    /// Spawn a vehicle at `at`, facing +X.
    pub fn spawn_vehicle(at: [f32; 3]) -> Self {
        Self {
            vector: at,
            ..Self::new(CommandKind::SpawnVehicle, 0)
        }
    }

    /// Spawn a vehicle of chassis half extents `half` (simbus axes) and
    /// `mass` kg at `at`, facing +X.
    pub fn spawn_sized_vehicle(at: [f32; 3], half: [f32; 3], mass: f32) -> Self {
        Self {
            vector: at,
            params: [half[0], half[1], half[2], mass],
            ..Self::new(CommandKind::SpawnVehicle, 0)
        }
    }

    /// Spawn a walker of `radius` and `half_height` (round ends
    /// included) standing at `at`, facing +X.
    pub fn spawn_walker(at: [f32; 3], radius: f32, half_height: f32) -> Self {
        Self {
            vector: at,
            params: [radius, half_height, 0.0, 0.0],
            ..Self::new(CommandKind::SpawnWalker, 0)
        }
    }

    /// Walk walker `actor` along `direction` (world axes) at `speed` m/s,
    /// jumping once if `jump`.
    pub fn walker_control(actor: u64, direction: [f32; 3], speed: f32, jump: bool) -> Self {
        Self {
            flags: if jump { Self::ON } else { 0 },
            vector: direction,
            params: [speed, 0.0, 0.0, 0.0],
            ..Self::new(CommandKind::WalkerControl, actor)
        }
    }

    /// Show `state` on traffic light `actor`.
    pub fn traffic_light_state(actor: u64, state: crate::LightState) -> Self {
        Self {
            params: [state as u32 as f32, 0.0, 0.0, 0.0],
            ..Self::new(CommandKind::TrafficLightState, actor)
        }
    }

    /// Set traffic light `actor`'s green, yellow and red times, seconds;
    /// `None` leaves one as it is.
    pub fn traffic_light_times(actor: u64, times: [Option<f32>; 3]) -> Self {
        let mut command = Self::new(CommandKind::TrafficLightTimes, actor);
        for (i, time) in times.into_iter().enumerate() {
            if let Some(seconds) = time {
                command.flags |= 1 << i;
                command.params[i] = seconds;
            }
        }
        command
    }

    /// Freeze or unfreeze the lights of `actor`'s group (`actor` 0: all).
    pub fn freeze_traffic_lights(actor: u64, frozen: bool) -> Self {
        Self {
            flags: if frozen { Self::ON } else { 0 },
            ..Self::new(CommandKind::FreezeTrafficLights, actor)
        }
    }

    /// Restart the cycle of `actor`'s group (`actor` 0: every group).
    pub fn reset_traffic_lights(actor: u64) -> Self {
        Self::new(CommandKind::ResetTrafficLights, actor)
    }

    /// Drive vehicle `actor` to steering angle `steer` (radians, positive
    /// left) at `steer_speed` rad/s and to `speed` m/s at `acceleration`
    /// m/s² (0: at once / as hard as it can).
    pub fn vehicle_ackermann(
        actor: u64,
        steer: f32,
        steer_speed: f32,
        speed: f32,
        acceleration: f32,
    ) -> Self {
        Self {
            params: [steer, steer_speed, speed, acceleration],
            ..Self::new(CommandKind::VehicleAckermann, actor)
        }
    }

    /// Remove `actor`.
    pub fn destroy(actor: u64) -> Self {
        Self::new(CommandKind::Destroy, actor)
    }

    /// Teleport `actor` to `position` with orientation `rotation` (x, y, z, w).
    pub fn set_transform(actor: u64, position: [f32; 3], rotation: [f32; 4]) -> Self {
        Self {
            vector: position,
            rotation,
            ..Self::new(CommandKind::SetTransform, actor)
        }
    }

    /// Set `actor`'s linear and angular velocity.
    pub fn set_target_velocity(actor: u64, linear: [f32; 3], angular: [f32; 3]) -> Self {
        Self {
            vector: linear,
            rotation: [angular[0], angular[1], angular[2], 0.0],
            ..Self::new(CommandKind::SetTargetVelocity, actor)
        }
    }

    /// Push `actor` with `force` newtons during the next frame.
    pub fn apply_force(actor: u64, force: [f32; 3]) -> Self {
        Self {
            vector: force,
            ..Self::new(CommandKind::ApplyForce, actor)
        }
    }

    /// Kick `actor` with `impulse` N·s.
    pub fn apply_impulse(actor: u64, impulse: [f32; 3]) -> Self {
        Self {
            vector: impulse,
            ..Self::new(CommandKind::ApplyImpulse, actor)
        }
    }

    /// Twist `actor` with `torque` N·m during the next frame.
    pub fn apply_torque(actor: u64, torque: [f32; 3]) -> Self {
        Self {
            vector: torque,
            ..Self::new(CommandKind::ApplyTorque, actor)
        }
    }

    /// Enable or disable `actor`'s physics.
    pub fn set_physics(actor: u64, enabled: bool) -> Self {
        Self {
            flags: if enabled { Self::ON } else { 0 },
            ..Self::new(CommandKind::SetPhysics, actor)
        }
    }

    /// Enable or disable gravity on `actor`.
    pub fn set_gravity(actor: u64, enabled: bool) -> Self {
        Self {
            flags: if enabled { Self::ON } else { 0 },
            ..Self::new(CommandKind::SetGravity, actor)
        }
    }

    /// Hold `actor` at `velocity` (m/s, in its own axes) from now on, or
    /// (`None`) let it go.
    pub fn constant_velocity(actor: u64, velocity: Option<[f32; 3]>) -> Self {
        Self {
            flags: if velocity.is_some() { Self::ON } else { 0 },
            vector: velocity.unwrap_or_default(),
            ..Self::new(CommandKind::ConstantVelocity, actor)
        }
    }

    /// Drive vehicle `actor`.
    pub fn vehicle_control(
        actor: u64,
        throttle: f32,
        steer: f32,
        brake: f32,
        hand_brake: bool,
    ) -> Self {
        Self {
            flags: if hand_brake { Self::ON } else { 0 },
            params: [throttle, steer, brake, 0.0],
            ..Self::new(CommandKind::VehicleControl, actor)
        }
    }

    /// This `VehicleControl` in the reverse gear (or, `false`, forward).
    pub fn in_reverse(mut self, reverse: bool) -> Self {
        if reverse {
            self.flags |= Self::REVERSE;
        } else {
            self.flags &= !Self::REVERSE;
        }
        self
    }
}

wire_enum! {
    /// How one command ended.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum CommandStatus {
        /// Executed.
        Ok = 0,
        /// No actor has this id (never had, or destroyed).
        UnknownActor = 1,
        /// A value is NaN, infinite or out of range.
        InvalidArgument = 2,
        /// The command needs a vehicle and the actor is not one.
        NotAVehicle = 3,
        /// The command kind is unknown to this server.
        UnknownCommand = 4,
        /// The actor is static and cannot be changed.
        StaticActor = 5,
        /// A spawn whose body would overlap another body (CARLA's "Spawn
        /// failed because of collision at spawn position"); the result's
        /// `actor` is the actor whose body is there.
        SpawnCollision = 6,
        /// The command needs a walker and the actor is not one.
        NotAWalker = 7,
        /// The command needs a traffic light and the actor is not one.
        NotATrafficLight = 8,
    }
}

impl std::fmt::Display for CommandStatus {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Ok => "ok",
            Self::UnknownActor => "unknown actor",
            Self::InvalidArgument => {
                "invalid argument: values must be finite; sizes in (0, 1000] m, positions \
                 within +-100000 m of the origin, throttle and brake in 0..=1, steer in -1..=1; \
                 a vehicle's params all zero or half extents in 0.05..=20 m and mass in \
                 1..=100000 kg; a walker's radius in 0.05..=2 m, its half height above \
                 the radius and up to 5 m, its speed in 0..=20 m/s; a traffic light's state a \
                 known code and its times in 0..=1000000 s; an Ackermann steer within +-pi/2 rad, its \
                 speed within +-100 m/s, steering speed, acceleration and jerk not negative"
            }
            Self::NotAVehicle => "the actor is not a vehicle",
            Self::NotAWalker => "the actor is not a walker",
            Self::NotATrafficLight => "the actor is not a traffic light",
            Self::UnknownCommand => "unknown command",
            Self::StaticActor => "the actor is static",
            Self::SpawnCollision => "spawn failed because of a collision at the spawn position",
        })
    }
}

/// The result of one command: the actor it concerned (the new id for a
/// spawn) and its [`CommandStatus`].
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::CommandResult/1")]
pub struct CommandResult {
    /// The actor: the new id for a spawn; for a spawn refused with
    /// [`CommandStatus::SpawnCollision`] the actor whose body is at the
    /// spawn position; 0 when a spawn failed otherwise.
    pub actor: u64,
    /// [`CommandStatus`] as `u32`.
    pub status: u32,
    /// Zero.
    pub reserved: u32,
}

/// The user header of a batch request.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::BatchHeader/1")]
pub struct BatchHeader {
    /// [`PROTOCOL_VERSION`] of the sender.
    pub protocol_version: u32,
    /// Process id of the sender, as it states it: for logs only. Whether a
    /// ticking batch comes from the ticker's process is decided by the
    /// sending port (iceoryx2's request header), never by this field.
    pub pid: u32,
    /// [`BatchHeader::TICK`] and future flags.
    pub flags: u32,
    /// Zero.
    pub reserved: u32,
}

impl BatchHeader {
    /// Flag: after applying the batch, step one frame (ticker only).
    pub const TICK: u32 = 1;

    /// A header from this process.
    pub fn new(tick: bool) -> Self {
        Self {
            protocol_version: PROTOCOL_VERSION,
            pid: crate::wire::this_process_id(),
            flags: if tick { Self::TICK } else { 0 },
            reserved: 0,
        }
    }
}

/// The user header of a batch response.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::BatchResponseHeader/1")]
pub struct BatchResponseHeader {
    /// [`PROTOCOL_VERSION`] of the server.
    pub protocol_version: u32,
    /// [`ResponseStatus`](crate::wire::ResponseStatus) of the batch as a whole.
    pub status: u32,
    /// The first frame that shows the batch's effects. With
    /// [`BatchHeader::TICK`], the frame that was stepped.
    pub frame: u64,
}

crate::wire::responses!(BatchResponseHeader);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_are_fixed() {
        assert_eq!(std::mem::size_of::<Command>(), 64);
        assert_eq!(std::mem::size_of::<CommandResult>(), 16);
    }

    #[test]
    fn kinds_and_statuses_are_numbered_without_gaps() {
        let kinds: Vec<u32> = CommandKind::ALL.into_iter().map(u32::from).collect();
        assert_eq!(kinds, (1..=22).collect::<Vec<_>>());
        let statuses: Vec<u32> = CommandStatus::ALL.into_iter().map(u32::from).collect();
        assert_eq!(statuses, (0..=8).collect::<Vec<_>>());
    }
}
