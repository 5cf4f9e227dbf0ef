//! CARLA's streaming side: clients connect, write the 4-byte id of the
//! stream they want, then read `[u32 length][message]` frames. The world
//! stream carries one world state per simbus frame, pumped from a frame
//! subscription of the gateway's own.

use std::collections::HashMap;
use std::io::{Read, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use shared_types::carla::{self, CarlaTransform};
use sim_client::{Client, FrameView};
use tracing::{debug, info, warn};

use super::convert;

/// How long a subscriber may take to accept one message before it is
/// dropped (a client that connects and never reads must not stall the rest).
const WRITE_TIMEOUT: Duration = Duration::from_secs(2);

/// The streams and who reads them.
#[derive(Debug, Default)]
pub(crate) struct Hub {
    subscribers: Mutex<HashMap<u32, Vec<TcpStream>>>,
    /// (episode, frame) of the last world state sent.
    pub(crate) last_frame: AtomicU64,
    pub(crate) last_episode: AtomicU64,
    /// The actors of the last frame: id → (kind, half extents in CARLA's axes).
    pub(crate) actors: Mutex<HashMap<u32, (u32, [f32; 3])>>,
}

impl Hub {
    /// Sends `message` to every reader of `stream`; a reader that fails is dropped.
    pub(crate) fn send(&self, stream: u32, message: &[u8]) {
        let mut subscribers = self.subscribers.lock().unwrap_or_else(|e| e.into_inner());
        let Some(readers) = subscribers.get_mut(&stream) else {
            return;
        };
        let length = (message.len() as u32).to_le_bytes();
        readers.retain_mut(|reader| {
            let sent = reader
                .write_all(&length)
                .and_then(|()| reader.write_all(message));
            if let Err(e) = &sent {
                debug!(stream, "stream reader dropped: {e}");
            }
            sent.is_ok()
        });
    }

    fn subscribe(&self, stream: u32, socket: TcpStream) {
        let mut subscribers = self.subscribers.lock().unwrap_or_else(|e| e.into_inner());
        subscribers.entry(stream).or_default().push(socket);
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

/// The world state of `frame` as CARLA's client reads it.
pub(crate) fn world_state(frame: &FrameView) -> Vec<u8> {
    let t = frame.timestamp();
    let actors = frame.actors();
    let mut out = Vec::with_capacity(
        carla::SENSOR_HEADER_LEN
            + carla::EPISODE_HEADER_LEN
            + actors.len() * carla::ACTOR_STATE_LEN,
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
        frame.episode(),
        t.platform_timestamp,
        t.delta_seconds() as f32,
    );
    for actor in actors {
        carla::actor_state(&mut out, &convert::actor(actor));
    }
    out
}

/// Streams every frame of `world` as a world state until the process ends;
/// reconnects when the server comes back.
pub(crate) fn pump(world: String, hub: Arc<Hub>) {
    loop {
        let mut client = match Client::connect(&world, Duration::from_secs(5)) {
            Ok(client) => client,
            Err(e) => {
                debug!("world stream waits for the server: {e}");
                std::thread::sleep(Duration::from_millis(200));
                continue;
            }
        };
        client.set_every_frame(true);
        info!(world, "streaming the world's frames to CARLA clients");
        loop {
            match client.wait_for_frame(Duration::from_secs(1)) {
                Ok(frame) => {
                    let message = world_state(&frame);
                    hub.last_episode.store(frame.episode(), Ordering::Relaxed);
                    let actors = frame
                        .actors()
                        .iter()
                        .map(|a| {
                            let id = u32::try_from(a.id).unwrap_or(u32::MAX);
                            (id, (a.kind, convert::vector(a.extent)))
                        })
                        .collect();
                    *hub.actors.lock().unwrap_or_else(|e| e.into_inner()) = actors;
                    hub.last_frame.store(frame.frame(), Ordering::Relaxed);
                    hub.send(carla::WORLD_STREAM_ID, &message);
                }
                Err(sim_client::WaitError::Timeout { .. }) => {}
                Err(e) => {
                    warn!("world stream lost the server: {e}");
                    break;
                }
            }
        }
    }
}
