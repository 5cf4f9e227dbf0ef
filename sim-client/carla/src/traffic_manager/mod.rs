//! The native traffic manager: CARLA's client asks the server whether a
//! traffic manager runs on a port (`is_traffic_manager_running`) and, if
//! one does, drives it over CARLA's traffic-manager RPC protocol instead
//! of starting its own threads. The gateway answers yes and serves that
//! protocol itself ([`server`]); a driver thread ([`driver`]) joins the
//! world's lockstep and, every frame, turns the frame into one control per
//! registered vehicle (`simbus_traffic`'s planner) over the scene's lanes.
//!
//! So no thread of CARLA's own traffic manager runs in the script: its
//! synchronous-mode deadlock (carla-simulator/carla#9172) cannot happen,
//! and in synchronous mode the world steps only once the traffic manager's
//! controls for the frame are in. What the calls set ([`parameters`])
//! takes effect from the frame after the last one sent when the call came,
//! so a script's calls and ticks give the same run every time.

mod driver;
mod server;

use std::collections::HashMap;
use std::net::TcpListener;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, Condvar, Mutex};
use std::time::Duration;

use tracing::{info, warn};

use crate::locks::lock;
use crate::stream::Hub;
use simbus_traffic::Change;

/// How long a new traffic manager waits to join the world's lockstep
/// before it answers.
const JOIN_WAIT: Duration = Duration::from_secs(5);

/// (run pid, episode, frame) of the last world state sent when a call
/// came: its change holds from the next frame.
type Stamp = (u32, u64, u64);

/// What a traffic manager's RPC connections and its driver share.
#[derive(Debug)]
struct Shared {
    port: u16,
    hub: std::sync::Weak<Hub>,
    changes: Mutex<Vec<(Stamp, Change)>>,
    stopped: AtomicBool,
    /// Whether the driver joined the world's lockstep (`None`: not yet
    /// tried).
    joined: Mutex<Option<bool>>,
    joined_changed: Condvar,
}

impl Shared {
    fn is_stopped(&self) -> bool {
        self.stopped.load(Ordering::Relaxed)
    }

    /// The driver joined the lockstep, or could not.
    fn set_joined(&self, joined: bool) {
        *lock(&self.joined) = Some(joined);
        self.joined_changed.notify_all();
    }

    /// Waits (at most `timeout`) until the driver tried to join the
    /// lockstep: whether it did.
    fn wait_joined(&self, timeout: Duration) -> bool {
        let joined = lock(&self.joined);
        let (joined, _) = self
            .joined_changed
            .wait_timeout_while(joined, timeout, |j| j.is_none())
            .unwrap_or_else(std::sync::PoisonError::into_inner);
        joined.unwrap_or(false)
    }

    /// Queues `change` for the frame after the last one sent.
    fn queue(&self, change: Change) {
        let stamp = self.hub.upgrade().map_or((0, 0, 0), |hub| hub.last_sent());
        lock(&self.changes).push((stamp, change));
    }

    /// The changes due at `now`: those stamped before it, in the order
    /// they came (a stamp of another run is due at once).
    fn due(&self, now: Stamp, out: &mut Vec<Change>) {
        out.clear();
        let mut changes = lock(&self.changes);
        let mut kept = Vec::new();
        for (stamp, change) in changes.drain(..) {
            let before = stamp.0 != now.0 || (stamp.1, stamp.2) < (now.1, now.2);
            if before {
                out.push(change);
            } else {
                kept.push((stamp, change));
            }
        }
        *changes = kept;
    }
}

/// The native traffic managers of a gateway, by port.
#[derive(Debug, Default)]
pub(crate) struct Natives {
    /// Off (`--client-traffic-manager`): CARLA's client runs its own.
    enabled: bool,
    /// The address the gateway listens on.
    host: String,
    world: String,
    running: Mutex<HashMap<u16, Arc<Shared>>>,
}

impl Natives {
    /// Native traffic managers for `world`, listening on `host`, if
    /// `enabled`.
    pub(crate) fn new(enabled: bool, host: &str, world: &str) -> Self {
        Self {
            enabled,
            host: host.to_owned(),
            world: world.to_owned(),
            running: Mutex::default(),
        }
    }

    /// Whether a native traffic manager runs on `port`.
    pub(crate) fn is_running(&self, port: u16) -> bool {
        lock(&self.running).contains_key(&port)
    }

    /// Makes sure a native traffic manager runs on `port`, starting one if
    /// none does: whether one runs (not if they are off, or the port
    /// cannot be bound: CARLA's client then starts its own).
    pub(crate) fn ensure(&self, hub: &Arc<Hub>, port: u16) -> bool {
        if !self.enabled {
            return false;
        }
        let mut running = lock(&self.running);
        if running.contains_key(&port) {
            return true;
        }
        let listener = match TcpListener::bind((self.host.as_str(), port)) {
            Ok(listener) => listener,
            Err(e) => {
                warn!("no traffic manager on port {port} ({e}): CARLA's client starts its own");
                return false;
            }
        };
        let shared = Arc::new(Shared {
            port,
            hub: Arc::downgrade(hub),
            changes: Mutex::default(),
            stopped: AtomicBool::new(false),
            joined: Mutex::default(),
            joined_changed: Condvar::new(),
        });
        let accepting = {
            let shared = shared.clone();
            std::thread::Builder::new()
                .name("carla-tm".into())
                .spawn(move || server::accept(listener, shared))
        };
        let driving = {
            let (shared, world, hub) = (shared.clone(), self.world.clone(), hub.clone());
            std::thread::Builder::new()
                .name("carla-tm-driver".into())
                .spawn(move || driver::run(&shared, &world, &hub))
        };
        if let Err(e) = accepting.and(driving) {
            warn!("no traffic manager on port {port}: {e}");
            shared.stopped.store(true, Ordering::Relaxed);
            return false;
        }
        // Answered once it is in step with the world, so the script's
        // next tick already waits for it.
        if !shared.wait_joined(JOIN_WAIT) {
            warn!("the native traffic manager on port {port} is not in step with the world yet");
        }
        info!(port, "the native traffic manager serves port {port}");
        running.insert(port, shared);
        true
    }
}
