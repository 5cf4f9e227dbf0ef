//! The exporter's frame thread: every frame published on Zenoh (and its
//! time on `clock`), each after the captures of its frame, as the server
//! publishes them, so a remote reader that sees frame N finds its
//! captures; and the sensors it follows, which the main thread names.

use std::collections::{BTreeSet, HashMap};
use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::mpsc::{self, Sender};
use std::sync::Mutex;
use std::time::Duration;

use shared_types::bridge::{self, BridgeKeys};
use shared_types::WorldName;
use sim_client::{Client, WaitError};
use tracing::{info, warn};
use zenoh::qos::CongestionControl;
use zenoh::{Session, Wait as _};

/// A sensor the frame thread is to forward, and whom to tell once it reads.
pub(super) struct Follow {
    id: u64,
    reading: Sender<()>,
}

/// One forwarded sensor: its reader and its publisher.
struct Forwarding {
    sensor: sim_client::Sensor,
    publisher: zenoh::pubsub::Publisher<'static>,
}

/// Publishes every frame on Zenoh (and its time on `clock`), each after
/// the captures of its frame, as the server publishes them: a remote
/// reader that sees frame N finds its captures. Until the server is gone
/// or `stop`.
#[allow(clippy::too_many_arguments)]
pub(super) fn forward_frames(
    world: &WorldName,
    timeout: Duration,
    session: &Session,
    keys: &BridgeKeys,
    latest: &Mutex<Vec<u8>>,
    ros2_clock: bool,
    forwarded: &AtomicU64,
    forwarded_one: &dyn Fn(),
    follow: &mpsc::Receiver<Follow>,
    stop: &AtomicBool,
) -> anyhow::Result<()> {
    let zenoh = |e: zenoh::Error| anyhow::anyhow!("{e}");
    let mut client = Client::connect(world.as_str(), timeout)?;
    // Express: each message leaves at once, in order, none batched.
    let publisher = |key: String| {
        session
            .declare_publisher(key)
            .congestion_control(CongestionControl::Block)
            .express(true)
            .wait()
            .map_err(zenoh)
    };
    let frames = publisher(keys.frames())?;
    let clock = publisher(bridge::ROS2_CLOCK_KEY.to_owned())?;
    let mut sensors: HashMap<u64, Forwarding> = HashMap::new();
    let mut bytes = Vec::new();
    while !stop.load(Ordering::Relaxed) {
        while let Ok(Follow { id, reading }) = follow.try_recv() {
            match client.sensor(id) {
                Ok(sensor) => {
                    sensors.insert(
                        id,
                        Forwarding {
                            sensor,
                            publisher: publisher(keys.sensor(id))?,
                        },
                    );
                }
                Err(e) => info!(sensor = id, "not forwarded: {e}"),
            }
            let _ = reading.send(());
        }
        let frame = match client.wait_for_frame(Duration::from_millis(100)) {
            Ok(frame) => frame,
            Err(WaitError::Timeout { .. }) => continue,
            Err(e) => return Err(e.into()),
        };
        // The frame's captures first (the server published them before it).
        sensors.retain(|id, forwarding| loop {
            let capture = match forwarding.sensor.try_recv() {
                Ok(Some(capture)) => capture,
                Ok(None) => return true,
                Err(e) => {
                    info!(sensor = id, "stopped forwarding captures: {e}");
                    return false;
                }
            };
            bytes.clear();
            bridge::encode_capture(capture.header(), capture.bytes(), &mut bytes);
            let ended = capture.header().end().is_some();
            drop(capture);
            if let Err(e) = forwarding.publisher.put(bytes.as_slice()).wait() {
                warn!(sensor = id, "capture not published: {e}");
            }
            if ended {
                return false;
            }
        });
        bytes.clear();
        bridge::encode_frame(frame.header(), frame.actors(), &mut bytes);
        let (number, elapsed_ns) = (frame.frame(), frame.timestamp().elapsed_ns);
        drop(frame);
        frames.put(bytes.as_slice()).wait().map_err(zenoh)?;
        if ros2_clock {
            clock
                .put(bridge::ros2_clock_cdr(elapsed_ns).as_slice())
                .wait()
                .map_err(zenoh)?;
        }
        if let Ok(mut latest) = latest.lock() {
            latest.clone_from(&bytes);
        }
        forwarded.store(number, Ordering::Release);
        forwarded_one();
    }
    Ok(())
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
