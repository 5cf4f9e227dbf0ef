//! The exporting bridge, on the server's host: the world's frames and
//! captures published on Zenoh, its request services answered as Zenoh
//! queryables through ordinary simbus ports, tick ownership held for a
//! remote ticker and released when its mirror goes.
//!
//! Threads: one forwards frames (and `/clock`), the captures of every
//! sensor and the tick service (`frames.rs`); it owns its simbus ports
//! and waits on the world's frame-ready event, which the server rings
//! after every frame and after answering the requests clients announced,
//! and which Zenoh's callback rings after handing it a tick (`ticks.rs`).
//! A tick's answer goes from that thread attached to its frame's
//! publication: the mirrored tick's path has no other thread of the
//! exporter in it. The
//! main thread, an [`Exporter`], owns the other request ports; its one
//! wait point is one channel, fed by Zenoh's callbacks and by the frame
//! thread, which tells it of a ring while it awaits answers. The
//! channel's only timed wait is the deadline of the next look at the
//! server's sensors.

mod declare;
mod events;
mod follow;
mod frame_forwarder;
mod relay;
mod ticker;
mod ticks;

pub(crate) use self::follow::run;

use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::mpsc::{self, Receiver, RecvTimeoutError, Sender};
use std::sync::Arc;
use std::time::{Duration, Instant};

use iceoryx2::node::Node;
use iceoryx2::port::notifier::Notifier;
use shared_types::{
    ControlRequest, ControlResponse, RecorderRequest, RecorderResponse, ServiceNames,
};
use sim_client::Client;
use simbus_transport::spec::WorldServices;
use simbus_transport::Bus;
use tracing::info;
use zenoh::query::Query;

use self::declare::{declare, Routes};
use self::events::Event;
use self::frame_forwarder::{follow_sensors, FrameForwarder, Order, Shared};
use self::relay::{
    mirror_of, Answer, BatchRelay, Dropped, FixedRelay, Refusal, Refused, SensorRelay,
};
use self::ticker::LockstepRelay;
use self::ticker::RemoteTicker;
use crate::error::{ExportError, FramesError, LocalError};
use crate::ports;
use crate::side::{JsonViews, Notice, Side};
use crate::wire::{BridgeKeys, Forwarded};

/// How often the server's sensors are looked at, for sensors spawned by
/// clients on its host (those spawned from other hosts are followed as
/// their answer goes back).
const SENSOR_SCAN_PERIOD: Duration = Duration::from_secs(1);

/// Sets its flag when dropped (also when unwinding), so the frame thread
/// stops before its scope is left.
struct SetOnDrop<'a>(&'a AtomicBool);

impl Drop for SetOnDrop<'_> {
    fn drop(&mut self) {
        self.0.store(true, Ordering::Relaxed);
    }
}

/// How one export of a server ended.
enum Ended {
    /// `stop` was set, or the export failed.
    Done(Result<(), ExportError>),
    /// The server exited.
    ServerGone {
        error: ExportError,
        server_pid: u32,
        run_pid: u32,
        /// The remote ticker that owned the world then.
        owner: Option<RemoteTicker>,
    },
}

/// Exports the server `client` is connected to until `stop` or the
/// server is gone, claiming the world first for `claim_for` (the remote
/// ticker that owned it when the previous server exited). The first
/// export says so ([`Notice::Exporting`]).
fn export_once(
    side: &mut Side<'_>,
    mut client: Client,
    claim_for: Option<RemoteTicker>,
    first: bool,
) -> Ended {
    client.set_request_timeout(side.timeout);
    let status = match client.status() {
        Ok(status) => status,
        Err(e) => return Ended::Done(Err(e.into())),
    };
    let (server_pid, run_pid) = (status.server_pid, status.run_pid);
    let mut owner = None;
    let result = export_server(side, client, &status, claim_for, first, &mut owner);
    match result {
        Err(ExportError::FramesEnded(e)) if is_server_gone(&e) => Ended::ServerGone {
            error: ExportError::FramesEnded(e),
            server_pid,
            run_pid,
            owner,
        },
        result => Ended::Done(result),
    }
}

/// Whether the frame thread ended because the server is gone.
fn is_server_gone(e: &FramesError) -> bool {
    matches!(
        e,
        FramesError::Wait(sim_client::WaitError::ServerGone { .. })
    )
}

fn export_server(
    side: &mut Side<'_>,
    client: Client,
    status: &sim_client::Status,
    claim_for: Option<RemoteTicker>,
    first: bool,
    owner: &mut Option<RemoteTicker>,
) -> Result<(), ExportError> {
    let keys = BridgeKeys::new(side.world);
    let (events, incoming) = mpsc::channel::<Event>();
    let shared = Arc::new(Shared::default());
    let (orders, ordered) = mpsc::channel::<Order>();
    let names = ServiceNames::new(side.world);
    let routes = Routes {
        events: &events,
        orders: &orders,
        names: &names,
        shared: &shared,
    };
    let _declared = declare(&side.session, &keys, routes)?;
    let done = AtomicBool::new(false);
    let (world, timeout, stop) = (side.world, side.timeout, side.stop);
    let (ros2_clock, poll) = (side.options.ros2_clock, side.options.poll);
    std::thread::scope(|scope| {
        let _stop_frames = SetOnDrop(&done);
        let (session, keys, forwarded, done) = (&side.session, &keys, shared.clone(), &done);
        let to_main = events.clone();
        let frames = std::thread::Builder::new()
            .name("frames".into())
            .spawn_scoped(scope, move || {
                let mut owner = None;
                let ended = FrameForwarder::new(
                    world,
                    timeout,
                    session,
                    keys,
                    (ros2_clock, poll),
                    forwarded,
                )
                .and_then(|mut forwarder| {
                    if let Some(claim_for) = claim_for {
                        forwarder.claim_again(claim_for);
                    }
                    let (ended, held) = forwarder.run(
                        &ordered,
                        || frame_forwarder::either(stop, done),
                        |event| {
                            let _ = to_main.send(event);
                        },
                    );
                    owner = held;
                    ended
                });
                let _ = to_main.send(Event::FramesEnded(ended.err()));
                owner
            })
            .map_err(ExportError::Thread)?;
        let mut exporter = Exporter::open(
            client,
            side.timeout,
            side.options.json,
            shared.clone(),
            orders,
        )?;
        exporter.await_first_frame(&incoming, side.timeout)?;
        if first {
            (side.notice)(Notice::Exporting {
                world: side.world.clone(),
                endpoint: side.endpoint.to_owned(),
                server_pid: status.server_pid,
                frame: status.frame,
            });
        }
        info!(world = %side.world, zid = %session.zid(), "exporting");
        let result = exporter.serve(&incoming, side.stop);
        exporter.finish();
        drop(exporter);
        done.store(true, Ordering::Relaxed);
        if let Ok(held) = frames.join() {
            *owner = held;
        }
        result
    })
}

/// The exporter's main thread: the world's request services answered for
/// queries from other hosts, and the remote ticker's ownership.
struct Exporter {
    client: Client,
    timeout: Duration,
    specs: WorldServices,
    keys: BridgeKeys,
    json: JsonViews,
    shared: Arc<Shared>,
    control: FixedRelay<ControlRequest, ControlResponse>,
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
    mirrors: BTreeSet<String>,
    /// Sensors the frame thread forwards; how to ask it for more, and to
    /// forward a tick or release a lost mirror's ownership.
    following: BTreeSet<u64>,
    orders: Sender<Order>,
    next_sensor_scan: Instant,
    /// Answers taken from the ports, replied at once.
    answers: Vec<Answer>,
    dropped: Dropped,
}

impl Exporter {
    /// Opens the request ports of the world `client` is connected to.
    fn open(
        client: Client,
        timeout: Duration,
        json: JsonViews,
        shared: Arc<Shared>,
        orders: Sender<Order>,
    ) -> Result<Self, LocalError> {
        let specs = ports::specs(&ServiceNames::new(client.world()))?;
        let node = ports::node("sim-client")?;
        Ok(Self {
            control: FixedRelay::open(&node, &specs.control)?,
            recorder: FixedRelay::open(&node, &specs.recorder)?,
            batch: BatchRelay::open(&node, &specs.batch)?,
            sensors: SensorRelay::open(&node, &specs.sensors)?,
            wake: ports::wake_notifier_on(&node, &specs)?,
            node,
            lockstep: HashMap::new(),
            keys: BridgeKeys::new(client.world()),
            specs,
            client,
            timeout,
            json,
            shared,
            mirrors: BTreeSet::new(),
            following: BTreeSet::new(),
            orders,
            next_sensor_scan: Instant::now(),
            answers: Vec::new(),
            dropped: Dropped::default(),
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

    /// Serves until `stop`, or the frame thread ends (the server is gone,
    /// or it saw `stop`).
    fn serve(&mut self, incoming: &Receiver<Event>, stop: &AtomicBool) -> Result<(), ExportError> {
        while !stop.load(Ordering::Relaxed) {
            if Instant::now() >= self.next_sensor_scan {
                self.on_sensor_scan();
            }
            // The one wait point: an event, or the next sensor scan's deadline.
            let left = self
                .next_sensor_scan
                .saturating_duration_since(Instant::now());
            match incoming.recv_timeout(left) {
                Ok(Event::FramesEnded(None)) => return Ok(()),
                Ok(Event::FramesEnded(Some(e))) => return Err(ExportError::FramesEnded(e)),
                Ok(event) => self.on_event(event),
                Err(RecvTimeoutError::Timeout) => {}
                Err(RecvTimeoutError::Disconnected) => return Ok(()),
            }
        }
        Ok(())
    }

    fn on_event(&mut self, event: Event) {
        match event {
            Event::Query(query) => self.on_query(query),
            Event::Mirror(zid, true) => {
                info!(mirror = %zid, "a mirror joined");
                self.mirrors.insert(zid);
            }
            Event::Mirror(zid, false) => self.on_mirror_left(&zid),
            Event::Forwarded | Event::Answered => self.on_answers(),
            Event::FramesEnded(_) => {}
        }
    }

    /// The periodic look at the server's sensors; requests that waited past
    /// their timeout are refused on the way.
    fn on_sensor_scan(&mut self) {
        self.next_sensor_scan = Instant::now() + SENSOR_SCAN_PERIOD;
        self.follow_sensors();
        self.on_answers();
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
        // Raised before the request goes, so the ring after its answer
        // reaches this thread.
        self.shared.awaiting.fetch_add(1, Ordering::SeqCst);
        let sent = self.forward(service, mirror, &bytes, query);
        self.dropped.settle(sent, &self.wake);
        self.shared
            .awaiting
            .store(self.in_flight(), Ordering::SeqCst);
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
            // Zenoh's callback hands ticks to the frame thread; one that
            // came here anyway goes there (seen at its next wake-up).
            Forwarded::Tick => {
                let _ = self.orders.send(Order::Tick(query));
                Ok(())
            }
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
                FixedRelay::open(&self.node, &self.specs.lockstep).map(|port| e.insert(port))
            }
        }
    }

    /// A mirror is gone: the ownership held for its ticker is released and
    /// its lockstep participants leave.
    fn on_mirror_left(&mut self, zid: &str) {
        info!(mirror = %zid, "a mirror left (its link dropped or it stopped)");
        self.mirrors.remove(zid);
        let _ = self.orders.send(Order::MirrorLeft(zid.to_owned()));
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

    /// The server rang: takes the answers that came and replies them.
    fn on_answers(&mut self) {
        self.control.poll(|_| false, |_| None, &mut self.answers);
        self.recorder.poll(|_| false, |_| None, &mut self.answers);
        self.batch.poll(&mut self.answers);
        let before = self.answers.len();
        self.sensors.poll(&mut self.answers);
        if self.answers.len() > before {
            // A sensor may have been spawned: its captures are forwarded
            // from before the answer goes, so none is missed.
            self.follow_sensors();
        }
        for port in self.lockstep.values_mut() {
            port.poll(|_| false, |_| None, &mut self.answers);
        }
        for answer in self.answers.drain(..) {
            relay::reply(&answer.query, answer.bytes);
        }
        self.shared
            .awaiting
            .store(self.in_flight(), Ordering::SeqCst);
    }

    /// Requests sent and not yet answered.
    fn in_flight(&self) -> usize {
        self.control.in_flight()
            + self.recorder.in_flight()
            + self.batch.in_flight()
            + self.sensors.in_flight()
            + self
                .lockstep
                .values()
                .map(FixedRelay::in_flight)
                .sum::<usize>()
    }

    /// Has the frame thread forward every sensor not yet forwarded.
    fn follow_sensors(&mut self) {
        follow_sensors(
            &self.client,
            self.timeout,
            &mut self.following,
            &self.orders,
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

    /// The export ends (the frame thread gives back the ownership held
    /// for a remote ticker).
    fn finish(&mut self) {
        info!(dropped = self.dropped.count, "export ended");
    }
}

impl std::fmt::Debug for Exporter {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Exporter")
            .field("world", self.client.world())
            .field("mirrors", &self.mirrors)
            .field("in_flight", &self.in_flight())
            .finish()
    }
}
