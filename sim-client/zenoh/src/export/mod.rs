//! The exporting bridge, on the server's host: the world's frames and
//! captures published on Zenoh, its request services answered as Zenoh
//! queryables through ordinary simbus ports, tick ownership held for a
//! remote ticker and released when its mirror goes.
//!
//! Threads: one forwards frames (and `/clock`) and the captures of every
//! sensor (`frames.rs`); it owns its simbus ports. The main thread, an
//! [`Exporter`], owns the request ports; its one wait point is one
//! channel, fed by Zenoh's callbacks and by the frame thread (a tick's
//! answer goes back only once its frame is out). While answers are
//! awaited it also looks at the request ports, after 20 µs at first and
//! then at most every millisecond: iceoryx2's request-response gives a
//! client no event for an answer, and the server notifies none except
//! for frames (which a tick's answer follows, and which wake it at once).

mod declare;
mod frames;
mod relay;
mod ticker;

pub(crate) use self::relay::{service_name, MAX_FORWARDED_BATCH};

use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::time::{Duration, Instant};

use iceoryx2::node::Node;
use iceoryx2::port::notifier::Notifier;
use shared_types::{
    ControlRequest, ControlResponse, RecorderRequest, RecorderResponse, ServiceNames, TickResponse,
};
use sim_client::Client;
use simbus_transport::Bus;
use tracing::info;
use zenoh::query::Query;

use self::declare::{declare, mirror_of, Dropped};
use self::frames::{follow_sensors, Follow, FrameForwarder, Shared};
use self::relay::{Answer, BatchRelay, FixedRelay, Refusal, Refused, SensorRelay};
use self::ticker::{LockstepRelay, RemoteTickers, TickRelay};
use crate::error::{ExportError, FramesError, LocalError};
use crate::wire::{self, BridgeKeys, Forwarded};
use crate::{JsonViews, Notice, Side};

/// What wakes the exporter.
pub(super) enum Event {
    /// A query on one of the world's keys.
    Query(Query),
    /// A mirror's liveliness token appeared (`true`) or went.
    Mirror(String, bool),
    /// The frame thread published a frame.
    Forwarded,
    /// The frame thread ended: stopped, or the server is gone (why).
    FramesEnded(Option<FramesError>),
}

/// Sets its flag when dropped (also when unwinding), so the frame thread
/// stops before its scope is left.
struct SetOnDrop<'a>(&'a AtomicBool);

impl Drop for SetOnDrop<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

/// Exports `world` on `session` until `stop` or the server is gone.
pub(crate) fn run(side: Side<'_>) -> Result<(), ExportError> {
    let mut client = Client::connect(side.world.as_str(), side.timeout)?;
    client.set_request_timeout(side.timeout);
    let status = client.status()?;
    let keys = BridgeKeys::new(side.world);
    let (events, incoming) = mpsc::channel::<Event>();
    let shared = Arc::new(Shared::default());
    let _declared = declare(&side.session, &keys, &events, &shared)?;
    let (follow, followed) = mpsc::channel::<Follow>();
    let done = AtomicBool::new(false);
    std::thread::scope(|scope| {
        let _stop_frames = SetOnDrop(&done);
        let (session, keys, forwarded, done) = (&side.session, &keys, shared.clone(), &done);
        let to_main = events.clone();
        std::thread::Builder::new()
            .name("frames".into())
            .spawn_scoped(scope, move || {
                let ended = FrameForwarder::new(
                    side.world,
                    side.timeout,
                    session,
                    keys,
                    side.options.ros2_clock,
                    forwarded,
                )
                .and_then(|forwarder| {
                    forwarder.run(
                        &followed,
                        || frames::either(side.stop, done),
                        || {
                            let _ = to_main.send(Event::Forwarded);
                        },
                    )
                });
                let _ = to_main.send(Event::FramesEnded(ended.err()));
            })
            .map_err(ExportError::Thread)?;
        let mut exporter = Exporter::open(
            client,
            side.timeout,
            side.options.json,
            shared.clone(),
            follow,
        )?;
        exporter.await_first_frame(&incoming, side.timeout)?;
        (side.notice)(Notice::Exporting {
            world: side.world.clone(),
            endpoint: side.endpoint.to_owned(),
            server_pid: status.server_pid,
            frame: status.frame,
        });
        info!(world = %side.world, zid = %session.zid(), "exporting");
        let result = exporter.serve(&incoming, side.stop);
        exporter.finish();
        result
    })
}

/// The exporter's main thread: the world's request services answered for
/// queries from other hosts, and the remote ticker's ownership.
struct Exporter {
    client: Client,
    timeout: Duration,
    names: ServiceNames,
    keys: BridgeKeys,
    json: JsonViews,
    shared: Arc<Shared>,
    control: FixedRelay<ControlRequest, ControlResponse>,
    tick: TickRelay,
    recorder: FixedRelay<RecorderRequest, RecorderResponse>,
    batch: BatchRelay,
    sensors: SensorRelay,
    /// One lockstep port per remote participant (mirror, pid): the server
    /// tells participants apart by their port.
    lockstep: HashMap<(String, u32), LockstepRelay>,
    /// Wakes an idle (paced or waiting) server after a request.
    wake: Notifier<Bus>,
    /// The node of the relay ports (named as a client's, as `top` shows
    /// them); last, so the ports drop first.
    node: Node<Bus>,
    tickers: RemoteTickers,
    mirrors: BTreeSet<String>,
    /// Sensors the frame thread forwards, and how to ask it for more.
    following: BTreeSet<u64>,
    follow: Sender<Follow>,
    next_sensor_scan: Instant,
    /// Final answers, replied once their frame is out.
    held: Vec<Answer>,
    dropped: Dropped,
    /// How long to wait before looking at the request ports again.
    idle: Duration,
}

/// The first look at the request ports after an event.
const FIRST_LOOK: Duration = Duration::from_micros(20);
/// The longest wait between looks while answers are awaited.
const LAST_LOOK: Duration = Duration::from_millis(1);
/// The longest wait while nothing is awaited (how soon `stop` is seen).
const IDLE_WAIT: Duration = Duration::from_millis(100);

impl Exporter {
    /// Opens the request ports of the world `client` is connected to.
    fn open(
        client: Client,
        timeout: Duration,
        json: JsonViews,
        shared: Arc<Shared>,
        follow: Sender<Follow>,
    ) -> Result<Self, LocalError> {
        let names = ServiceNames::new(client.world());
        let node = crate::mirror::node("sim-client")?;
        Ok(Self {
            control: FixedRelay::open(&node, &names.control)?,
            tick: FixedRelay::open(&node, &names.tick)?,
            recorder: FixedRelay::open(&node, &names.recorder)?,
            batch: BatchRelay::open(&node, &names.batch)?,
            sensors: SensorRelay::open(&node, &names.sensors)?,
            wake: crate::mirror::wake_notifier_on(&node, &names)?,
            node,
            lockstep: HashMap::new(),
            keys: BridgeKeys::new(client.world()),
            names,
            client,
            timeout,
            json,
            shared,
            tickers: RemoteTickers::default(),
            mirrors: BTreeSet::new(),
            following: BTreeSet::new(),
            follow,
            next_sensor_scan: Instant::now(),
            held: Vec::new(),
            dropped: Dropped::default(),
            idle: FIRST_LOOK,
        })
    }

    /// Waits until the frame thread has published the current frame (a
    /// peer told of the export may then ask for it at once).
    fn await_first_frame(
        &mut self,
        incoming: &Receiver<Event>,
        timeout: Duration,
    ) -> Result<(), ExportError> {
        let deadline = Instant::now() + timeout;
        let mut early = Vec::new();
        let result = loop {
            let left = deadline.saturating_duration_since(Instant::now());
            match incoming.recv_timeout(left) {
                Ok(Event::Forwarded) => break Ok(()),
                Ok(Event::FramesEnded(Some(e))) => break Err(ExportError::FramesEnded(e)),
                Ok(Event::FramesEnded(None)) => break Ok(()),
                // Served once the export is announced.
                Ok(event) => early.push(event),
                Err(_) => break Err(ExportError::FirstFrame(timeout)),
            }
        };
        for event in early {
            self.on_event(event);
        }
        result
    }

    /// Serves until `stop`, or the frame thread ends (the server is gone).
    fn serve(&mut self, incoming: &Receiver<Event>, stop: &AtomicBool) -> Result<(), ExportError> {
        while !stop.load(Ordering::Relaxed) {
            if Instant::now() >= self.next_sensor_scan {
                self.next_sensor_scan = Instant::now() + Duration::from_secs(1);
                self.follow_sensors();
            }
            // The one wait point.
            match incoming.recv_timeout(self.wait()) {
                Ok(Event::FramesEnded(None)) => return Ok(()),
                Ok(Event::FramesEnded(Some(e))) => return Err(ExportError::FramesEnded(e)),
                Ok(event) => {
                    self.idle = FIRST_LOOK;
                    self.on_event(event);
                }
                Err(RecvTimeoutError::Timeout) => self.idle = (self.idle * 2).min(LAST_LOOK),
                Err(RecvTimeoutError::Disconnected) => return Ok(()),
            }
            self.on_answers();
        }
        Ok(())
    }

    /// How long the next wait may be: short while answers are awaited.
    fn wait(&self) -> Duration {
        let busy = self.tick.busy()
            || self.control.busy()
            || self.recorder.busy()
            || self.batch.busy()
            || self.sensors.busy()
            || self.lockstep.values().any(FixedRelay::busy)
            || !self.held.is_empty();
        if busy {
            self.idle
        } else {
            IDLE_WAIT
        }
    }

    fn on_event(&mut self, event: Event) {
        match event {
            Event::Query(query) => self.on_query(query),
            Event::Mirror(zid, true) => {
                info!(mirror = %zid, "a mirror joined");
                self.mirrors.insert(zid);
            }
            Event::Mirror(zid, false) => self.on_mirror_left(&zid),
            Event::Forwarded | Event::FramesEnded(_) => {}
        }
    }

    /// A query: a request forwarded to the server, or status JSON.
    fn on_query(&mut self, query: Query) {
        let key = query.key_expr().as_str().to_owned();
        if key == self.keys.status() || key == self.keys.settings() {
            self.answer_json(&query, key == self.keys.settings());
            return;
        }
        let Some(service) = Forwarded::ALL
            .into_iter()
            .find(|s| self.keys.rpc(*s) == key)
        else {
            self.dropped.note(&query, &Refusal::NoSuchService);
            return;
        };
        let Some(mirror) = mirror_of(&query) else {
            self.dropped.note(&query, &Refusal::NoMirror);
            return;
        };
        let bytes = query
            .payload()
            .map(|p| p.to_bytes().into_owned())
            .unwrap_or_default();
        match self.forward(service, mirror, &bytes, query) {
            // An idle (paced or waiting) server answers at once.
            Ok(()) => {
                if let Err(e) = self.wake.notify() {
                    tracing::debug!("wake-up not delivered: {e:?}");
                }
            }
            Err(refused) => {
                let (query, why) = *refused;
                self.dropped.note(&query, &why);
            }
        }
    }

    /// Sends a request from `mirror` to the server's `service`.
    fn forward(
        &mut self,
        service: Forwarded,
        mirror: String,
        bytes: &[u8],
        query: Query,
    ) -> Result<(), Refused> {
        match service {
            Forwarded::Control => {
                match FixedRelay::<ControlRequest, ControlResponse>::decode(bytes) {
                    Ok(request) => self.control.send(request, query),
                    Err(e) => Err(relay::malformed(query, "control request", e)),
                }
            }
            Forwarded::Recorder => {
                match FixedRelay::<RecorderRequest, RecorderResponse>::decode(bytes) {
                    Ok(request) => self.recorder.send(request, query),
                    Err(e) => Err(relay::malformed(query, "recorder request", e)),
                }
            }
            Forwarded::Batch => self.batch.forward(bytes, query),
            Forwarded::Sensors => self.sensors.forward(bytes, query),
            Forwarded::Lockstep => match LockstepRelay::decode(bytes) {
                Ok(request) => match self.lockstep_port(mirror, request.pid) {
                    Ok(port) => port.send(request, query),
                    Err(e) => Err(relay::refused(query, Refusal::NoLockstepPort(e))),
                },
                Err(e) => Err(relay::malformed(query, "lockstep request", e)),
            },
            Forwarded::Tick => match TickRelay::decode(bytes) {
                Ok(request) => self.tickers.forward(
                    request,
                    mirror,
                    query,
                    &mut self.tick,
                    &self.shared.forwarded,
                ),
                Err(e) => Err(relay::malformed(query, "tick request", e)),
            },
        }
    }

    /// The lockstep port of the remote participant `pid` of `mirror`.
    fn lockstep_port(
        &mut self,
        mirror: String,
        pid: u32,
    ) -> Result<&mut LockstepRelay, LocalError> {
        match self.lockstep.entry((mirror, pid)) {
            std::collections::hash_map::Entry::Occupied(e) => Ok(e.into_mut()),
            std::collections::hash_map::Entry::Vacant(e) => {
                FixedRelay::open(&self.node, &self.names.lockstep).map(|port| e.insert(port))
            }
        }
    }

    /// A mirror is gone: the ownership held for its ticker is released and
    /// its lockstep participants leave.
    fn on_mirror_left(&mut self, zid: &str) {
        info!(mirror = %zid, "a mirror left (its link dropped or it stopped)");
        self.mirrors.remove(zid);
        self.tickers.mirror_left(zid, &mut self.tick);
        let gone: Vec<_> = self
            .lockstep
            .keys()
            .filter(|(m, _)| m == zid)
            .cloned()
            .collect();
        for key in gone {
            if let Some(port) = self.lockstep.remove(&key) {
                ticker::leave_for(port, key.1);
            }
        }
    }

    /// Takes the server's answers that came and replies each whose frame
    /// is out.
    fn on_answers(&mut self) {
        let mut ticks = Vec::new();
        self.tick
            .poll(relay::tick_interim, relay::tick_frame, &mut ticks);
        for answer in ticks {
            // The server's word on who ticks now decides the remote owner.
            if let Ok(response) = wire::decode_fixed::<TickResponse>(&answer.bytes, "tick answer") {
                self.tickers.answered(&response);
            }
            self.held.push(answer);
        }
        self.control.poll(|_| false, |_| None, &mut self.held);
        self.recorder.poll(|_| false, |_| None, &mut self.held);
        self.batch.poll(&mut self.held);
        let before = self.held.len();
        self.sensors.poll(&mut self.held);
        if self.held.len() > before {
            // A sensor may have been spawned: its captures are forwarded
            // from before the answer goes, so none is missed.
            self.follow_sensors();
        }
        for port in self.lockstep.values_mut() {
            port.poll(|_| false, |_| None, &mut self.held);
        }
        // A tick's answer goes once its frame is on Zenoh, so a remote
        // reader that sees the answer finds the frame.
        let out = self.shared.forwarded.load(Ordering::Acquire);
        self.held.retain(|answer| {
            if answer.frame.is_some_and(|frame| frame > out) {
                return true;
            }
            relay::reply(&answer.query, &answer.bytes);
            false
        });
    }

    /// Has the frame thread forward every sensor not yet forwarded.
    fn follow_sensors(&mut self) {
        follow_sensors(
            &self.client,
            self.timeout,
            &mut self.following,
            &self.follow,
        );
    }

    /// Answers a status or settings query with JSON.
    fn answer_json(&self, query: &Query, settings_only: bool) {
        let text = match self.client.status() {
            Ok(status) if settings_only => {
                serde_json::to_string(&(self.json.settings)(&status.settings))
            }
            Ok(status) => serde_json::to_string(&(self.json.status)(self.client.world(), &status)),
            Err(e) => {
                relay::refuse(query, &e.to_string());
                return;
            }
        };
        match text {
            Ok(text) => relay::reply(query, text.as_bytes()),
            Err(e) => relay::refuse(query, &e.to_string()),
        }
    }

    /// The export ends: the ownership held for a remote ticker goes back.
    fn finish(&mut self) {
        self.tickers.release(&mut self.tick);
        info!(dropped = self.dropped.count, "export ended");
    }
}

impl std::fmt::Debug for Exporter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Exporter")
            .field("world", self.client.world())
            .field("mirrors", &self.mirrors)
            .field("held", &self.held.len())
            .finish()
    }
}
