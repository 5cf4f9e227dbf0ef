//! CARLA's streaming side: clients connect, write the 4-byte id of the
//! stream they want, then read `[u32 length][message]` frames. The world
//! stream carries one world state per simbus frame, pumped from a frame
//! subscription of the gateway's own; each sensor stream is fed by a
//! forwarder (`sensors.rs`) while someone listens.
//!
//! Who reads which stream, and what each is sent across an episode change
//! (CARLA's client survives one only if the gateway is quiet then), lives
//! in [`readers`].

mod readers;

use std::collections::HashMap;
use std::io::Read;
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicU32, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use rmpv::Value;
use shared_types::SensorSpec;
use sim_client::{Client, ConnectError, FrameView};
use tracing::{debug, info, warn};

use crate::convert;
use crate::locks::lock;
use crate::signals::Signals;
use crate::wire::{self as carla, CarlaActorState, CarlaTransform, CarlaVehicleControl};

/// How long a subscriber may take to accept one message before it is
/// dropped (a client that connects and never reads must not stall the rest).
const WRITE_TIMEOUT: Duration = Duration::from_secs(2);
/// How long the world stream's connection waits for the world's server.
const SERVER_WAIT: Duration = Duration::from_secs(5);
/// How long the world stream waits before it connects again after a
/// connection refused at once (the world full of clients, a server of
/// another protocol version, a broken shared directory): nothing
/// announces that this changed, so this is a retry delay, not a wait.
const RETRY_AFTER: Duration = Duration::from_millis(200);

/// What the gateway knows about one actor of the last frame.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct ActorInfo {
    pub(crate) kind: u32,
    /// Half extents in CARLA's axes.
    pub(crate) extent: [f32; 3],
    /// simbus pose and velocities (for sensors riding on the actor, and
    /// commands that change one part).
    pub(crate) position: [f32; 3],
    pub(crate) rotation: [f32; 4],
    pub(crate) linear: [f32; 3],
    pub(crate) angular: [f32; 3],
}

/// A sensor spawned through the gateway.
#[derive(Debug, Clone)]
pub(crate) struct SensorEntry {
    /// Its simbus sensor (0: none, a sensor CARLA's client computes).
    pub(crate) simbus_id: u64,
    pub(crate) spec: SensorSpec,
    /// CARLA's actor description it was spawned from.
    pub(crate) description: Value,
    /// The CARLA id of its parent (0: none).
    pub(crate) parent: u32,
    /// Where it was in the last world state.
    pub(crate) pose: ([f32; 3], [f32; 4]),
    /// Its parent went (its simbus sensor with it) and no client destroyed
    /// it yet: reported as CARLA's `PendingKill` where it last was, so
    /// `is_alive` reads false and `destroy()` succeeds (CARLA's client
    /// reads an absent actor's state from uninitialised memory).
    pub(crate) gone: bool,
}

impl SensorEntry {
    /// A sensor just spawned on `parent` (0: none) from `spec`.
    pub(crate) fn new(simbus_id: u64, spec: SensorSpec, description: Value, parent: u32) -> Self {
        Self {
            simbus_id,
            spec,
            description,
            parent,
            pose: (spec.position, [0.0, 0.0, 0.0, 1.0]),
            gone: false,
        }
    }
}

/// What CARLA clients spawned and set through the gateway: descriptions
/// (for `actor.attributes`), sensors, vehicles' last controls.
#[derive(Debug, Default)]
pub(crate) struct Registry {
    pub(crate) descriptions: HashMap<u32, Value>,
    pub(crate) sensors: HashMap<u32, SensorEntry>,
    pub(crate) controls: HashMap<u32, CarlaVehicleControl>,
    /// Each vehicle's lights as CARLA clients set them (CARLA's
    /// `VehicleLightState` flags; simbus draws no light).
    pub(crate) vehicle_lights: HashMap<u32, u32>,
    /// Each vehicle's Ackermann controller settings as CARLA clients set
    /// them.
    pub(crate) ackermann_settings: HashMap<u32, [f32; 6]>,
    /// Client-side sensors numbered so far ([`crate::wire::client_side_id`]).
    pub(crate) client_side: u32,
}

/// A world load in flight, from [`Hub::change_episode`]: no sensor
/// capture goes out and the world stream is held until it goes (the
/// sensors end with their episode; a load that fails lets both flow
/// again). See [`readers`] for why.
#[derive(Debug)]
pub(crate) struct EpisodeChange {
    hub: Arc<Hub>,
    /// The episode the load began, once it did.
    began: Option<readers::EpisodeKey>,
}

impl EpisodeChange {
    /// The load began episode `episode` of the run `run_pid`: from
    /// the return on, no message of an older episode goes out, captures of
    /// this one flow again, and the world stream waits for the loading
    /// client to subscribe to it again.
    pub(crate) fn begun(mut self, run_pid: u32, episode: u64) {
        self.began = Some((run_pid, episode));
    }

    /// Waits, before the load is answered, until the captures written
    /// before it had [`readers::CAPTURES_LAND`] to reach the client's
    /// sensor callbacks (none goes out meanwhile): a callback still to
    /// run when CARLA's client swaps its episode builds one of its own.
    pub(crate) fn let_captures_land(&self) {
        let wait = lock(&self.hub.streams).captures_land_in();
        if !wait.is_zero() {
            debug!(
                wait_ms = wait.as_millis() as u64,
                "letting the last captures reach the client before answering the load"
            );
            std::thread::sleep(wait);
        }
    }
}

impl Drop for EpisodeChange {
    fn drop(&mut self) {
        lock(&self.hub.streams).change_ends(self.began);
    }
}

/// The streams and who reads them, and what the gateway keeps for CARLA
/// clients about the world.
#[derive(Debug)]
pub(crate) struct Hub {
    streams: Mutex<readers::Streams>,
    /// The actors of the last frame.
    pub(crate) actors: Mutex<HashMap<u32, ActorInfo>>,
    pub(crate) registry: Mutex<Registry>,
    /// (run pid, episode, frame) of the last world state sent.
    sent: Mutex<Sent>,
    sent_changed: Condvar,
    /// The `EpisodeSettings` fields simbus does not have, as last set.
    pub(crate) other_settings: Mutex<Vec<Value>>,
    /// The spectator's pose, as CARLA clients last set it: the gateway's
    /// own, no simbus body (every client of the gateway sees the same).
    pub(crate) spectator: Mutex<CarlaTransform>,
    /// The maps the gateway gave episodes (`maps.rs`).
    pub(crate) maps: crate::maps::Maps,
    /// The traffic managers CARLA clients run, by port.
    pub(crate) traffic_managers: Mutex<crate::traffic_managers::Registry>,
    /// The gateway's own traffic managers, by port.
    pub(crate) natives: crate::traffic_manager::Natives,
    /// CARLA's native ROS 2: the sensors enabled for it, and its adapter.
    pub(crate) ros2: crate::ros2::Ros2,
    /// The recording a CARLA client started, while it runs.
    pub(crate) recording: Mutex<Option<std::path::PathBuf>>,
    /// The weather CARLA clients set (simbus renders no sky).
    pub(crate) weather: Mutex<carla::Weather>,
    /// The town's traffic lights and signs, as seen in its frames.
    pub(crate) signals: Mutex<crate::signals::Signals>,
    /// The last world stream id handed out ([`Hub::next_world_stream`]).
    world_streams: AtomicU32,
    /// How many connections have ended (and released any tick ownership
    /// they held); a claim refused by another connection of this gateway
    /// waits on it ([`Hub::wait_for_a_connection_to_end`]).
    ended: Mutex<u64>,
    ended_changed: Condvar,
}

impl Default for Hub {
    fn default() -> Self {
        Self {
            streams: Mutex::default(),
            actors: Mutex::default(),
            registry: Mutex::default(),
            sent: Mutex::default(),
            sent_changed: Condvar::default(),
            other_settings: Mutex::new(crate::episode_settings::default_other_fields()),
            spectator: Mutex::default(),
            maps: crate::maps::Maps::default(),
            traffic_managers: Mutex::default(),
            natives: crate::traffic_manager::Natives::default(),
            ros2: crate::ros2::Ros2::default(),
            recording: Mutex::default(),
            weather: Mutex::new(carla::CLEAR_NOON),
            signals: Mutex::default(),
            world_streams: AtomicU32::new(0),
            ended: Mutex::default(),
            ended_changed: Condvar::default(),
        }
    }
}

/// (run pid, episode, frame) of a world state.
type Sent = (u32, u64, u64);

impl Hub {
    /// A connection ended, its tick ownership released.
    pub(crate) fn connection_ended(&self) {
        *lock(&self.ended) += 1;
        self.ended_changed.notify_all();
    }

    /// Waits until a connection ends, at most until `deadline`; whether
    /// one did.
    pub(crate) fn wait_for_a_connection_to_end(&self, deadline: std::time::Instant) -> bool {
        let mut ended = lock(&self.ended);
        let before = *ended;
        while *ended == before {
            let Some(left) = deadline.checked_duration_since(std::time::Instant::now()) else {
                return false;
            };
            ended = match self.ended_changed.wait_timeout(ended, left) {
                Ok((guard, _)) => guard,
                Err(poisoned) => poisoned.into_inner().0,
            };
        }
        true
    }

    /// A world stream id no episode of this gateway's clients had just
    /// before: CARLA's client keys its stream subscriptions by id without
    /// a lock, and when a world load drops its episode while an io thread
    /// still reads a world state, the old episode unsubscribes later, from
    /// that thread. Under one id for all episodes the new subscription is
    /// then refused (the id is taken) and freed while it connects: a
    /// segfault in its first read. A new id per `get_episode_info` keeps
    /// the two subscriptions apart; all of them read the one world stream.
    pub(crate) fn next_world_stream(&self) -> u32 {
        let previous = self
            .world_streams
            .fetch_update(Ordering::Relaxed, Ordering::Relaxed, |n| {
                Some(carla::world_stream_after(n))
            })
            .unwrap_or_default();
        carla::world_stream_after(previous)
    }

    /// Sends `message`, a capture of `episode` (of the run `run_pid`),
    /// to every reader of sensor stream `stream`, unless a world load is in
    /// flight or a newer episode began (the sensor is gone with its
    /// episode). Returns whether it went out (or waits for its reader).
    pub(crate) fn send_capture(
        &self,
        stream: u32,
        run_pid: u32,
        episode: u64,
        message: &[u8],
    ) -> bool {
        lock(&self.streams).send_capture(stream, (run_pid, episode), message)
    }

    /// A world load or reload is about to be asked for (CARLA's
    /// `load_new_episode`): until the returned guard goes, no sensor
    /// capture goes out and world states are held; its
    /// [`EpisodeChange::begun`] names the new episode.
    pub(crate) fn change_episode(self: &Arc<Self>) -> EpisodeChange {
        lock(&self.streams).change_begins();
        EpisodeChange {
            hub: self.clone(),
            began: None,
        }
    }

    /// (run pid, episode, frame) of the last world state sent.
    pub(crate) fn last_sent(&self) -> (u32, u64, u64) {
        *lock(&self.sent)
    }

    /// The frame of the last world state sent.
    pub(crate) fn last_frame(&self) -> u64 {
        lock(&self.sent).2
    }

    /// Waits (at most `timeout`) until the world state of `frame` of
    /// `episode` went out. Sensor messages follow their frame's world
    /// state: CARLA's client may hold Python's GIL until it sees the frame
    /// (`apply_batch_sync(..., True)`), and a sensor callback arriving first
    /// would block the thread that must read it.
    pub(crate) fn after_world_state(
        &self,
        run_pid: u32,
        episode: u64,
        frame: u64,
        timeout: Duration,
    ) {
        let sent = lock(&self.sent);
        let _ = self
            .sent_changed
            .wait_timeout_while(sent, timeout, |&mut (p, e, f)| {
                p == run_pid && e == episode && f < frame
            });
    }

    /// How long a forwarder of `stream` may wait for a capture before it
    /// must look again whether anyone still listens: until the earliest
    /// handed-out token gives up on its connection. `None` while no token
    /// is pending: then only the forwarder's own failed write (or the
    /// sensor's end) can leave the stream without readers.
    pub(crate) fn patience(&self, stream: u32) -> Option<Duration> {
        lock(&self.streams).patience(stream)
    }

    /// Whether a forwarder of `stream` may stop: nobody reads or is about
    /// to. If so it is marked stopped, atomically with the check.
    pub(crate) fn retire(&self, stream: u32) -> bool {
        lock(&self.streams).retire(stream)
    }

    /// A token for `stream` was handed out: keep its messages until the
    /// connection comes. Returns whether a forwarder must be started.
    pub(crate) fn expect(&self, stream: u32) -> bool {
        lock(&self.streams).expect(stream)
    }

    /// The forwarder of `stream` could not start.
    pub(crate) fn forwarder_failed(&self, stream: u32) {
        lock(&self.streams).forwarder_failed(stream);
    }

    /// Stream `stream` ended (its sensor is gone): nothing more is written
    /// to its readers, which stay open until their clients hang up.
    pub(crate) fn end(&self, stream: u32) {
        let readers = lock(&self.streams).end(stream);
        for reader in readers {
            readers::linger(reader, stream);
        }
    }

    /// Adds `socket` to the readers of `stream`.
    fn subscribe(&self, stream: u32, socket: TcpStream) {
        let unknown = lock(&self.streams).subscribe(stream, socket);
        if let Some(socket) = unknown {
            debug!(stream, "a reader of a stream that ended");
            readers::linger(socket, stream);
        }
    }
}

/// Accepts stream subscriptions until the listener fails.
pub(crate) fn accept(listener: TcpListener, hub: Arc<Hub>) {
    for socket in listener.incoming() {
        let Ok(mut socket) = socket else {
            continue;
        };
        let hub = hub.clone();
        // The id comes first; a client that never sends it holds one thread
        // for at most the timeout.
        std::thread::spawn(move || {
            let _ = socket.set_read_timeout(Some(Duration::from_secs(10)));
            let mut id = [0u8; 4];
            if socket.read_exact(&mut id).is_err() {
                return;
            }
            let stream = u32::from_le_bytes(id);
            let _ = socket.set_nodelay(true);
            let _ = socket.set_write_timeout(Some(WRITE_TIMEOUT));
            debug!(stream, peer = ?socket.peer_addr().ok(), "stream subscribed");
            hub.subscribe(stream, socket);
        });
    }
}

/// The world state of `frame` as CARLA's client reads it: simbus's actors
/// (vehicles with their last control and the light they are at, lights
/// with their state, signs with their ids), the gateway's sensors, placed
/// on their parents in `actors`, and the spectator at `spectator`.
fn world_state(
    frame: &FrameView,
    run_pid: u32,
    actors: &HashMap<u32, ActorInfo>,
    registry: &Registry,
    signals: &Signals,
    spectator: CarlaTransform,
) -> Vec<u8> {
    let t = frame.timestamp();
    let mut out = Vec::with_capacity(
        carla::SENSOR_HEADER_LEN
            + carla::EPISODE_HEADER_LEN
            + (actors.len() + registry.sensors.len() + 1) * carla::ACTOR_STATE_LEN,
    );
    carla::sensor_header(
        &mut out,
        carla::WORLD_STATE_SENSOR_TYPE,
        t.frame,
        t.elapsed_seconds(),
        CarlaTransform::default(),
    );
    carla::episode_header(
        &mut out,
        carla::episode_id(run_pid, frame.episode()),
        t.platform_timestamp,
        t.delta_seconds() as f32,
    );
    for actor in frame.actors() {
        let mut state = convert::actor(actor);
        match actor.actor_kind() {
            Some(shared_types::ActorKind::Vehicle) => {
                state.vehicle = Some(
                    registry
                        .controls
                        .get(&state.id)
                        .copied()
                        .unwrap_or_default(),
                );
                state.signals = signals.vehicle(actor.position, actor.rotation);
            }
            Some(shared_types::ActorKind::TrafficLight) => state.light = signals.light(actor),
            Some(shared_types::ActorKind::TrafficSign) => state.sign = signals.sign_id(state.id),
            _ => {}
        }
        carla::actor_state(&mut out, &state);
    }
    for (&id, sensor) in &registry.sensors {
        let (position, rotation) = sensor.pose;
        let state = CarlaActorState {
            id,
            transform: convert::transform(position, rotation),
            dying: sensor.gone,
            ..CarlaActorState::default()
        };
        carla::actor_state(&mut out, &state);
    }
    let spectator = CarlaActorState {
        id: carla::SPECTATOR_ID,
        transform: spectator,
        ..CarlaActorState::default()
    };
    carla::actor_state(&mut out, &spectator);
    out
}

/// Where a sensor is: on its parent, or fixed in the world.
fn sensor_pose(
    sensor: &SensorEntry,
    actors: &HashMap<u32, ActorInfo>,
) -> Option<([f32; 3], [f32; 4])> {
    let rotation = match sensor.spec.rotation {
        [0.0, 0.0, 0.0, 0.0] => [0.0, 0.0, 0.0, 1.0],
        q => q,
    };
    let offset = (sensor.spec.position, rotation);
    if sensor.parent == 0 {
        return Some(offset);
    }
    actors
        .get(&sensor.parent)
        .map(|parent| convert::compose((parent.position, parent.rotation), offset))
}

/// Streams every frame of `world` as a world state until the process ends;
/// reconnects when the server comes back. A server resumed from its
/// journal continues its run (the same run pid): CARLA's clients see the
/// same episode go on, from the frame after the last one they were sent.
pub(crate) fn pump(world: String, hub: Arc<Hub>) {
    loop {
        let mut client = match Client::connect(&world, SERVER_WAIT) {
            Ok(client) => client,
            Err(e) => {
                debug!("world stream waits for the server: {e}");
                if !waited_for_the_server(&e) {
                    std::thread::sleep(RETRY_AFTER);
                }
                continue;
            }
        };
        client.set_every_frame(true);
        let run_pid = match client.status() {
            Ok(status) => status.run_pid,
            Err(e) => {
                debug!("world stream waits for the server: {e}");
                continue;
            }
        };
        info!(world, "streaming the world's frames to CARLA clients");
        loop {
            match client.wait_for_frame(Duration::from_secs(1)) {
                Ok(frame) => publish(&hub, &frame, run_pid),
                Err(sim_client::WaitError::Timeout { .. }) => {}
                Err(e) => {
                    warn!("world stream lost the server: {e}");
                    break;
                }
            }
        }
    }
}

/// Whether a failed connection waited its whole [`SERVER_WAIT`] for the
/// world's server (none came, or it did not answer): then it is tried
/// again at once, the connection being the wait.
fn waited_for_the_server(e: &ConnectError) -> bool {
    matches!(
        e,
        ConnectError::NoServer { .. } | ConnectError::NotAnswering { .. }
    )
}

/// Sends the world state of `frame` (of the run `run_pid`: the server's,
/// or the journal's it resumed) unless a newer one went out: the pump
/// sends every frame, and a CARLA ticker's session sends the frame it
/// stepped at once, saving the pump's wake-up. Frames a resumed server
/// computes again (those after its journal's last durable one) are not
/// sent again, as CARLA's client keeps no state older than its newest.
pub(crate) fn publish(hub: &Hub, frame: &FrameView, run_pid: u32) {
    let episode = frame.episode();
    let mut sent = lock(&hub.sent);
    let (p, e, f) = *sent;
    let stale = readers::older((run_pid, episode), (p, e));
    if stale || (p == run_pid && e == episode && f >= frame.frame()) {
        return;
    }
    let actors: HashMap<u32, ActorInfo> = frame
        .actors()
        .iter()
        .map(|a| {
            let info = ActorInfo {
                kind: a.kind,
                extent: convert::vector(a.extent),
                position: a.position,
                rotation: a.rotation,
                linear: a.linear_velocity,
                angular: a.angular_velocity,
            };
            (convert::actor_id(a.id), info)
        })
        .collect();
    let message = {
        let mut registry = lock(&hub.registry);
        if (p, e) != (run_pid, episode) {
            // A new episode (or run) ended every sensor (a server resumed
            // from its journal goes on with the run, and its sensors).
            registry.sensors.clear();
        }
        // A sensor whose parent is gone went with it; it stays, dying,
        // where it was until a client destroys it.
        for sensor in registry.sensors.values_mut() {
            match sensor_pose(sensor, &actors) {
                Some(pose) if !sensor.gone => sensor.pose = pose,
                _ => sensor.gone = true,
            }
        }
        let spectator = *lock(&hub.spectator);
        let mut signals = lock(&hub.signals);
        signals.observe(frame.actors());
        world_state(frame, run_pid, &actors, &registry, &signals, spectator)
    };
    // The actors go in before the state goes out: a CARLA client that
    // reads a new actor's id in it asks for its record at once
    // (`get_actors_by_id`), and must find it.
    let previous = std::mem::replace(&mut *lock(&hub.actors), actors);
    // A frame of an episode older than one begun (its reload answered
    // before the world stream's pump saw it) is not news.
    if !lock(&hub.streams).send_world_state((run_pid, episode), &message) {
        *lock(&hub.actors) = previous;
        return;
    }
    *sent = (run_pid, episode, frame.frame());
    drop(sent);
    hub.sent_changed.notify_all();
}
