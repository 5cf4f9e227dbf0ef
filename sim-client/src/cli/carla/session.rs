//! One CARLA connection: its own simbus client (and, once it turns
//! synchronous mode on, its own claim on the world's tick ownership), and
//! what each CARLA call it makes does to the world.

use std::net::SocketAddr;
use std::sync::Arc;
use std::time::Duration;

use rmpv::Value;
use shared_types::carla::{token, CARLA_VERSION, WORLD_STREAM_ID};
use shared_types::WorldSettings;
use sim_client::{Client, Ticker};
use tracing::{debug, info};

use super::blueprints::{self, Description, Spawn};
use super::commands::{self, BatchCommand, Op};
use super::rpc::{Answer, Request};
use super::sensors;
use super::stream::{lock, Hub, SensorEntry};

/// A minimal OpenDRIVE map: one straight two-lane road. CARLA's client
/// builds its map from it (`world.get_map()`); simbus scenes have no roads.
const OPENDRIVE: &str = r#"<?xml version="1.0" standalone="yes"?>
<OpenDRIVE>
  <header revMajor="1" revMinor="4" name="" version="1" north="0" south="0" east="0" west="0"/>
  <road name="r0" length="100.0" id="0" junction="-1">
    <link/>
    <planView><geometry s="0.0" x="0.0" y="0.0" hdg="0.0" length="100.0"><line/></geometry></planView>
    <elevationProfile/>
    <lateralProfile/>
    <lanes>
      <laneSection s="0.0">
        <left><lane id="1" type="driving" level="false"><link/><width sOffset="0.0" a="3.5" b="0" c="0" d="0"/></lane></left>
        <center><lane id="0" type="none" level="false"><link/></lane></center>
        <right><lane id="-1" type="driving" level="false"><link/><width sOffset="0.0" a="3.5" b="0" c="0" d="0"/></lane></right>
      </laneSection>
    </lanes>
  </road>
</OpenDRIVE>
"#;

/// The calls answered with `Response<void>` by CARLA (their errors have
/// another shape).
const VOID_CALLS: &[&str] = &[
    "load_new_episode",
    "set_actor_simulate_physics",
    "set_actor_collisions",
    "copy_opendrive_to_file",
];

/// How long a call waits for the world's server to answer a (re)connection.
const CONNECT_TIMEOUT: Duration = Duration::from_secs(2);

/// One CARLA connection.
pub(crate) struct Session {
    world: String,
    timeout: Duration,
    peer: SocketAddr,
    streaming_port: u16,
    hub: Arc<Hub>,
    client: Option<Client>,
    ticker: Option<Ticker>,
}

impl std::fmt::Debug for Session {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Session")
            .field("peer", &self.peer)
            .field("ticker", &self.ticker.is_some())
            .finish_non_exhaustive()
    }
}

/// A failed call: the message the script's `RuntimeError` carries.
type Failed = String;

impl Session {
    pub(crate) fn new(
        world: String,
        timeout: Duration,
        peer: SocketAddr,
        streaming_port: u16,
        hub: Arc<Hub>,
    ) -> Self {
        Self {
            world,
            timeout,
            peer,
            streaming_port,
            hub,
            client: None,
            ticker: None,
        }
    }

    /// This connection's name as a ticker: `carla:<address>`.
    fn ticker_name(&self) -> String {
        format!("carla:{}", self.peer)
    }

    /// The simbus client, connected on first use and again after the
    /// server came back.
    fn client(&mut self) -> Result<&mut Client, Failed> {
        if self.client.is_none() {
            // A dead server's world fails fast, well inside CARLA's timeout.
            let connect = self.timeout.min(CONNECT_TIMEOUT);
            let mut client =
                Client::connect(&self.world, connect).map_err(|e| format!("simbus: {e}"))?;
            client.set_request_timeout(self.timeout);
            self.client = Some(client);
        }
        self.client
            .as_mut()
            .ok_or_else(|| "simbus: no connection".to_string())
    }

    /// Forgets the connection once its server is gone (the next call
    /// connects again, to the server that came back on the world).
    fn forget_a_dead_server(&mut self) {
        let gone = self
            .client
            .as_ref()
            .is_some_and(|c| !sim_client::process_alive(c.server_pid()));
        if gone {
            info!(peer = %self.peer, world = self.world, "the simbus server is gone; the next call connects again");
            self.ticker = None;
            self.client = None;
        }
    }

    /// Answers one request.
    pub(crate) fn answer(&mut self, request: &Request) -> Answer {
        let void = VOID_CALLS.contains(&request.method.as_str());
        let answer = self.call(&request.method, &request.args);
        // A batch reports a dead server per command: look after every call.
        self.forget_a_dead_server();
        match answer {
            Ok(answer) => answer,
            Err(message) => {
                debug!(peer = %self.peer, method = request.method, "refused: {message}");
                if request.method == "apply_batch" {
                    Answer::RpcError(message)
                } else {
                    Answer::Error { message, void }
                }
            }
        }
    }

    fn call(&mut self, method: &str, args: &[Value]) -> Result<Answer, Failed> {
        let value = |v: Value| Ok(Answer::Value(v));
        match method {
            "version" => value(Value::from(CARLA_VERSION)),
            "get_episode_info" => {
                let episode = self.status()?.episode;
                let episode = shared_types::carla::episode_id(self.client()?.server_pid(), episode);
                value(Value::Array(vec![
                    Value::from(episode),
                    Value::Array(vec![Value::Binary(
                        token(WORLD_STREAM_ID, self.streaming_port).to_vec(),
                    )]),
                ]))
            }
            "get_sensor_token" => {
                let stream = arg_u64(args, 0, method)?;
                let stream =
                    u32::try_from(stream).map_err(|_| format!("{method}: no stream {stream}"))?;
                if stream != WORLD_STREAM_ID {
                    sensors::expect(&self.hub, &self.world, stream, self.timeout)?;
                }
                value(Value::Array(vec![Value::Binary(
                    token(stream, self.streaming_port).to_vec(),
                )]))
            }
            "get_episode_settings" => {
                let settings = self
                    .client()?
                    .get_settings()
                    .map_err(|e| format!("simbus: {e}"))?;
                let other = lock(&self.hub.other_settings).clone();
                value(episode_settings(&settings, &other))
            }
            "set_episode_settings" => self.set_settings(args),
            "tick_cue" => self.tick(),
            "get_map_info" => {
                let scene = self.status()?.scene.to_string_lossy();
                value(Value::Array(vec![
                    Value::from(scene),
                    Value::Array(Vec::new()),
                ]))
            }
            "get_map_data" => value(Value::from(OPENDRIVE)),
            "get_actors_by_id" => {
                let ids = args
                    .first()
                    .and_then(Value::as_array)
                    .ok_or("get_actors_by_id: no id list")?;
                let records = ids
                    .iter()
                    .filter_map(commands::actor_id)
                    .filter_map(|id| self.actor_record(id))
                    .collect();
                value(Value::Array(records))
            }
            "get_actor_definitions" => value(blueprints::library()),
            "get_actor_bounding_box" => {
                let id = args
                    .first()
                    .and_then(commands::actor_id)
                    .ok_or("get_actor_bounding_box: no actor id")?;
                let extent = lock(&self.hub.actors)
                    .get(&id)
                    .map_or([0.0; 3], |a| a.extent);
                value(bounding_box(id, extent))
            }
            "spawn_actor" | "spawn_actor_with_parent" => {
                let description = Description::parse(args.first().unwrap_or(&Value::Nil))
                    .map_err(|e| format!("simbus: {method}: {e}"))?;
                let transform = args
                    .get(1)
                    .and_then(commands::transform)
                    .ok_or_else(|| format!("{method}: the transform is of the wrong shape"))?;
                let parent = match method {
                    "spawn_actor" => None,
                    _ => Some(
                        args.get(2)
                            .and_then(commands::actor_id)
                            .ok_or_else(|| format!("{method}: the parent is not an actor id"))?,
                    ),
                };
                let id = self.spawn(&description, &transform, parent)?;
                let record = self
                    .actor_record(id)
                    .ok_or_else(|| format!("simbus: actor {id} vanished at once"))?;
                value(record)
            }
            "destroy_actor" => {
                let id = args
                    .first()
                    .and_then(commands::actor_id)
                    .ok_or("destroy_actor: no actor id")?;
                let results = self.run_batch(vec![Ok(BatchCommand::Actor(id, Op::Destroy))]);
                results.into_iter().next().unwrap_or(Ok(id))?;
                value(Value::Boolean(true))
            }
            "apply_batch" => {
                let list = args
                    .first()
                    .and_then(Value::as_array)
                    .ok_or("apply_batch: no command list")?;
                let batch = list
                    .iter()
                    .map(|c| commands::batch_command(c, None))
                    .collect();
                let results = self.run_batch(batch);
                if args.get(1).and_then(Value::as_bool) == Some(true) {
                    self.tick()?;
                }
                // CARLA's `Response<ActorId>` per command, not wrapped.
                let responses = results
                    .into_iter()
                    .map(|r| match r {
                        Ok(id) => Value::Array(vec![Value::Array(vec![
                            Value::from(1u8),
                            Value::from(id),
                        ])]),
                        Err(e) => Value::Array(vec![Value::Array(vec![
                            Value::from(0u8),
                            Value::Array(vec![Value::from(e)]),
                        ])]),
                    })
                    .collect();
                Ok(Answer::Raw(Value::Array(responses)))
            }
            "get_required_files" | "query_lights_state" | "get_vehicle_light_states" => {
                value(Value::Array(Vec::new()))
            }
            "get_available_maps" => value(Value::Array(
                ["default", "empty", "boxes:100"]
                    .into_iter()
                    .map(Value::from)
                    .collect(),
            )),
            "get_weather_parameters" => value(Value::Array(vec![Value::F32(0.0); 14])),
            "load_new_episode" => {
                let scene = arg_str(args, 0, method)?;
                let reset = args.get(1).and_then(Value::as_bool).unwrap_or(false);
                let client = self.client()?;
                let loaded = if scene.is_empty() {
                    client.reload_world(reset)
                } else {
                    client.load_world(&scene, reset)
                };
                loaded.map_err(|e| format!("simbus: {e}"))?;
                if reset {
                    *lock(&self.hub.other_settings) = default_other_fields();
                }
                Ok(Answer::Done)
            }
            "start_recorder"
            | "stop_recorder"
            | "replay_file"
            | "stop_replayer"
            | "set_replayer_time_factor"
            | "show_recorder_file_info"
            | "show_recorder_collisions"
            | "show_recorder_actors_blocked" => self.recorder(method, args),
            _ => {
                if let Some(op) = commands::rpc_op(method, args) {
                    let (id, op) = op?;
                    let results = self.run_batch(vec![Ok(BatchCommand::Actor(id, op))]);
                    results.into_iter().next().unwrap_or(Ok(id))?;
                    return Ok(if VOID_CALLS.contains(&method) {
                        Answer::Done
                    } else {
                        Answer::Value(Value::Nil)
                    });
                }
                Err(format!(
                    "simbus: CARLA's `{method}` is not supported by simbus (its CARLA gateway serves the world, its settings and ticks, actors, batches, sensors and the recorder)"
                ))
            }
        }
    }

    /// CARLA's `rpc::Actor` of actor `id`, if the world has it.
    fn actor_record(&self, id: u32) -> Option<Value> {
        let registry = lock(&self.hub.registry);
        if let Some(sensor) = registry.sensors.get(&id) {
            return Some(actor_record(
                id,
                sensor.parent,
                sensor.description.clone(),
                [0.0; 3],
                Value::Binary(token(id, self.streaming_port).to_vec()),
            ));
        }
        let (kind, extent) = match lock(&self.hub.actors).get(&id) {
            Some(a) => (a.kind, a.extent),
            None => {
                // Spawned through the gateway, not in a frame yet.
                let description = registry.descriptions.get(&id)?;
                let uid = description.as_array()?.first()?.as_u64()?;
                (blueprints::kind_of_uid(uid), [0.0; 3])
            }
        };
        let description = registry.descriptions.get(&id).cloned().unwrap_or_else(|| {
            Value::Array(vec![
                Value::from(kind),
                Value::from(type_id(kind)),
                Value::Array(Vec::new()),
            ])
        });
        Some(actor_record(
            id,
            0,
            description,
            extent,
            Value::Binary(Vec::new()),
        ))
    }

    /// Spawns one actor (a sensor through simbus's sensor service, a body
    /// through a batch) and returns its CARLA id.
    fn spawn(
        &mut self,
        description: &Description,
        transform: &shared_types::carla::CarlaTransform,
        parent: Option<u32>,
    ) -> Result<u32, Failed> {
        let spawn = description
            .spawn(transform)
            .map_err(|e| format!("simbus: {e}"))?;
        let id = match spawn {
            Spawn::Body(command) => {
                if let Some(parent) = parent {
                    return Err(format!(
                        "simbus: {} cannot be attached to actor {parent}: simbus attaches only sensors",
                        description.id
                    ));
                }
                self.apply(&[command])?
                    .into_iter()
                    .next()
                    .unwrap_or_else(|| Err("simbus: no answer".into()))?
            }
            Spawn::Sensor(spec) => {
                let parent = parent.unwrap_or(0);
                if sensors::simbus_id(parent).is_some() {
                    return Err(format!(
                        "simbus: a sensor cannot ride on sensor {parent}: attach it to an actor"
                    ));
                }
                let spec = spec.attached_to(u64::from(parent));
                let info = self
                    .client()?
                    .create_sensor(spec)
                    .map_err(|e| format!("simbus: {e}"))?;
                let id = sensors::carla_id(info.id).ok_or_else(|| {
                    format!("simbus: sensor id {} is out of CARLA's range", info.id)
                })?;
                lock(&self.hub.registry).sensors.insert(
                    id,
                    SensorEntry {
                        simbus_id: info.id,
                        spec,
                        description: description.record(),
                        parent,
                    },
                );
                return Ok(id);
            }
        };
        lock(&self.hub.registry)
            .descriptions
            .insert(id, description.record());
        Ok(id)
    }

    /// Applies simbus commands in one batch: per command, the actor's id or
    /// why it failed.
    fn apply(
        &mut self,
        batch: &[shared_types::Command],
    ) -> Result<Vec<Result<u32, String>>, Failed> {
        if batch.is_empty() {
            return Ok(Vec::new());
        }
        let response = self
            .client()?
            .apply_batch_sync(batch, false)
            .map_err(|e| format!("simbus: {e}"))?;
        Ok(response
            .results
            .iter()
            .zip(batch)
            .map(
                |(r, c)| match shared_types::CommandStatus::from_u32(r.status) {
                    Some(shared_types::CommandStatus::Ok) => u32::try_from(r.actor).map_err(|_| {
                        format!("simbus: actor id {} is out of CARLA's range", r.actor)
                    }),
                    status => {
                        let status = status.unwrap_or(shared_types::CommandStatus::UnknownCommand);
                        Err(match c.actor {
                            0 => format!("simbus: spawn refused: {status}"),
                            actor => format!("simbus: actor {actor}: {status}"),
                        })
                    }
                },
            )
            .collect())
    }

    /// Runs CARLA commands in order: one simbus batch for the commands on
    /// bodies, sensors through the sensor service, then every spawned
    /// actor's `.then(...)` commands. One result per command.
    fn run_batch(&mut self, batch: Vec<Result<BatchCommand, String>>) -> Vec<Result<u32, String>> {
        let mut results: Vec<Result<u32, String>> = Vec::with_capacity(batch.len());
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
                        after.push((i, then, description));
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
                Ok(BatchCommand::Actor(id, Op::Destroy)) if sensors::simbus_id(id).is_some() => {
                    self.destroy_sensor(id)
                }
                Ok(BatchCommand::Actor(id, op)) => {
                    let last = lock(&self.hub.actors).get(&id).copied();
                    op.command(id, last.as_ref()).map(|command| {
                        slots.push(i);
                        simbus.push(command);
                        if let Op::Control(control) = op {
                            lock(&self.hub.registry).controls.insert(id, control);
                        }
                        id
                    })
                }
            };
            results.push(result);
        }
        match self.apply(&simbus) {
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
        for (i, then, description) in after {
            if let Ok(id) = results[i] {
                lock(&self.hub.registry)
                    .descriptions
                    .insert(id, description.record());
                self.then(id, &then);
            }
        }
        results
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
                Ok(BatchCommand::Spawn { .. }) => {
                    Err("simbus: SpawnActor inside .then() is not supported by simbus".to_string())
                }
                other => other,
            })
            .collect();
        for result in self.run_batch(batch) {
            if let Err(e) = result {
                debug!(peer = %self.peer, actor = id, "a .then() command failed: {e}");
            }
        }
    }

    fn destroy_sensor(&mut self, id: u32) -> Result<u32, String> {
        let simbus_id =
            sensors::simbus_id(id).ok_or_else(|| format!("simbus: actor {id} is not a sensor"))?;
        self.client()?
            .destroy_sensor(simbus_id)
            .map_err(|e| format!("simbus: {e}"))?;
        lock(&self.hub.registry).sensors.remove(&id);
        Ok(id)
    }

    /// CARLA's recorder calls on simbus's recorder. The `show_*` calls read
    /// the file here and answer JSON text (CARLA's answer preformatted text).
    fn recorder(&mut self, method: &str, args: &[Value]) -> Result<Answer, Failed> {
        let refused = |e: sim_client::RecorderError| format!("simbus: {e}");
        let json =
            |v: serde_json::Result<String>| Ok(Answer::Value(Value::from(v.unwrap_or_default())));
        let number = |i: usize| {
            args.get(i)
                .and_then(|v| v.as_f64().or_else(|| v.as_i64().map(|n| n as f64)))
                .ok_or_else(|| format!("{method}: argument {i} is not a number"))
        };
        match method {
            "start_recorder" => {
                let name = arg_str(args, 0, method)?;
                let sensors = args.get(1).and_then(Value::as_bool).unwrap_or(false);
                let path = self
                    .client()?
                    .start_recorder(&name, sensors)
                    .map_err(refused)?;
                Ok(Answer::Value(Value::from(
                    path.to_string_lossy().into_owned(),
                )))
            }
            "stop_recorder" => {
                self.client()?.stop_recorder().map_err(refused)?;
                Ok(Answer::Done)
            }
            "replay_file" => {
                let name = arg_str(args, 0, method)?;
                let (start, duration) = (number(1)?, number(2)?);
                let follow = args.get(3).and_then(Value::as_u64).unwrap_or(0);
                let sensors = args.get(4).and_then(Value::as_bool).unwrap_or(false);
                let status = self
                    .client()?
                    .replay_file(&name, start, duration, follow, sensors)
                    .map_err(refused)?;
                Ok(Answer::Value(Value::from(format!(
                    "Replaying {name}: {} ({})",
                    crate::cli::words::count(status.replay.total, "frame"),
                    status.replay.mode
                ))))
            }
            "stop_replayer" => {
                let keep = args.first().and_then(Value::as_bool).unwrap_or(false);
                self.client()?.stop_replayer(keep).map_err(refused)?;
                Ok(Answer::Done)
            }
            "set_replayer_time_factor" => {
                let factor = number(0)?;
                self.client()?
                    .set_replayer_time_factor(factor)
                    .map_err(refused)?;
                Ok(Answer::Done)
            }
            "show_recorder_file_info" => {
                let name = arg_str(args, 0, method)?;
                let all = args.get(1).and_then(Value::as_bool).unwrap_or(false);
                let info = sim_client::inspect::file_info(&name, all).map_err(|e| e.to_string())?;
                json(serde_json::to_string_pretty(&info))
            }
            "show_recorder_collisions" => {
                let name = arg_str(args, 0, method)?;
                let kind = |i: usize| {
                    args.get(i)
                        .and_then(Value::as_u64)
                        .and_then(|c| char::from_u32(c as u32))
                        .unwrap_or('a')
                };
                let list = sim_client::inspect::collisions(&name, kind(1), kind(2))
                    .map_err(|e| e.to_string())?;
                json(serde_json::to_string_pretty(&list))
            }
            _ => {
                let name = arg_str(args, 0, method)?;
                let list = sim_client::inspect::actors_blocked(&name, number(1)?, number(2)?)
                    .map_err(|e| e.to_string())?;
                json(serde_json::to_string_pretty(&list))
            }
        }
    }

    fn status(&mut self) -> Result<shared_types::StatusReport, Failed> {
        let status = self.client()?.status();
        status.map_err(|e| format!("simbus: {e}"))
    }

    /// CARLA's `apply_settings`: entering synchronous mode makes this
    /// connection the world's ticker (refused, naming the owner, if another
    /// client ticks); leaving it gives the ownership back.
    fn set_settings(&mut self, args: &[Value]) -> Result<Answer, Failed> {
        let settings = parse_settings(args.first())
            .ok_or("set_episode_settings: settings of the wrong shape")?;
        if settings.synchronous_mode && self.ticker.is_none() {
            let name = self.ticker_name();
            let ticker = self
                .client()?
                .claim_ticker_as(&name)
                .map_err(|e| format!("simbus: {e}"))?;
            info!(peer = %self.peer, "a CARLA connection is the ticker");
            let mut ticker = ticker;
            ticker.set_wait_mode(shared_types::WaitMode::Hybrid);
            self.ticker = Some(ticker);
        }
        let applied = match &mut self.ticker {
            Some(ticker) => ticker.apply_settings(settings),
            None => self.client()?.apply_settings(settings),
        };
        let frame = applied.map_err(|e| format!("simbus: {e}"))?;
        if !settings.synchronous_mode {
            if let Some(ticker) = self.ticker.take() {
                let _ = ticker.release();
                info!(peer = %self.peer, "the CARLA ticker left synchronous mode");
            }
        }
        if let Some(other) = other_fields(args.first()) {
            *lock(&self.hub.other_settings) = other;
        }
        // The frame the settings hold from; the client waits for the one before.
        Ok(Answer::Value(Value::from(frame.saturating_sub(1))))
    }

    /// CARLA's `world.tick()`: the ticker steps a frame; in asynchronous
    /// mode anyone may wait for the next one; in synchronous mode another
    /// client's tick is refused naming the owner.
    fn tick(&mut self) -> Result<Answer, Failed> {
        if let Some(ticker) = &mut self.ticker {
            let frame = ticker
                .tick(self.timeout)
                .map_err(|e| format!("simbus: {e}"))?;
            self.publish(frame);
            return Ok(Answer::Value(Value::from(frame)));
        }
        let settings = self
            .client()?
            .get_settings()
            .map_err(|e| format!("simbus: {e}"))?;
        if !settings.synchronous_mode {
            let next = self.hub.last_frame() + 1;
            return Ok(Answer::Value(Value::from(next)));
        }
        // Synchronous and not ours: take it if free, else say who has it.
        let name = self.ticker_name();
        let mut ticker = self
            .client()?
            .claim_ticker_as(&name)
            .map_err(|e| format!("simbus: {e}"))?;
        ticker.set_wait_mode(shared_types::WaitMode::Hybrid);
        let frame = ticker
            .tick(self.timeout)
            .map_err(|e| format!("simbus: {e}"))?;
        self.ticker = Some(ticker);
        self.publish(frame);
        Ok(Answer::Value(Value::from(frame)))
    }

    /// Sends the world state of `frame`, just stepped, to the CARLA clients
    /// now (the pump would send it after its own wake-up).
    fn publish(&mut self, frame: u64) {
        let Some(client) = self.client.as_mut() else {
            return;
        };
        let pid = client.server_pid();
        // The frame is in shared memory already: older queued ones are
        // skipped without waiting.
        while let Ok(view) = client.wait_for_frame(Duration::from_millis(5)) {
            if view.frame() >= frame {
                super::stream::publish(&self.hub, &view, pid);
                return;
            }
        }
    }
}

/// CARLA's type id of a simbus actor kind.
fn type_id(kind: u32) -> &'static str {
    match shared_types::ActorKind::from_u32(kind) {
        Some(shared_types::ActorKind::Box) => "static.prop.box",
        Some(shared_types::ActorKind::Sphere) => "static.prop.sphere",
        Some(shared_types::ActorKind::Capsule) => "static.prop.capsule",
        Some(shared_types::ActorKind::Vehicle) => "vehicle.simbus.car",
        _ => "static.prop.fixed",
    }
}

/// CARLA's `BoundingBox` of actor `id`: centred, `extent` half sizes.
fn bounding_box(id: u32, extent: [f32; 3]) -> Value {
    let vector = |v: [f32; 3]| Value::Array(v.iter().map(|&x| Value::F32(x)).collect());
    Value::Array(vec![
        vector([0.0; 3]),
        vector(extent),
        vector([0.0; 3]),
        Value::from(id),
    ])
}

/// CARLA's `rpc::Actor`: id, parent, description, bounding box, no
/// semantic tags, and the stream token (sensors only).
fn actor_record(
    id: u32,
    parent: u32,
    description: Value,
    extent: [f32; 3],
    stream: Value,
) -> Value {
    Value::Array(vec![
        Value::from(id),
        Value::from(parent),
        description,
        bounding_box(id, extent),
        Value::Binary(Vec::new()),
        stream,
    ])
}

fn arg_u64(args: &[Value], i: usize, method: &str) -> Result<u64, Failed> {
    args.get(i)
        .and_then(Value::as_u64)
        .ok_or_else(|| format!("{method}: argument {i} is not an integer"))
}

fn arg_str(args: &[Value], i: usize, method: &str) -> Result<String, Failed> {
    args.get(i)
        .and_then(Value::as_str)
        .map(str::to_string)
        .ok_or_else(|| format!("{method}: argument {i} is not a string"))
}

/// The positions in CARLA's `EpisodeSettings` of the fields simbus does not
/// have (rendering, culling, ragdolls, large-map distances, spectator as
/// ego), and CARLA's defaults for them.
const OTHER_FIELDS: [usize; 6] = [1, 6, 7, 8, 9, 10];

/// CARLA's defaults of [`OTHER_FIELDS`].
pub(crate) fn default_other_fields() -> Vec<Value> {
    vec![
        Value::Boolean(false),
        Value::F32(0.0),
        Value::Boolean(true),
        Value::F32(3000.0),
        Value::F32(2000.0),
        Value::Boolean(false),
    ]
}

/// The [`OTHER_FIELDS`] of CARLA settings, if each has its default's type.
fn other_fields(value: Option<&Value>) -> Option<Vec<Value>> {
    let fields = value?.as_array()?;
    OTHER_FIELDS
        .iter()
        .zip(default_other_fields())
        .map(|(&i, default)| {
            let v = fields.get(i)?;
            let same = match default {
                Value::Boolean(_) => v.is_bool(),
                _ => v.as_f64().is_some() || v.as_i64().is_some(),
            };
            same.then(|| v.clone())
        })
        .collect()
}

/// simbus settings as CARLA's `EpisodeSettings` (11 fields; `other` holds
/// the ones simbus does not have, as a script last set them).
fn episode_settings(s: &WorldSettings, other: &[Value]) -> Value {
    let fixed = match s.fixed_delta_seconds {
        Some(dt) => Value::Array(vec![Value::Boolean(true), Value::F64(dt)]),
        None => Value::Array(vec![Value::Boolean(false)]),
    };
    let mut fields = vec![
        Value::Boolean(s.synchronous_mode),
        Value::Nil,
        fixed,
        Value::Boolean(s.substepping),
        Value::F64(s.max_substep_delta_time),
        Value::from(s.max_substeps),
    ];
    fields.resize(11, Value::Nil);
    let defaults = default_other_fields();
    for (k, &i) in OTHER_FIELDS.iter().enumerate() {
        fields[i] = other.get(k).unwrap_or(&defaults[k]).clone();
    }
    Value::Array(fields)
}

/// CARLA's `EpisodeSettings` as simbus settings (the fields simbus does not
/// have are ignored).
fn parse_settings(value: Option<&Value>) -> Option<WorldSettings> {
    let fields = value?.as_array()?;
    let number = |v: &Value| v.as_f64().or_else(|| v.as_i64().map(|i| i as f64));
    let fixed = fields.get(2)?.as_array()?;
    let fixed_delta_seconds = match fixed.first()?.as_bool()? {
        true => Some(number(fixed.get(1)?)?),
        false => None,
    };
    Some(WorldSettings {
        synchronous_mode: fields.first()?.as_bool()?,
        fixed_delta_seconds,
        substepping: fields.get(3)?.as_bool()?,
        max_substep_delta_time: number(fields.get(4)?)?,
        max_substeps: u32::try_from(fields.get(5)?.as_u64()?).ok()?,
    })
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn settings_round_trip_through_carlas_shape() {
        let s = WorldSettings {
            synchronous_mode: true,
            fixed_delta_seconds: Some(0.05),
            substepping: true,
            max_substep_delta_time: 0.01,
            max_substeps: 10,
        };
        assert_eq!(parse_settings(Some(&episode_settings(&s, &[]))), Some(s));
        let variable = WorldSettings::default();
        assert_eq!(
            parse_settings(Some(&episode_settings(&variable, &[]))),
            Some(variable)
        );
        // The fields simbus does not have come back as they were set.
        let mut other = default_other_fields();
        other[0] = Value::Boolean(true);
        other[3] = Value::F32(500.0);
        let carla = episode_settings(&s, &other);
        assert_eq!(other_fields(Some(&carla)), Some(other));
        assert_eq!(other_fields(Some(&Value::from(3))), None);
        assert_eq!(parse_settings(Some(&Value::from("nonsense"))), None);
    }
}
