//! [`crate::Client::on_tick`]: callbacks called with every new frame, on a thread
//! of their own with its own subscription.

use std::collections::{BTreeMap, BTreeSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use shared_types::{ServiceNames, WorldName};
use tracing::warn;

use crate::frame_stream::FrameStream;
use crate::open::client_node;
use crate::{ConnectError, WaitError, WorldSnapshot};

/// The id of a callback registered with [`crate::Client::on_tick`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CallbackId(u64);

pub(crate) type TickCallback = Box<dyn FnMut(&WorldSnapshot) + Send>;

/// The thread that calls `on_tick` callbacks, with its own subscription.
pub(crate) struct TickDispatcher {
    /// Registrations travel to the thread, which owns the callbacks: no
    /// lock is held while a user callback runs.
    changes: mpsc::Sender<Registration>,
    registered: BTreeSet<CallbackId>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    next_id: u64,
}

/// A change to the dispatcher's callbacks.
enum Registration {
    Add(CallbackId, TickCallback),
    Remove(CallbackId),
}

impl TickDispatcher {
    /// Starts the thread, which opens its own subscription to `world`
    /// within `timeout`.
    pub(crate) fn start(world: &WorldName, timeout: Duration) -> Result<Self, ConnectError> {
        start_dispatcher(world, timeout)
    }

    /// Registers `callback`, called with every frame from the next one on.
    pub(crate) fn add(&mut self, callback: TickCallback) -> Result<CallbackId, ConnectError> {
        self.next_id += 1;
        let id = CallbackId(self.next_id);
        self.changes
            .send(Registration::Add(id, callback))
            .map_err(|_| ConnectError::transport("on_tick thread", "the thread has stopped"))?;
        self.registered.insert(id);
        Ok(id)
    }

    /// Removes a callback; `false` if `id` was not registered.
    pub(crate) fn remove(&mut self, id: CallbackId) -> bool {
        if !self.registered.remove(&id) {
            return false;
        }
        // If the thread has stopped, nothing calls the callback any more.
        let _ = self.changes.send(Registration::Remove(id));
        true
    }

    /// Stops the dispatcher's thread and waits for it.
    pub(crate) fn stop(mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

fn start_dispatcher(world: &WorldName, timeout: Duration) -> Result<TickDispatcher, ConnectError> {
    let (changes, incoming) = mpsc::channel::<Registration>();
    let stop = Arc::new(AtomicBool::new(false));
    let world = world.clone();
    let (ready_tx, ready_rx) = mpsc::channel();
    let thread = {
        let stop = stop.clone();
        std::thread::Builder::new()
            .name("simbus-on-tick".into())
            .spawn(move || {
                let opened = client_node().and_then(|node| {
                    let deadline = Instant::now() + timeout;
                    let names = ServiceNames::new(&world);
                    let stream = FrameStream::open(&node, &names, world.as_str(), deadline)?;
                    Ok((node, stream))
                });
                let (_node, mut stream) = match opened {
                    Ok((node, Some(stream))) => {
                        let _ = ready_tx.send(Ok(()));
                        (node, stream)
                    }
                    Ok((_, None)) => {
                        let _ = ready_tx.send(Err(ConnectError::NoServer {
                            world: world.to_string(),
                            timeout,
                        }));
                        return;
                    }
                    Err(e) => {
                        let _ = ready_tx.send(Err(e));
                        return;
                    }
                };
                let mut callbacks: BTreeMap<CallbackId, TickCallback> = BTreeMap::new();
                while !stop.load(Ordering::Relaxed) {
                    match stream.next(Duration::from_millis(100), world.as_str(), None) {
                        Ok(view) => {
                            let snapshot = view.to_snapshot();
                            drop(view);
                            // Whatever was registered before this frame
                            // arrived sees it.
                            for change in incoming.try_iter() {
                                match change {
                                    Registration::Add(id, callback) => {
                                        callbacks.insert(id, callback);
                                    }
                                    Registration::Remove(id) => {
                                        callbacks.remove(&id);
                                    }
                                }
                            }
                            for callback in callbacks.values_mut() {
                                callback(&snapshot);
                            }
                        }
                        Err(WaitError::Timeout { .. }) => {}
                        Err(e) => {
                            warn!("on_tick dispatcher stopped: {e}");
                            return;
                        }
                    }
                }
            })
            .map_err(|e| ConnectError::transport("on_tick thread", e))?
    };
    ready_rx
        .recv()
        .map_err(|e| ConnectError::transport("on_tick thread start", e))??;
    Ok(TickDispatcher {
        changes,
        registered: BTreeSet::new(),
        stop,
        thread: Some(thread),
        next_id: 0,
    })
}
