//! A vehicle's physics as CARLA describes it (`get_physics_control`):
//! simbus's ray-cast vehicle, built from its blueprint's size and mass
//! ([`shared_types::VehicleSpec`]), in CARLA 0.9.16's
//! `VehiclePhysicsControl` layout. Changing it is refused.

use rmpv::Value;
use shared_types::{ActorKind, VehicleSpec, FRICTION_SLIP};

use tracing::warn;

use super::Session;
use crate::blueprints;
use crate::commands;
use crate::convert;
use crate::error::CallError;
use crate::locks::lock;
use crate::rpc::Answer;
use crate::stream::ActorInfo;

/// CARLA's unit for wheel radii and positions: centimetres.
const CM: f32 = 100.0;
/// The engine's top speed, rpm (CARLA's default cars rev to 5000–5700).
const MAX_RPM: f32 = 5000.0;
/// The gear ratio from engine to wheels (one gear; simbus has no gearbox).
const FINAL_RATIO: f32 = 4.0;

impl Session {
    /// CARLA's `vehicle.get_physics_control()`: mass, wheels (positions in
    /// the world, centimetres), steer angle and a flat torque curve that
    /// gives the engine force simbus applies.
    pub(super) fn on_get_physics_control(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let id = args
            .first()
            .and_then(commands::actor_id)
            .ok_or(CallError::Shape {
                method: "get_physics_control",
                what: "no actor id",
            })?;
        let info = lock(&self.hub.actors)
            .get(&id)
            .copied()
            .ok_or(CallError::UnknownActor(id))?;
        if ActorKind::from_u32(info.kind) != Some(ActorKind::Vehicle) {
            return Err(CallError::NotAVehicle(id));
        }
        let type_id = lock(&self.hub.registry)
            .descriptions
            .get(&id)
            .and_then(|d| d.as_array()?.get(1)?.as_str().map(str::to_string));
        let spec = type_id
            .as_deref()
            .and_then(blueprints::vehicle_build)
            .and_then(|(mass, extent)| {
                let [x, y, z] = convert::vector(extent);
                VehicleSpec::from_params([x, y, z, mass]).ok()
            })
            .unwrap_or_default();
        Ok(Answer::Value(physics_control(&spec, &info)))
    }

    /// CARLA's `vehicle.apply_physics_control()`: refused (simbus builds a
    /// vehicle from its blueprint). CARLA's client does not wait for this
    /// answer, so the refusal is logged too.
    pub(super) fn on_apply_physics_control(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        let refusal = CallError::PhysicsControl;
        warn!(peer = %self.peer, "{refusal}");
        Err(refusal)
    }
}

/// `[x, y]`.
fn vector2(x: f32, y: f32) -> Value {
    Value::Array(vec![Value::F32(x), Value::F32(y)])
}

/// `[x, y, z]`.
fn vector3(v: [f32; 3]) -> Value {
    Value::Array(v.iter().map(|&x| Value::F32(x)).collect())
}

/// CARLA 0.9.16's `VehiclePhysicsControl` of vehicle `spec` standing as
/// `info` says.
fn physics_control(spec: &VehicleSpec, info: &ActorInfo) -> Value {
    // Engine torque that, through the one gear, pushes as simbus's engine
    // does (two driven wheels).
    let torque = 2.0 * spec.engine_force * spec.wheel_radius / FINAL_RATIO;
    let torque_curve = Value::Array(vec![
        vector2(0.0, torque),
        vector2(MAX_RPM * 0.8, torque),
        vector2(MAX_RPM, torque * 0.8),
    ]);
    let gear = Value::Array(vec![Value::F32(1.0), Value::F32(0.5), Value::F32(0.65)]);
    let steering_curve = Value::Array(vec![vector2(0.0, 1.0), vector2(120.0, 1.0)]);
    // CARLA's order: front left, front right, rear left, rear right
    // (simbus's: front right, front left, rear right, rear left).
    let wheels = [1, 0, 3, 2].iter().map(|&i| wheel(spec, i, info)).collect();
    Value::Array(vec![
        torque_curve,
        Value::F32(MAX_RPM),
        Value::F32(1.0),          // moi
        Value::F32(0.25),         // damping_rate_full_throttle
        Value::F32(3.0),          // ..._zero_throttle_clutch_engaged
        Value::F32(0.35),         // ..._zero_throttle_clutch_disengaged
        Value::Boolean(true),     // use_gear_autobox
        Value::F32(0.0),          // gear_switch_time
        Value::F32(10.0),         // clutch_strength
        Value::F32(FINAL_RATIO),  // final_ratio
        Value::Array(vec![gear]), // forward_gears
        Value::F32(spec.mass),    // mass
        Value::F32(0.0),          // drag_coefficient: none in simbus
        vector3([0.0; 3]),        // center_of_mass: the box's centre
        steering_curve,
        Value::Array(wheels),
        Value::Boolean(false), // use_sweep_wheel_collision
    ])
}

/// CARLA's `WheelPhysicsControl` of `spec`'s wheel `i` (simbus's order).
fn wheel(spec: &VehicleSpec, i: usize, info: &ActorInfo) -> Value {
    let front = i < 2;
    let local = spec.wheels[i];
    let [x, y, z] = simbus_pose::rotate(info.rotation, local);
    let world = [
        info.position[0] + x,
        info.position[1] + y,
        info.position[2] + z,
    ];
    let position = convert::vector(world).map(|c| c * CM);
    Value::Array(vec![
        Value::F32(FRICTION_SLIP),
        Value::F32(0.25),
        Value::F32(if front {
            spec.max_steer.to_degrees()
        } else {
            0.0
        }),
        Value::F32(spec.wheel_radius * CM),
        Value::F32(1500.0),
        Value::F32(if front { 0.0 } else { 3000.0 }),
        Value::F32(2.0),
        Value::F32(17.0),
        Value::F32(1000.0),
        vector3(position),
    ])
}
