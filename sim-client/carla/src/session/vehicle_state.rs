//! What the gateway keeps of a vehicle beyond simbus's: its
//! `VehicleLightState` flags (simbus draws no light: they are state for
//! scripts and the traffic manager's `update_vehicle_lights`), its
//! Ackermann controller settings (read back as set; simbus's controller
//! has its own loop), and doors that open and close as accepted calls.

use rmpv::Value;
use shared_types::ActorKind;

use super::Session;
use crate::commands;
use crate::error::CallError;
use crate::locks::lock;
use crate::rpc::Answer;

/// CARLA's `AckermannControllerSettings` defaults: speed kp, ki, kd,
/// acceleration kp, ki, kd.
const ACKERMANN_DEFAULTS: [f32; 6] = [0.15, 0.0, 0.25, 0.01, 0.0, 0.01];

impl Session {
    /// The vehicle argument 0 of `method` names.
    fn vehicle_arg(&self, args: &[Value], method: &'static str) -> Result<u32, CallError> {
        self.vehicle(super::actor_id_arg(args, method)?)
    }

    /// `id`, if it is a vehicle of the last frame (or just spawned
    /// through the gateway as one).
    fn vehicle(&self, id: u32) -> Result<u32, CallError> {
        let kind = lock(&self.hub.actors).get(&id).map(|a| a.kind).or_else(|| {
            let registry = lock(&self.hub.registry);
            let description = registry.descriptions.get(&id)?;
            let uid = description.as_array()?.first()?.as_u64()?;
            Some(crate::blueprints::kind_of_uid(uid))
        });
        match kind.map(ActorKind::from_u32) {
            Some(Some(ActorKind::Vehicle)) => Ok(id),
            Some(_) => Err(CallError::NotAVehicle(id)),
            None => Err(CallError::UnknownActor(id)),
        }
    }

    /// Keeps vehicle `id`'s light flags (the batch's
    /// `SetVehicleLightState`).
    pub(super) fn set_vehicle_lights(&mut self, id: u32, flags: u32) -> Result<u32, CallError> {
        let id = self.vehicle(id)?;
        lock(&self.hub.registry).vehicle_lights.insert(id, flags);
        Ok(id)
    }

    /// CARLA's `vehicle.set_light_state(flags)`.
    pub(super) fn on_set_vehicle_light_state(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        const METHOD: &str = "set_vehicle_light_state";
        let id = self.vehicle_arg(args, METHOD)?;
        let flags = args
            .get(1)
            .and_then(commands::light_flags)
            .ok_or(CallError::Shape {
                method: METHOD,
                what: "no VehicleLightState",
            })?;
        self.set_vehicle_lights(id, flags)?;
        Ok(Answer::Done)
    }

    /// CARLA's `vehicle.get_light_state()`: as last set (`NONE` until).
    pub(super) fn on_get_vehicle_light_state(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        let id = self.vehicle_arg(args, "get_vehicle_light_state")?;
        let flags = lock(&self.hub.registry)
            .vehicle_lights
            .get(&id)
            .copied()
            .unwrap_or(0);
        Ok(Answer::Value(Value::Array(vec![Value::from(flags)])))
    }

    /// CARLA's `world.get_vehicles_light_states()` (the traffic manager
    /// reads it every step): every vehicle of the last frame and its
    /// flags.
    pub(super) fn on_get_vehicle_light_states(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        let mut vehicles: Vec<u32> = lock(&self.hub.actors)
            .iter()
            .filter(|(_, a)| ActorKind::from_u32(a.kind) == Some(ActorKind::Vehicle))
            .map(|(&id, _)| id)
            .collect();
        vehicles.sort_unstable();
        let registry = lock(&self.hub.registry);
        let list = vehicles
            .into_iter()
            .map(|id| {
                let flags = registry.vehicle_lights.get(&id).copied().unwrap_or(0);
                Value::Array(vec![Value::from(id), Value::from(flags)])
            })
            .collect();
        Ok(Answer::Value(Value::Array(list)))
    }

    /// CARLA's `get_ackermann_controller_settings()`: as last set, CARLA's
    /// defaults until then.
    pub(super) fn on_get_ackermann_settings(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        let id = self.vehicle_arg(args, "get_ackermann_controller_settings")?;
        let settings = lock(&self.hub.registry)
            .ackermann_settings
            .get(&id)
            .copied()
            .unwrap_or(ACKERMANN_DEFAULTS);
        Ok(Answer::Value(Value::Array(
            settings.iter().map(|&v| Value::F32(v)).collect(),
        )))
    }

    /// CARLA's `apply_ackermann_controller_settings(settings)`: kept and
    /// read back (simbus's Ackermann loop has its own gains).
    pub(super) fn on_apply_ackermann_settings(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        const METHOD: &str = "apply_ackermann_controller_settings";
        let id = self.vehicle_arg(args, METHOD)?;
        let bad = CallError::Shape {
            method: METHOD,
            what: "no AckermannControllerSettings of six numbers",
        };
        let fields = args.get(1).and_then(Value::as_array).ok_or(bad.clone())?;
        if fields.len() != 6 {
            return Err(bad);
        }
        let mut settings = [0.0; 6];
        for (slot, field) in settings.iter_mut().zip(fields) {
            *slot = commands::number(field).ok_or(bad.clone())? as f32;
        }
        lock(&self.hub.registry)
            .ackermann_settings
            .insert(id, settings);
        Ok(Answer::Done)
    }

    /// CARLA's `open_door` / `close_door`: accepted on a vehicle (simbus's
    /// have no doors to move).
    pub(super) fn on_vehicle_door(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        self.vehicle_arg(args, "open_vehicle_door / close_vehicle_door")?;
        Ok(Answer::Done)
    }
}
