//! The actors' calls: records and bounding boxes, spawns (bodies through a
//! simbus batch, sensors through simbus's sensor service), destruction,
//! batches with their `.then(...)` commands, and the calls on one actor.

use rmpv::Value;
use shared_types::CommandStatus;
use tracing::debug;

use super::Session;
use crate::blueprints::{self, Description, Spawn};
use crate::commands::{self, BatchCommand, Op};
use crate::error::CallError;
use crate::locks::lock;
use crate::records::{bounding_box, record_of};
use crate::rpc::Answer;
use crate::stream::SensorEntry;
use crate::wire::{CarlaTransform, SPECTATOR_ID};

/// One result per command of a batch: the actor's CARLA id, or why not.
type Results = Vec<Result<u32, CallError>>;

impl Session {
    pub(super) fn on_get_actors_by_id(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let ids = args
            .first()
            .and_then(Value::as_array)
            .ok_or(CallError::Shape {
                method: "get_actors_by_id",
                what: "no id list",
            })?;
        let records = ids
            .iter()
            .filter_map(commands::actor_id)
            .filter_map(|id| self.actor_record(id))
            .collect();
        Ok(Answer::Value(Value::Array(records)))
    }

    /// CARLA's `world.get_spectator()`: the spectator's record (one per
    /// gateway, a pose with no simbus body).
    pub(super) fn on_get_spectator(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        let record = self
            .actor_record(SPECTATOR_ID)
            .ok_or(CallError::Vanished(SPECTATOR_ID))?;
        Ok(Answer::Value(record))
    }

    pub(super) fn on_get_actor_definitions(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        Ok(Answer::Value(blueprints::library()))
    }

    pub(super) fn on_get_actor_bounding_box(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        let id = args
            .first()
            .and_then(commands::actor_id)
            .ok_or(CallError::Shape {
                method: "get_actor_bounding_box",
                what: "no actor id",
            })?;
        let extent = lock(&self.hub.actors)
            .get(&id)
            .map_or([0.0; 3], |a| a.extent);
        Ok(Answer::Value(bounding_box(id, extent)))
    }

    pub(super) fn on_spawn_actor(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        self.spawn_call("spawn_actor", args, false)
    }

    pub(super) fn on_spawn_actor_with_parent(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        self.spawn_call("spawn_actor_with_parent", args, true)
    }

    /// `spawn_actor` (description, transform) and
    /// `spawn_actor_with_parent` (and the parent's id): the actor's record.
    fn spawn_call(
        &mut self,
        method: &'static str,
        args: &[Value],
        with_parent: bool,
    ) -> Result<Answer, CallError> {
        let description = Description::parse(args.first().unwrap_or(&Value::Nil))
            .map_err(|source| CallError::Description { method, source })?;
        let transform = args
            .get(1)
            .and_then(commands::transform)
            .ok_or(CallError::Shape {
                method,
                what: "the transform is of the wrong shape",
            })?;
        let parent = match with_parent {
            false => None,
            true => Some(
                args.get(2)
                    .and_then(commands::actor_id)
                    .ok_or(CallError::Shape {
                        method,
                        what: "the parent is not an actor id",
                    })?,
            ),
        };
        let id = self.spawn(&description, &transform, parent)?;
        self.hub.ros2.spawned(id, &description);
        self.show_spawned(&[id]);
        let record = self.actor_record(id).ok_or(CallError::Vanished(id))?;
        Ok(Answer::Value(record))
    }

    pub(super) fn on_destroy_actor(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let id = args
            .first()
            .and_then(commands::actor_id)
            .ok_or(CallError::Shape {
                method: "destroy_actor",
                what: "no actor id",
            })?;
        let results = self.run_batch(vec![Ok(BatchCommand::Actor(id, Op::Destroy))]);
        results.into_iter().next().unwrap_or(Ok(id))?;
        Ok(Answer::Value(Value::Boolean(true)))
    }

    /// CARLA's `apply_batch`/`apply_batch_sync`: one `Response<ActorId>`
    /// per command, not wrapped; a tick after, if asked.
    pub(super) fn on_apply_batch(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let list = args
            .first()
            .and_then(Value::as_array)
            .ok_or(CallError::Shape {
                method: "apply_batch",
                what: "no command list",
            })?;
        let batch: Vec<_> = list
            .iter()
            .map(|c| commands::batch_command(c, None))
            .collect();
        let spawns: Vec<bool> = batch
            .iter()
            .map(|c| matches!(c, Ok(BatchCommand::Spawn { .. })))
            .collect();
        let results = self.run_batch(batch);
        if args.get(1).and_then(Value::as_bool) == Some(true) {
            self.tick()?;
        } else {
            let spawned: Vec<u32> = (results.iter().zip(spawns))
                .filter_map(|(r, spawn)| r.as_ref().ok().filter(|_| spawn).copied())
                .collect();
            self.show_spawned(&spawned);
        }
        let responses = results
            .into_iter()
            .map(|r| match r {
                Ok(id) => Value::Array(vec![Value::Array(vec![Value::from(1u8), Value::from(id)])]),
                Err(e) => Value::Array(vec![Value::Array(vec![
                    Value::from(0u8),
                    Value::Array(vec![Value::from(e.to_string())]),
                ])]),
            })
            .collect();
        Ok(Answer::Raw(Value::Array(responses)))
    }

    /// A call on one actor (`set_actor_transform`, ...): `void` says
    /// whether CARLA answers it with `Response<void>`.
    pub(super) fn on_actor_op(
        &mut self,
        (id, op): (u32, Op),
        void: bool,
    ) -> Result<Answer, CallError> {
        let results = self.run_batch(vec![Ok(BatchCommand::Actor(id, op))]);
        match results.into_iter().next().unwrap_or(Ok(id)) {
            // CARLA's traffic manager turns physics on for the vehicles of
            // its last snapshot, on its own thread, where an error ends
            // the script: an actor the script destroyed since is ignored.
            Err(CallError::CommandRefused {
                status: CommandStatus::UnknownActor,
                ..
            }) if matches!(op, Op::Physics(_)) => {
                debug!(peer = %self.peer, actor = id, "simulate physics on an actor gone: ignored");
            }
            result => {
                result?;
            }
        }
        Ok(if void {
            Answer::Done
        } else {
            Answer::Value(Value::Nil)
        })
    }

    /// CARLA's `rpc::Actor` of actor `id`, if the world has it.
    fn actor_record(&self, id: u32) -> Option<Value> {
        record_of(&self.hub, id, self.streaming_port)
    }

    /// Spawns one actor (a sensor through simbus's sensor service, a body
    /// through a batch) and returns its CARLA id.
    fn spawn(
        &mut self,
        description: &Description,
        transform: &CarlaTransform,
        parent: Option<u32>,
    ) -> Result<u32, CallError> {
        let spawn = description.spawn(transform).map_err(CallError::Spawn)?;
        let id = match spawn {
            Spawn::Body(command) => {
                if let Some(parent) = parent {
                    return Err(CallError::OnlySensorsAttach {
                        blueprint: description.id.clone(),
                        parent,
                    });
                }
                let id = self
                    .apply(&[command])?
                    .into_iter()
                    .next()
                    .unwrap_or(Err(CallError::NoAnswer))?;
                self.provisional(id, &command);
                id
            }
            Spawn::Sensor(spec) => return self.spawn_sensor(description, spec, parent),
            Spawn::ClientSide(position, rotation) => {
                return self.spawn_client_side(description, position, rotation, parent)
            }
            Spawn::Controller => {
                let walker = parent.ok_or_else(|| CallError::ControllerWithoutWalker)?;
                let kind = lock(&self.hub.actors).get(&walker).map(|a| a.kind);
                if kind != Some(shared_types::ActorKind::Walker as u32) {
                    return Err(CallError::ControllerNotOnAWalker(walker));
                }
                return self.spawn_client_side(description, [0.0; 3], [0.0, 0.0, 0.0, 1.0], parent);
            }
        };
        lock(&self.hub.registry)
            .descriptions
            .insert(id, description.record());
        Ok(id)
    }

    /// Spawns a sensor through simbus's sensor service, on `parent` if
    /// given, and registers it for the streams.
    fn spawn_sensor(
        &mut self,
        description: &Description,
        spec: shared_types::SensorSpec,
        parent: Option<u32>,
    ) -> Result<u32, CallError> {
        let parent = parent.unwrap_or(0);
        if crate::wire::is_sensor(parent) {
            return Err(CallError::SensorOnSensor(parent));
        }
        let spec = spec.attached_to(u64::from(parent));
        let info = self
            .client()?
            .create_sensor(spec)
            .map_err(CallError::simbus)?;
        let id = crate::wire::carla_id(info.id).ok_or(CallError::SensorIdRange(info.id))?;
        lock(&self.hub.registry).sensors.insert(
            id,
            SensorEntry::new(info.id, spec, description.record(), parent),
        );
        Ok(id)
    }

    /// Registers a sensor CARLA's client computes itself (on `parent` if
    /// given): a pose-only actor the world states carry, no simbus sensor.
    fn spawn_client_side(
        &mut self,
        description: &Description,
        position: [f32; 3],
        rotation: [f32; 4],
        parent: Option<u32>,
    ) -> Result<u32, CallError> {
        let parent = parent.unwrap_or(0);
        if crate::wire::is_sensor(parent) {
            return Err(CallError::SensorOnSensor(parent));
        }
        // simbus checks a simbus sensor's parent; this one is the gateway's.
        if parent != 0 && !lock(&self.hub.actors).contains_key(&parent) {
            return Err(CallError::UnknownActor(parent));
        }
        let spec = shared_types::SensorSpec {
            position,
            rotation,
            attach_to: u64::from(parent),
            ..shared_types::SensorSpec::default()
        };
        let mut registry = lock(&self.hub.registry);
        let id = crate::wire::client_side_id(registry.client_side)
            .ok_or(CallError::SensorIdRange(u64::from(registry.client_side)))?;
        registry.client_side += 1;
        registry
            .sensors
            .insert(id, SensorEntry::new(0, spec, description.record(), parent));
        Ok(id)
    }

    /// Applies simbus commands in one batch: per command, the actor's id or
    /// why it failed.
    fn apply(&mut self, batch: &[shared_types::Command]) -> Result<Results, CallError> {
        if batch.is_empty() {
            return Ok(Vec::new());
        }
        let response = self
            .client()?
            .apply_batch_sync(batch, false)
            .map_err(CallError::simbus)?;
        Ok(response
            .results
            .iter()
            .zip(batch)
            .map(|(r, c)| match CommandStatus::from_u32(r.status) {
                Some(CommandStatus::Ok) => {
                    u32::try_from(r.actor).map_err(|_| CallError::ActorIdRange(r.actor))
                }
                status => {
                    let status = status.unwrap_or(CommandStatus::UnknownCommand);
                    Err(match c.actor {
                        0 if status == CommandStatus::SpawnCollision => CallError::SpawnCollision,
                        0 => CallError::SpawnRefused(status),
                        actor => CallError::CommandRefused { actor, status },
                    })
                }
            })
            .collect())
    }

    /// Runs CARLA commands in order: one simbus batch for the commands on
    /// bodies, sensors through the sensor service, then every spawned
    /// actor's `.then(...)` commands. One result per command.
    pub(super) fn run_batch(&mut self, batch: Vec<Result<BatchCommand, CallError>>) -> Results {
        let mut results: Results = Vec::with_capacity(batch.len());
        let mut simbus = Vec::new();
        let mut slots = Vec::new();
        let mut after = Vec::new();
        for (i, command) in batch.into_iter().enumerate() {
            let result = match command {
                Err(e) => Err(e),
                Ok(BatchCommand::Spawn {
                    description,
                    transform,
                    parent,
                    then,
                }) => match description.spawn(&transform) {
                    Ok(Spawn::Body(command)) if parent.is_none() => {
                        slots.push(i);
                        simbus.push(command);
                        after.push((i, then, description, command));
                        Ok(0)
                    }
                    _ => {
                        let id = self.spawn(&description, &transform, parent);
                        if let Ok(id) = id {
                            self.then(id, &then);
                        }
                        id
                    }
                },
                Ok(BatchCommand::Autopilot(id)) => self.autopilot_target(id),
                Ok(BatchCommand::VehicleLights(id, flags)) => self.set_vehicle_lights(id, flags),
                Ok(BatchCommand::Actor(SPECTATOR_ID, op)) => self.move_spectator(op),
                Ok(BatchCommand::Actor(id, Op::Destroy)) if crate::wire::is_sensor(id) => {
                    self.destroy_sensor(id)
                }
                Ok(BatchCommand::Actor(id, op)) => {
                    let last = lock(&self.hub.actors).get(&id).copied();
                    op.command(id, last.as_ref()).map(|command| {
                        slots.push(i);
                        simbus.push(command);
                        match op {
                            Op::Control(control) => {
                                lock(&self.hub.registry).controls.insert(id, control);
                            }
                            Op::LightTimes(times) => lock(&self.hub.signals).set_times(id, times),
                            _ => {}
                        }
                        id
                    })
                }
            };
            results.push(result);
        }
        self.apply_in_slots(&simbus, slots, &mut results);
        for (i, then, description, command) in after {
            if let Ok(id) = results[i] {
                self.provisional(id, &command);
                lock(&self.hub.registry)
                    .descriptions
                    .insert(id, description.record());
                self.then(id, &then);
            }
        }
        results
    }

    /// Applies the batch's simbus commands, each result into its command's
    /// slot (a failed batch fails each of them).
    fn apply_in_slots(
        &mut self,
        simbus: &[shared_types::Command],
        slots: Vec<usize>,
        results: &mut Results,
    ) {
        match self.apply(simbus) {
            Ok(applied) => {
                for (slot, result) in slots.into_iter().zip(applied) {
                    results[slot] = result;
                }
            }
            Err(e) => {
                for slot in slots {
                    results[slot] = Err(e.clone());
                }
            }
        }
    }

    /// A spawned actor's `.then(...)` commands (their results are not
    /// reported, as in CARLA).
    fn then(&mut self, id: u32, then: &[Value]) {
        if then.is_empty() {
            return;
        }
        // One level: a spawn inside `.then(...)` is refused, so a nested
        // chain from a client cannot recurse the gateway's stack away.
        let batch = then
            .iter()
            .map(|c| match commands::batch_command(c, Some(id)) {
                Ok(BatchCommand::Spawn { .. }) => Err(CallError::SpawnInThen),
                other => other,
            })
            .collect();
        for result in self.run_batch(batch) {
            if let Err(e) = result {
                debug!(peer = %self.peer, actor = id, "a .then() command failed: {e}");
            }
        }
    }

    /// Moves the spectator (its pose goes out with the next world state);
    /// anything else on it is refused: it has no body.
    fn move_spectator(&mut self, op: Op) -> Result<u32, CallError> {
        let mut pose = lock(&self.hub.spectator);
        match op {
            Op::Transform(t) => *pose = t,
            Op::Location(l) => pose.location = l,
            _ => return Err(CallError::SpectatorHasNoBody),
        }
        Ok(SPECTATOR_ID)
    }

    fn destroy_sensor(&mut self, id: u32) -> Result<u32, CallError> {
        // A sensor that went with its parent is destroyed already in
        // simbus, a client-side one never was there: the client's destroy
        // ends it here.
        let mut registry = lock(&self.hub.registry);
        if registry
            .sensors
            .get(&id)
            .is_some_and(|s| s.gone || s.simbus_id == 0)
        {
            registry.sensors.remove(&id);
            return Ok(id);
        }
        let spawned_here = registry.sensors.contains_key(&id);
        drop(registry);
        let simbus_id = crate::wire::simbus_id(id).ok_or(CallError::NotASensor(id))?;
        match self.client()?.destroy_sensor(simbus_id) {
            Ok(()) => {}
            // A sensor this gateway spawned that the server no longer has
            // went with its parent in a frame the world stream has not
            // passed on yet (a destroy right after the parent's): it is
            // destroyed, as the client asks.
            Err(sim_client::SensorError::UnknownSensor { .. }) if spawned_here => {}
            Err(e) => return Err(CallError::simbus(e)),
        }
        lock(&self.hub.registry).sensors.remove(&id);
        Ok(id)
    }
}
