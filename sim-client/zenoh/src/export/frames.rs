//! The exporter's frame thread: every frame published on Zenoh (and its
//! time on `clock`), each after the captures of its frame, as the server
//! publishes them, so a remote reader that sees frame N finds its
//! captures; and the sensors it follows, which the main thread names.

use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{self, Receiver, Sender};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use shared_types::WorldName;
use sim_client::{Capture, Client, FrameView, WaitError};
use tracing::{info, warn};
use zenoh::pubsub::Publisher;
use zenoh::qos::CongestionControl;
use zenoh::{Session, Wait as _};

use crate::error::FramesError;
use crate::wire::{self, BridgeKeys};

/// A sensor the frame thread is to forward, and whom to tell once it reads.
pub(super) struct Follow {
    id: u64,
    reading: Sender<()>,
}

/// One forwarded sensor: its reader and its publisher.
struct Forwarding {
    sensor: sim_client::Sensor,
    publisher: Publisher<'static>,
}

/// What the frame thread shares with the main thread.
#[derive(Debug, Default)]
pub(super) struct Shared {
    /// The last frame published, as sent (for the `frames/latest` query).
    pub latest: Mutex<Vec<u8>>,
    /// The number of the last frame published.
    pub forwarded: AtomicU64,
}

/// The frame thread: publishes every frame on Zenoh (and its time on
/// `clock`), each after the captures of its frame, as the server
/// publishes them, so a remote reader that sees frame N finds its
/// captures. Its one wait point is the wait for the next frame.
pub(super) struct FrameForwarder<'a> {
    client: Client,
    session: &'a Session,
    keys: &'a BridgeKeys,
    frames: Publisher<'static>,
    clock: Option<Publisher<'static>>,
    sensors: HashMap<u64, Forwarding>,
    shared: Arc<Shared>,
    bytes: Vec<u8>,
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
    /// Connects to `world` and declares the frame (and clock) publishers.
    pub(super) fn new(
        world: &WorldName,
        timeout: Duration,
        session: &'a Session,
        keys: &'a BridgeKeys,
        ros2_clock: bool,
        shared: Arc<Shared>,
    ) -> Result<Self, FramesError> {
        let client = Client::connect(world.as_str(), timeout)?;
        let frames = express(session, keys.frames())?;
        let clock = if ros2_clock {
            Some(express(session, wire::ROS2_CLOCK_KEY.to_owned())?)
        } else {
            None
        };
        Ok(Self {
            client,
            session,
            keys,
            frames,
            clock,
            sensors: HashMap::new(),
            shared,
            bytes: Vec::new(),
        })
    }

    /// Forwards frames until `stopping` says so or the server is gone;
    /// `forwarded_one` is told of each frame out.
    pub(super) fn run(
        mut self,
        follow: &Receiver<Follow>,
        stopping: impl Fn() -> bool,
        forwarded_one: impl Fn(),
    ) -> Result<(), FramesError> {
        while !stopping() {
            while let Ok(request) = follow.try_recv() {
                self.on_follow(request)?;
            }
            match self.client.wait_for_frame(Duration::from_millis(100)) {
                Ok(frame) => {
                    self.on_frame(frame)?;
                    forwarded_one();
                }
                Err(WaitError::Timeout { .. }) => {}
                Err(e) => return Err(e.into()),
            }
        }
        Ok(())
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
        let bytes = &mut self.bytes;
        self.sensors.retain(|id, forwarding| loop {
            match forwarding.sensor.try_recv() {
                Ok(Some(capture)) => {
                    if !forward_capture(*id, capture, &forwarding.publisher, bytes) {
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
        self.bytes.clear();
        wire::encode_frame(frame.header(), frame.actors(), &mut self.bytes);
        let (number, elapsed_ns) = (frame.frame(), frame.timestamp().elapsed_ns);
        drop(frame);
        self.frames
            .put(self.bytes.as_slice())
            .wait()
            .map_err(FramesError::zenoh("publishing a frame"))?;
        if let Some(clock) = &self.clock {
            clock
                .put(wire::ros2_clock_cdr(elapsed_ns).as_slice())
                .wait()
                .map_err(FramesError::zenoh("publishing the clock"))?;
        }
        if let Ok(mut latest) = self.shared.latest.lock() {
            latest.clone_from(&self.bytes);
        }
        self.shared.forwarded.store(number, Ordering::Release);
        Ok(())
    }
}

/// Publishes a capture of sensor `id`; `false` once it was the sensor's
/// last.
fn forward_capture(
    id: u64,
    capture: Capture,
    publisher: &Publisher<'_>,
    bytes: &mut Vec<u8>,
) -> bool {
    bytes.clear();
    wire::encode_capture(capture.header(), capture.bytes(), bytes);
    let ended = capture.header().end().is_some();
    drop(capture);
    if let Err(e) = publisher.put(bytes.as_slice()).wait() {
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
    follow: &Sender<Follow>,
) {
    let Ok(list) = client.list_sensors() else {
        return;
    };
    let listed: BTreeSet<u64> = list.iter().map(|info| info.id).collect();
    following.retain(|id| listed.contains(id));
    for id in listed {
        if following.insert(id) {
            let (reading, read) = mpsc::channel();
            if follow.send(Follow { id, reading }).is_ok() {
                let _ = read.recv_timeout(timeout);
            }
        }
    }
}
