//! CARLA's actor commands — the RPC calls (`set_actor_transform`,
//! `apply_control_to_vehicle`, ...) and `carla.command.*` in batches — as
//! simbus commands, and CARLA's msgpack shapes they carry.

use rmpv::Value;
use shared_types::{Command, LightState};

use crate::blueprints::Description;
use crate::convert;
use crate::error::CallError;
use crate::stream::ActorInfo;
use crate::wire::{CarlaTransform, CarlaVehicleControl};

type V3 = [f32; 3];

/// A number, whether CARLA sent it as a float or an integer.
pub(crate) fn number(v: &Value) -> Option<f64> {
    v.as_f64().or_else(|| v.as_i64().map(|i| i as f64))
}

/// CARLA's `Vector3D`/`Location` `[x, y, z]`.
pub(crate) fn vector(v: &Value) -> Option<V3> {
    let a = v.as_array()?;
    let n = |i: usize| a.get(i).and_then(number).map(|x| x as f32);
    let out = [n(0)?, n(1)?, n(2)?];
    out.iter().all(|x| x.is_finite()).then_some(out)
}

/// CARLA's `Transform` `[[x, y, z], [pitch, yaw, roll]]`.
pub(crate) fn transform(v: &Value) -> Option<CarlaTransform> {
    let a = v.as_array()?;
    Some(CarlaTransform {
        location: vector(a.first()?)?,
        rotation: vector(a.get(1)?)?,
    })
}

/// CARLA's `ActorId`.
pub(crate) fn actor_id(v: &Value) -> Option<u32> {
    v.as_u64().and_then(|id| u32::try_from(id).ok())
}

/// CARLA 0.9.16's `VehicleControl`
/// `[throttle, steer, brake, hand_brake, reverse, manual_gear_shift, gear]`.
pub(crate) fn vehicle_control(v: &Value) -> Option<CarlaVehicleControl> {
    let a = v.as_array()?;
    let f = |i: usize| a.get(i).and_then(number).map(|x| x as f32);
    let b = |i: usize| a.get(i).and_then(Value::as_bool);
    Some(CarlaVehicleControl {
        throttle: f(0)?,
        steer: f(1)?,
        brake: f(2)?,
        hand_brake: b(3)?,
        reverse: b(4)?,
        manual_gear_shift: b(5)?,
        gear: i32::try_from(a.get(6)?.as_i64()?).ok()?,
    })
}

/// CARLA's `WalkerControl` `[direction, speed, jump]`: direction in
/// CARLA's world axes, speed m/s.
pub(crate) fn walker_control(v: &Value) -> Option<(V3, f32, bool)> {
    let a = v.as_array()?;
    let speed = a.get(1).and_then(number)? as f32;
    Some((vector(a.first()?)?, speed, a.get(2)?.as_bool()?))
}

/// What a CARLA command does to one actor.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Op {
    Transform(CarlaTransform),
    Location(V3),
    Velocity(V3),
    AngularVelocity(V3),
    Impulse(V3),
    Force(V3),
    Torque(V3),
    Physics(bool),
    Gravity(bool),
    Control(CarlaVehicleControl),
    /// CARLA's `WalkerControl`: direction (CARLA's axes), speed, jump.
    WalkerControl(V3, f32, bool),
    /// CARLA's `ApplyWalkerState`, what its walker AI sends every tick:
    /// where the walker's feet are (on the navigation mesh), facing its
    /// way; the speed it walks at there is shown by the next one.
    WalkerState(CarlaTransform),
    /// CARLA's `set_actor_collisions`: simbus has no switch of its own for
    /// it, so it switches the actor's physics (its contacts with it; see
    /// the CARLA chapter).
    Collisions(bool),
    /// CARLA's `enable_constant_velocity` (m/s in the actor's own axes),
    /// or `disable_constant_velocity` (`None`).
    ConstantVelocity(Option<V3>),
    /// CARLA's `VehicleAckermannControl`: steer (radians, positive
    /// right), steer speed, speed, acceleration, jerk.
    Ackermann([f32; 5]),
    /// CARLA's `TrafficLight.set_state`.
    LightState(LightState),
    /// CARLA's `set_green_time`, `set_yellow_time`, `set_red_time`: the
    /// times given.
    LightTimes([Option<f32>; 3]),
    /// CARLA's `freeze_traffic_light` (its group), or with actor 0
    /// `freeze_all_traffic_lights`.
    FreezeLights(bool),
    /// CARLA's `reset_group`, or with actor 0 `reset_all_traffic_lights`.
    ResetLights,
    Destroy,
}

impl Op {
    /// The simbus command doing `self` to CARLA actor `id`, whose last
    /// state is `last` (for the parts a CARLA command leaves as they are).
    pub(crate) fn command(self, id: u32, last: Option<&ActorInfo>) -> Result<Command, CallError> {
        if crate::wire::is_sensor(id) && self != Op::Destroy {
            return Err(CallError::IsASensor(id));
        }
        let actor = u64::from(id);
        let current = || last.copied().ok_or(CallError::UnknownActor(id));
        Ok(match self {
            Op::Transform(t) => {
                let (position, rotation) = convert::pose(&t);
                Command::set_transform(actor, position, rotation)
            }
            Op::Location(l) => {
                Command::set_transform(actor, convert::vector(l), current()?.rotation)
            }
            Op::Velocity(v) => {
                Command::set_target_velocity(actor, convert::vector(v), current()?.angular)
            }
            Op::AngularVelocity(w) => Command::set_target_velocity(
                actor,
                current()?.linear,
                convert::angular_velocity_from_carla(w),
            ),
            Op::Impulse(v) => Command::apply_impulse(actor, convert::vector(v)),
            Op::Force(v) => Command::apply_force(actor, convert::vector(v)),
            // A torque is a pseudo-vector: swapping two axes flips it.
            Op::Torque(v) => Command::apply_torque(actor, convert::vector(v).map(|x| -x)),
            Op::Physics(on) => Command::set_physics(actor, on),
            Op::Gravity(on) => Command::set_gravity(actor, on),
            // CARLA steers right for positive values, simbus left.
            Op::Control(c) => {
                Command::vehicle_control(actor, c.throttle, -c.steer, c.brake, c.hand_brake)
                    .in_reverse(c.reverse)
            }
            Op::ConstantVelocity(v) => Command::constant_velocity(actor, v.map(convert::vector)),
            Op::WalkerControl(direction, speed, jump) => {
                Command::walker_control(actor, convert::vector(direction), speed, jump)
            }
            Op::WalkerState(t) => {
                // The feet on the mesh: the walker's centre is its half
                // height above them (CARLA's server adds it too).
                let half_height = current()?.extent[2];
                let mut location = t.location;
                location[2] += half_height;
                let (position, rotation) = convert::pose(&CarlaTransform {
                    location,
                    rotation: [0.0, t.rotation[1], 0.0],
                });
                Command::set_transform(actor, position, rotation)
            }
            Op::Collisions(on) => Command::set_physics(actor, on),
            Op::Ackermann([steer, steer_speed, speed, acceleration, jerk]) => {
                // CARLA steers right for positive values, simbus left.
                let mut command =
                    Command::vehicle_ackermann(actor, -steer, steer_speed, speed, acceleration);
                command.rotation[0] = jerk;
                command
            }
            Op::LightState(state) => Command::traffic_light_state(actor, state),
            Op::LightTimes(times) => Command::traffic_light_times(actor, times),
            Op::FreezeLights(frozen) => Command::freeze_traffic_lights(actor, frozen),
            Op::ResetLights => Command::reset_traffic_lights(actor),
            Op::Destroy => Command::destroy(actor),
        })
    }
}

/// CARLA 0.9.16's `VehicleAckermannControl`: `[steer, steer_speed,
/// speed, acceleration, jerk]`.
fn ackermann_control(v: &Value) -> Option<[f32; 5]> {
    let fields = v.as_array()?;
    if fields.len() != 5 {
        return None;
    }
    let mut out = [0.0; 5];
    for (slot, field) in out.iter_mut().zip(fields) {
        *slot = number(field)? as f32;
    }
    Some(out)
}

/// CARLA's `VehicleLightState`: its flags, as `[flags]` (the class's
/// msgpack array) or a bare integer.
pub(crate) fn light_flags(v: &Value) -> Option<u32> {
    let flags = match v.as_array().map(Vec::as_slice) {
        Some([flags]) => flags,
        Some(_) => return None,
        None => v,
    };
    u32::try_from(flags.as_u64()?).ok()
}

/// CARLA's `TrafficLightState` (an integer; `Unknown`, 4, shows as off).
fn light_state(v: &Value) -> Option<LightState> {
    match v.as_u64()? {
        4 => Some(LightState::Off),
        code => LightState::from_u32(u32::try_from(code).ok()?),
    }
}

/// The RPC methods that act on one actor, as [`rpc_op`] reads them.
const RPC_OPS: [&str; 21] = [
    "set_actor_transform",
    "set_actor_location",
    "set_actor_target_velocity",
    "set_actor_target_angular_velocity",
    "add_actor_impulse",
    "add_actor_force",
    "add_actor_torque",
    "set_actor_simulate_physics",
    "set_actor_enable_gravity",
    "apply_control_to_vehicle",
    "apply_control_to_walker",
    "set_actor_collisions",
    "enable_actor_constant_velocity",
    "disable_actor_constant_velocity",
    "set_traffic_light_state",
    "set_traffic_light_green_time",
    "set_traffic_light_yellow_time",
    "set_traffic_light_red_time",
    "freeze_traffic_light",
    "reset_traffic_light_group",
    "apply_ackermann_control_to_vehicle",
];

/// The RPC methods that act on one actor: `(actor, what)` from their
/// arguments, or `None` if `method` is not one of them.
pub(crate) fn rpc_op(method: &str, args: &[Value]) -> Option<Result<(u32, Op), CallError>> {
    let arg = |i: usize| args.get(i).unwrap_or(&Value::Nil);
    let method = RPC_OPS.iter().copied().find(|&m| m == method)?;
    let bad = || CallError::Shape {
        method,
        what: "arguments of the wrong types",
    };
    let v3 = || vector(arg(1)).ok_or_else(bad);
    let op = match method {
        "set_actor_transform" => transform(arg(1)).map(Op::Transform).ok_or_else(bad),
        "set_actor_location" => v3().map(Op::Location),
        "set_actor_target_velocity" => v3().map(Op::Velocity),
        "set_actor_target_angular_velocity" => v3().map(Op::AngularVelocity),
        "add_actor_impulse" => v3().map(Op::Impulse),
        "add_actor_force" => v3().map(Op::Force),
        "add_actor_torque" => v3().map(Op::Torque),
        "set_actor_simulate_physics" => arg(1).as_bool().map(Op::Physics).ok_or_else(bad),
        "set_actor_enable_gravity" => arg(1).as_bool().map(Op::Gravity).ok_or_else(bad),
        "apply_control_to_vehicle" => vehicle_control(arg(1)).map(Op::Control).ok_or_else(bad),
        "apply_control_to_walker" => walker_control(arg(1))
            .map(|(d, s, j)| Op::WalkerControl(d, s, j))
            .ok_or_else(bad),
        "set_actor_collisions" => arg(1).as_bool().map(Op::Collisions).ok_or_else(bad),
        "enable_actor_constant_velocity" => v3().map(|v| Op::ConstantVelocity(Some(v))),
        "disable_actor_constant_velocity" => Ok(Op::ConstantVelocity(None)),
        "set_traffic_light_state" => light_state(arg(1)).map(Op::LightState).ok_or_else(bad),
        "set_traffic_light_green_time"
        | "set_traffic_light_yellow_time"
        | "set_traffic_light_red_time" => {
            let slot = match method {
                "set_traffic_light_green_time" => 0,
                "set_traffic_light_yellow_time" => 1,
                _ => 2,
            };
            number(arg(1)).ok_or_else(bad).map(|seconds| {
                let mut times = [None; 3];
                times[slot] = Some(seconds as f32);
                Op::LightTimes(times)
            })
        }
        "freeze_traffic_light" => arg(1).as_bool().map(Op::FreezeLights).ok_or_else(bad),
        "reset_traffic_light_group" => Ok(Op::ResetLights),
        "apply_ackermann_control_to_vehicle" => {
            ackermann_control(arg(1)).map(Op::Ackermann).ok_or_else(bad)
        }
        _ => return None,
    };
    Some(op.and_then(|op| actor_id(arg(0)).map(|id| (id, op)).ok_or_else(bad)))
}

/// One command of a batch.
#[derive(Debug, Clone)]
pub(crate) enum BatchCommand {
    /// `SpawnActor`: what, where, on which parent, and what to do to it
    /// once it exists (`.then(...)`).
    Spawn {
        description: Description,
        transform: CarlaTransform,
        parent: Option<u32>,
        then: Vec<Value>,
    },
    /// A command on an existing actor.
    Actor(u32, Op),
    /// `SetAutopilot`: CARLA's client registers the vehicle with the
    /// traffic manager in its own process; the server only checks the
    /// actor (simbus has no server-side autopilot).
    Autopilot(u32),
    /// `SetVehicleLightState` (what the traffic manager's
    /// `update_vehicle_lights` sends): the gateway keeps the flags.
    VehicleLights(u32, u32),
}

/// The names of CARLA 0.9.16's batch commands, in variant order.
const COMMAND_NAMES: [&str; 22] = [
    "SpawnActor",
    "DestroyActor",
    "ApplyVehicleControl",
    "ApplyVehicleAckermannControl",
    "ApplyWalkerControl",
    "ApplyVehiclePhysicsControl",
    "ApplyTransform",
    "ApplyWalkerState",
    "ApplyTargetVelocity",
    "ApplyTargetAngularVelocity",
    "ApplyImpulse",
    "ApplyForce",
    "ApplyAngularImpulse",
    "ApplyTorque",
    "SetSimulatePhysics",
    "SetEnableGravity",
    "SetAutopilot",
    "ShowDebugTelemetry",
    "SetVehicleLightState",
    "ApplyLocation",
    "ConsoleCommand",
    "SetTrafficLightState",
];

/// Reads one `carla.command.*` (`[[variant, body]]`); `actor` replaces the
/// actor id (a `.then(...)` command names the actor being spawned as 0).
pub(crate) fn batch_command(v: &Value, actor: Option<u32>) -> Result<BatchCommand, CallError> {
    let variant = v
        .as_array()
        .and_then(|a| a.first())
        .and_then(Value::as_array)
        .filter(|a| a.len() == 2)
        .ok_or(CallError::BatchShape)?;
    let index = variant[0].as_u64().ok_or(CallError::BatchShape)?;
    let name = COMMAND_NAMES
        .get(index as usize)
        .copied()
        .unwrap_or("unknown");
    let body = variant[1].as_array().ok_or(CallError::BatchShape)?;
    let bad = || CallError::Shape {
        method: name,
        what: "fields of the wrong types",
    };
    let field = |i: usize| body.get(i).unwrap_or(&Value::Nil);
    if index == 0 {
        let parent = match field(2).as_array().map(Vec::as_slice) {
            Some([flag, id]) if flag.as_bool() == Some(true) => Some(actor_id(id).ok_or_else(bad)?),
            _ => None,
        };
        return Ok(BatchCommand::Spawn {
            description: Description::parse(field(0))?,
            transform: transform(field(1)).ok_or_else(bad)?,
            parent,
            then: field(5).as_array().cloned().unwrap_or_default(),
        });
    }
    let id = || match actor {
        Some(id) => Ok(id),
        None => actor_id(field(0)).ok_or_else(bad),
    };
    if index == 16 {
        field(1).as_bool().ok_or_else(bad)?;
        return Ok(BatchCommand::Autopilot(id()?));
    }
    if index == 18 {
        let flags = light_flags(field(1)).ok_or_else(bad)?;
        return Ok(BatchCommand::VehicleLights(id()?, flags));
    }
    let v3 = || vector(field(1)).ok_or_else(bad);
    let op = match index {
        1 => Op::Destroy,
        2 => Op::Control(vehicle_control(field(1)).ok_or_else(bad)?),
        3 => Op::Ackermann(ackermann_control(field(1)).ok_or_else(bad)?),
        4 => {
            let (direction, speed, jump) = walker_control(field(1)).ok_or_else(bad)?;
            Op::WalkerControl(direction, speed, jump)
        }
        6 => Op::Transform(transform(field(1)).ok_or_else(bad)?),
        7 => {
            number(field(2)).ok_or_else(bad)?;
            Op::WalkerState(transform(field(1)).ok_or_else(bad)?)
        }
        8 => Op::Velocity(v3()?),
        9 => Op::AngularVelocity(v3()?),
        10 => Op::Impulse(v3()?),
        11 => Op::Force(v3()?),
        13 => Op::Torque(v3()?),
        14 => Op::Physics(field(1).as_bool().ok_or_else(bad)?),
        15 => Op::Gravity(field(1).as_bool().ok_or_else(bad)?),
        19 => Op::Location(v3()?),
        21 => Op::LightState(light_state(field(1)).ok_or_else(bad)?),
        _ => return Err(CallError::UnsupportedCommand(name)),
    };
    Ok(BatchCommand::Actor(id()?, op))
}

#[cfg(test)]
mod tests {
    use super::*;

    fn command(index: u64, body: Vec<Value>) -> Value {
        Value::Array(vec![Value::Array(vec![
            Value::from(index),
            Value::Array(body),
        ])])
    }

    #[test]
    fn batch_commands_read_as_carla_writes_them() {
        let control = command(
            2,
            vec![
                Value::from(5u32),
                Value::Array(vec![
                    Value::F32(0.1),
                    Value::F32(0.2),
                    Value::F32(0.3),
                    Value::Boolean(true),
                    Value::Boolean(false),
                    Value::Boolean(false),
                    Value::from(3),
                ]),
            ],
        );
        let BatchCommand::Actor(5, Op::Control(c)) = batch_command(&control, None).unwrap() else {
            panic!("not a control");
        };
        assert!(c.hand_brake && c.gear == 3 && (c.steer - 0.2).abs() < 1e-6);
        // A `.then(...)` command names the spawned actor as 0.
        let physics = command(14, vec![Value::from(0u32), Value::Boolean(false)]);
        assert!(matches!(
            batch_command(&physics, Some(9)).unwrap(),
            BatchCommand::Actor(9, Op::Physics(false))
        ));
        let walker = command(4, vec![Value::from(1u32)]);
        let e = batch_command(&walker, None).unwrap_err();
        assert!(e.to_string().contains("ApplyWalkerControl"), "{e}");
        let walk = command(
            4,
            vec![
                Value::from(1u32),
                Value::Array(vec![
                    Value::Array(vec![Value::F32(1.0), Value::F32(0.0), Value::F32(0.0)]),
                    Value::F32(1.4),
                    Value::Boolean(false),
                ]),
            ],
        );
        assert!(matches!(
            batch_command(&walk, None).unwrap(),
            BatchCommand::Actor(1, Op::WalkerControl([1.0, 0.0, 0.0], s, false)) if (s - 1.4).abs() < 1e-6
        ));
        let state = command(
            7,
            vec![
                Value::from(5u32),
                Value::Array(vec![
                    Value::Array(vec![Value::F32(1.0), Value::F32(2.0), Value::F32(3.0)]),
                    Value::Array(vec![Value::F32(0.0), Value::F32(90.0), Value::F32(0.0)]),
                ]),
                Value::F32(1.5),
            ],
        );
        assert!(matches!(
            batch_command(&state, None).unwrap(),
            BatchCommand::Actor(5, Op::WalkerState(_))
        ));
        let speedless = command(7, vec![Value::from(5u32), Value::Nil]);
        assert!(batch_command(&speedless, None).is_err());
        assert!(batch_command(&Value::from("x"), None).is_err());
        let wrong = command(10, vec![Value::from(1u32), Value::from("up")]);
        assert!(batch_command(&wrong, None)
            .unwrap_err()
            .to_string()
            .contains("ApplyImpulse"));
    }

    #[test]
    fn reverse_engages_the_reverse_gear_and_sensors_are_refused_with_the_reason() {
        let reverse = Op::Control(CarlaVehicleControl {
            throttle: 0.5,
            reverse: true,
            ..Default::default()
        });
        let command = reverse.command(3, None).unwrap();
        assert_eq!(command.flags & Command::REVERSE, Command::REVERSE);
        let on_sensor = Op::Impulse([0.0; 3]).command(crate::wire::SENSOR_ID_BASE + 1, None);
        let e = on_sensor.unwrap_err().to_string();
        assert!(e.contains("sensor"), "{e}");
    }
}
