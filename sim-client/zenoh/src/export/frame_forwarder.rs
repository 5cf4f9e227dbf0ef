//! The exporter's frame thread: every frame published on Zenoh (and its
//! time on `clock`), each after the captures of its frame, as the server
//! publishes them, so a remote reader that sees frame N finds its
//! captures; and the sensors it follows, which the main thread names.
//! It also forwards the tick service ([`Ticks`]): a remote tick is sent
//! to the server from here and its answer replied from here right after
//! its frame, no other thread in between. It waits on the world's
//! frame-ready event, which the server rings after every frame and after
//! answering requests, and which the Zenoh callback of a tick query rings
//! too; it tells the main thread of a ring only while the main thread
//! awaits answers.

use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicBool, AtomicUsize, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use iceoryx2::node::Node;
use iceoryx2::port::listener::Listener;
use shared_types::{ServiceNames, WorldName};
use sim_client::{Capture, Client, FrameView, WaitError};
use simbus_transport::stamps::{self, Stage};
use simbus_transport::{hybrid, Bus};
use tracing::{info, warn};
use zenoh::bytes::ZBytes;
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::query::Query;
use zenoh::{Session, Wait as _};

use super::events::Event;
use super::ticker::RemoteTicker;
use super::ticks::Ticks;
use crate::error::{FramesError, LocalError};
use crate::ports;
use crate::wire::{self, BridgeKeys};

/// How soon the frame thread notices that the server died (or that it is
/// to stop) while the server rings nothing.
const LIVENESS: Duration = Duration::from_millis(100);

/// A sensor the frame thread is to forward, and whom to tell once it reads.
pub(super) struct Follow {
    id: u64,
    reading: Sender<()>,
}

/// What the frame thread is asked to do, besides forwarding frames.
pub(super) enum Order {
    /// Forward a sensor's captures.
    Follow(Follow),
    /// A remote tick request (the Zenoh callback that sends it rings the
    /// frame-ready event).
    Tick(Query),
    /// A mirror's tick publication (rung likewise).
    TickPut(ZBytes),
    /// A mirror is gone: release the ownership held for its ticker.
    MirrorLeft(String),
}

/// One forwarded sensor: its reader and its publisher.
struct Forwarding {
    sensor: sim_client::Sensor,
    publisher: Publisher<'static>,
}

/// What the frame thread shares with the main thread and Zenoh's
/// callbacks.
#[derive(Debug, Default)]
pub(super) struct Shared {
    /// The last frame published, as sent (for the `frames/latest` query):
    /// the very payload handed to Zenoh, shared, not a copy.
    pub latest: Mutex<ZBytes>,
    /// Requests the main thread sent and awaits answers to: while none,
    /// a ring is not worth waking it for. Raised before a request is sent.
    pub awaiting: AtomicUsize,
}

/// The frame thread: publishes every frame on Zenoh (and its time on
/// `clock`), each after the captures of its frame, as the server
/// publishes them, so a remote reader that sees frame N finds its
/// captures. Its one wait point is the frame-ready event.
pub(super) struct FrameForwarder<'a> {
    client: Client,
    /// Rung by the server after every frame and after answering requests;
    /// on its own node, declared before it so it goes first.
    ready: Listener<Bus>,
    /// The tick service's port, on the same node.
    ticks: Ticks,
    _node: Node<Bus>,
    session: &'a Session,
    keys: &'a BridgeKeys,
    frames: Publisher<'static>,
    clock: Option<Publisher<'static>>,
    sensors: HashMap<u64, Forwarding>,
    shared: Arc<Shared>,
    /// The number of the last frame published.
    forwarded: u64,
    /// Whether the main thread heard of the first frame.
    told_first: bool,
    /// How long a ring is looked for while a tick is with the server.
    poll_window: Duration,
}

/// A publisher that sends each message at once, in order, none batched.
fn express(session: &Session, key: String) -> Result<Publisher<'static>, FramesError> {
    session
        .declare_publisher(key)
        .congestion_control(CongestionControl::Block)
        .express(true)
        .wait()
        .map_err(FramesError::zenoh("declaring a publisher"))
}

impl<'a> FrameForwarder<'a> {
    /// Connects to `world` and declares the frame (and clock, with
    /// `ros2_clock`) publishers; `poll` is the bridge's poll window.
    pub(super) fn new(
        world: &WorldName,
        timeout: Duration,
        session: &'a Session,
        keys: &'a BridgeKeys,
        (ros2_clock, poll): (bool, Duration),
        shared: Arc<Shared>,
    ) -> Result<Self, FramesError> {
        let client = Client::connect(world.as_str(), timeout)?;
        let node = ports::node("sim-client")?;
        let specs = ports::specs(&ServiceNames::new(world))?;
        let ticks = Ticks::open(&node, &specs, express(session, keys.tick_answers())?)?;
        let ready = specs
            .frame_ready
            .open(&node)
            .map_err(|e| LocalError::transport("frame-ready event", e))?
            .listener_builder()
            .create()
            .map_err(|e| LocalError::transport("frame-ready listener", e))?;
        let frames = express(session, keys.frames())?;
        let clock = if ros2_clock {
            Some(express(session, wire::ROS2_CLOCK_KEY.to_owned())?)
        } else {
            None
        };
        Ok(Self {
            client,
            ready,
            ticks,
            _node: node,
            session,
            keys,
            frames,
            clock,
            sensors: HashMap::new(),
            shared,
            forwarded: 0,
            told_first: false,
            poll_window: poll,
        })
    }

    /// Forwards frames and ticks until `stopping` says so or the server
    /// is gone, then releases the ownership held for a remote ticker;
    /// `tell` hears of the first frame ([`Event::Forwarded`]) and then of
    /// every ring while the main thread awaits answers. When the server is
    /// gone, the remote ticker that owned the world comes back with the
    /// error, to claim it again from a resumed server.
    pub(super) fn run(
        mut self,
        orders: &Receiver<Order>,
        stopping: impl Fn() -> bool,
        tell: impl Fn(Event),
    ) -> (Result<(), FramesError>, Option<RemoteTicker>) {
        let result = self.serve(orders, stopping, tell);
        let owner = match &result {
            Err(FramesError::Wait(WaitError::ServerGone { .. })) => self.ticks.take_owner(),
            _ => None,
        };
        self.ticks.finish();
        (result, owner)
    }

    /// Claims the world again for `owner`, the remote ticker that held it
    /// when the previous server exited.
    pub(super) fn claim_again(&mut self, owner: RemoteTicker) {
        self.ticks.claim_again(owner);
    }

    fn serve(
        &mut self,
        orders: &Receiver<Order>,
        stopping: impl Fn() -> bool,
        tell: impl Fn(Event),
    ) -> Result<(), FramesError> {
        // The current frame is there without a ring.
        let mut rang = true;
        while !stopping() {
            while let Ok(order) = orders.try_recv() {
                match order {
                    Order::Follow(request) => self.on_follow(request)?,
                    Order::Tick(query) => self.ticks.on_query(query, self.forwarded),
                    Order::TickPut(bytes) => self.ticks.on_put(&bytes, self.forwarded),
                    Order::MirrorLeft(zid) => self.ticks.mirror_left(&zid),
                }
            }
            if rang {
                // The tick answers first: each rides on its frame.
                self.ticks.take();
                let forwarded = self.on_ring()?;
                // The tick's reply right after its frame, from here.
                self.ticks.reply_due(self.forwarded);
                if !self.told_first && forwarded {
                    self.told_first = true;
                    tell(Event::Forwarded);
                } else if self.shared.awaiting.load(Ordering::SeqCst) > 0 {
                    tell(Event::Answered);
                }
            } else {
                self.check_server()?;
            }
            rang = self.wait()?;
        }
        Ok(())
    }

    /// The one wait point: whether the server rang within [`LIVENESS`].
    /// While a tick is with the server, its ring is looked for, yielding,
    /// for the bridge's poll window before the thread sleeps: the default
    /// wait of a local ticker, and a wake-up fewer per remote tick.
    fn wait(&self) -> Result<bool, FramesError> {
        let poll_for = if self.ticks.awaiting_server() {
            self.poll_window
        } else {
            Duration::ZERO
        };
        hybrid::wait(&self.ready, poll_for, LIVENESS)
            .map_err(|e| LocalError::transport("frame-ready wait", e).into())
    }

    /// Publishes every frame queued; whether there was one.
    fn on_ring(&mut self) -> Result<bool, FramesError> {
        let mut forwarded = false;
        loop {
            match self.client.wait_for_frame(Duration::ZERO) {
                Ok(frame) => {
                    self.on_frame(frame)?;
                    forwarded = true;
                }
                Err(WaitError::Timeout { .. }) => return Ok(forwarded),
                Err(e) => return Err(e.into()),
            }
        }
    }

    /// The server rang nothing for a while: is it still there?
    fn check_server(&self) -> Result<(), FramesError> {
        let pid = self.client.server_pid();
        if pid == 0 || sim_client::process_alive(pid) {
            return Ok(());
        }
        Err(WaitError::ServerGone {
            world: self.client.world().to_string(),
            pid,
        }
        .into())
    }

    /// Starts forwarding sensor `id`'s captures.
    fn on_follow(&mut self, Follow { id, reading }: Follow) -> Result<(), FramesError> {
        match self.client.sensor(id) {
            Ok(sensor) => {
                let publisher = express(self.session, self.keys.sensor(id))?;
                self.sensors.insert(id, Forwarding { sensor, publisher });
            }
            Err(e) => info!(sensor = id, "not forwarded: {e}"),
        }
        let _ = reading.send(());
        Ok(())
    }

    /// Publishes the frame's captures, then the frame and its time.
    fn on_frame(&mut self, frame: FrameView) -> Result<(), FramesError> {
        // The frame's captures first (the server published them before it).
        self.sensors.retain(|id, forwarding| loop {
            match forwarding.sensor.try_recv() {
                Ok(Some(capture)) => {
                    if !forward_capture(*id, capture, &forwarding.publisher) {
                        return false;
                    }
                }
                Ok(None) => return true,
                Err(e) => {
                    info!(sensor = id, "stopped forwarding captures: {e}");
                    return false;
                }
            }
        });
        // The one copy out of shared memory: into the buffer Zenoh sends
        // and `frames/latest` keeps (a new one each frame, as both hold
        // the last).
        let mut bytes = Vec::with_capacity(wire::frame_len(frame.actors().len()));
        wire::encode_frame(frame.header(), frame.actors(), &mut bytes);
        let (number, elapsed_ns) = (frame.frame(), frame.timestamp().elapsed_ns);
        drop(frame);
        let bytes = ZBytes::from(bytes);
        self.frames
            .put(bytes.clone())
            .attachment(self.ticks.attachment(number))
            .wait()
            .map_err(FramesError::zenoh("publishing a frame"))?;
        stamps::stamp(Stage::ExportPuts, number);
        stamps::expect(number + 1);
        if let Some(clock) = &self.clock {
            clock
                .put(wire::ros2_clock_cdr(elapsed_ns).as_slice())
                .wait()
                .map_err(FramesError::zenoh("publishing the clock"))?;
        }
        if let Ok(mut latest) = self.shared.latest.lock() {
            *latest = bytes;
        }
        self.forwarded = number;
        Ok(())
    }
}

/// Publishes a capture of sensor `id`; `false` once it was the sensor's
/// last.
fn forward_capture(id: u64, capture: Capture, publisher: &Publisher<'_>) -> bool {
    // The one copy out of shared memory, into the buffer Zenoh sends.
    let mut bytes = Vec::with_capacity(wire::capture_len(capture.bytes().len()));
    wire::encode_capture(capture.header(), capture.bytes(), &mut bytes);
    let ended = capture.header().end().is_some();
    drop(capture);
    if let Err(e) = publisher.put(bytes).wait() {
        warn!(sensor = id, "capture not published: {e}");
    }
    !ended
}

/// Whether `stop` or `done` is set.
pub(super) fn either(stop: &AtomicBool, done: &AtomicBool) -> bool {
    stop.load(Ordering::Relaxed) || done.load(Ordering::Relaxed)
}

/// Has the frame thread forward every sensor not yet forwarded, and waits
/// until it reads each (so a capture right after is forwarded).
pub(super) fn follow_sensors(
    client: &Client,
    timeout: Duration,
    following: &mut BTreeSet<u64>,
    follow: &Sender<Order>,
) {
    let Ok(list) = client.list_sensors() else {
        return;
    };
    let listed: BTreeSet<u64> = list.iter().map(|info| info.id).collect();
    following.retain(|id| listed.contains(id));
    for id in listed {
        if following.insert(id) {
            let (reading, read) = mpsc::channel();
            if follow.send(Order::Follow(Follow { id, reading })).is_ok() {
                let _ = read.recv_timeout(timeout);
            }
        }
    }
}
