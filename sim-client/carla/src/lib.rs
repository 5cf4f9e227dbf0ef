//! The CARLA gateway (`sim-client carla-gateway`): CARLA 0.9.16's own
//! Python client library drives a simbus world through this crate, which
//! speaks CARLA's RPC (msgpack-RPC) and streaming protocols on TCP and is
//! an ordinary client of the world: it holds simbus ports, and a CARLA
//! connection that turns synchronous mode on claims the world's tick
//! ownership like any ticker.
//!
//! Each CARLA connection is served on its own thread with its own simbus
//! client; a connection that sends garbage, too much, or vanishes is
//! dropped (and its tick ownership released) without touching the others.
//!
//! The crate owns CARLA's wire layouts ([`wire`]); it prints nothing:
//! [`serve`] tells its caller where it listens, and logs with `tracing`.

mod blueprints;
mod commands;
mod convert;
mod derived;
mod episode_settings;
mod error;
mod locks;
mod maps;
mod navigation;
pub mod recorder_text;
mod records;
mod ros2;
mod rpc;
mod sensors;
mod session;
mod signals;
mod stop;
mod stream;
mod traffic_manager;
mod traffic_managers;
pub mod wire;

use std::net::TcpListener;
use std::sync::Arc;
use std::time::Duration;

use shared_types::WorldName;
use tracing::{info, warn};

pub use error::GatewayError;
use session::Session;
pub use stop::Stop;
use stop::Woken;
use stream::Hub;

/// The stack of a connection's thread: room for a batch's `.then(...)` and
/// the simbus client's calls, whatever the build.
const SESSION_STACK: usize = 8 << 20;

/// Where to serve CARLA clients, and how long to wait for the world.
#[derive(Debug, Clone)]
pub struct Config {
    /// The address to listen on.
    pub host: String,
    /// The RPC port (CARLA's `carla.Client(host, port)`); 0: any free port
    /// (and any free streaming port).
    pub port: u16,
    /// The streaming port (0: any free port); `None`: `port + 1` (with
    /// port 0, any free port). See [`streaming_port`].
    pub streaming_port: Option<u16>,
    /// How long a call waits for the world's server, and for a tick.
    pub timeout: Duration,
    /// Refuse to load CARLA's towns (`Town01`…`Town15`) instead of
    /// loading simbus's `town` in their place (`--strict-maps`).
    pub strict_maps: bool,
    /// Let CARLA's client run its own traffic manager (in the script's
    /// process) instead of the gateway's native one
    /// (`--client-traffic-manager`).
    pub client_traffic_manager: bool,
    /// CARLA's native ROS 2 (`--ros2`): publish the sensors scripts enable
    /// for ROS, and take `hero` vehicles' control, on this DDS domain.
    pub ros2: Option<u16>,
}

/// Where the gateway listens, once it does: the ports actually bound.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Listening {
    /// The RPC port.
    pub port: u16,
    /// The streaming port (in every stream token CARLA clients get).
    pub streaming_port: u16,
}

/// The streaming port to bind for RPC port `port`.
///
/// `explicit` as given; else `port + 1`, refused where that wraps past
/// 65535 or lands on a privileged port (below 1024) nobody asked for; with
/// port 0, any free port (0).
///
/// # Errors
///
/// Returns [`GatewayError::NoStreamingPort`] if `port + 1` is past 65535, and
/// [`GatewayError::PrivilegedStreamingPort`] if it is below 1024; both only
/// when no `explicit` port is given and `port` is not 0.
pub fn streaming_port(port: u16, explicit: Option<u16>) -> Result<u16, GatewayError> {
    if let Some(explicit) = explicit {
        return Ok(explicit);
    }
    if port == 0 {
        return Ok(0);
    }
    match port.checked_add(1) {
        None => Err(GatewayError::NoStreamingPort { port }),
        Some(next) if next < 1024 => Err(GatewayError::PrivilegedStreamingPort { port, next }),
        Some(next) => Ok(next),
    }
}

/// Serves `world` to CARLA clients until `stop` is given.
///
/// `on_listening` is told the ports bound once both listeners are. The
/// calling thread accepts the CARLA connections, waking only for a
/// connection or the stop. The streams' and connections' threads end with
/// the process (the server sees the gateway's tick ownership and ports go
/// with it).
///
/// # Errors
///
/// Returns the errors of [`streaming_port`] for the streaming port implied,
/// [`GatewayError::Listen`] if either listener cannot be bound (the port is
/// taken, or privileged), [`GatewayError::Address`] if a bound listener has no
/// address to report, and [`GatewayError::Wait`] if the RPC listener and the
/// stop cannot be waited on. A CARLA client's failure ends its own session,
/// never the gateway.
pub fn serve(
    world: &WorldName,
    config: &Config,
    stop: &Stop,
    on_listening: impl FnOnce(&Listening),
) -> Result<(), GatewayError> {
    let streaming_port = streaming_port(config.port, config.streaming_port)?;
    let host = config.host.as_str();
    let listen = |what: &'static str, port: u16| {
        TcpListener::bind((host, port)).map_err(|source| GatewayError::Listen {
            what,
            host: host.to_string(),
            port,
            source,
        })
    };
    let rpc = listen("clients", config.port)?;
    let streams = listen("streams", streaming_port)?;
    let address = |what: &'static str, listener: &TcpListener| {
        listener
            .local_addr()
            .map(|a| a.port())
            .map_err(|source| GatewayError::Address { what, source })
    };
    // The ports actually bound (port 0 binds any free one): these go to
    // the caller and into every stream token CARLA clients get.
    let listening = Listening {
        port: address("RPC", &rpc)?,
        streaming_port: address("streaming", &streams)?,
    };
    // Accepted without blocking once `stop::wait` said one waits.
    rpc.set_nonblocking(true).map_err(GatewayError::Wait)?;
    let mut hub = Hub::default();
    hub.maps = maps::Maps::new(config.strict_maps);
    hub.natives =
        traffic_manager::Natives::new(!config.client_traffic_manager, host, world.as_str());
    if let Some(domain_id) = config.ros2 {
        hub.ros2 = ros2::Ros2::start(world.as_str(), domain_id, config.timeout);
    }
    let hub = Arc::new(hub);
    {
        let hub = hub.clone();
        std::thread::spawn(move || stream::accept(streams, hub));
    }
    {
        let (world, hub) = (world.to_string(), hub.clone());
        std::thread::spawn(move || stream::pump(world, hub));
    }
    on_listening(&listening);
    let sessions = Sessions {
        world: world.to_string(),
        timeout: config.timeout,
        streaming_port: listening.streaming_port,
        hub,
    };
    // The one wait point: a connection, or the stop.
    while stop::wait(&rpc, stop).map_err(GatewayError::Wait)? == Woken::Connection {
        sessions.accept(&rpc);
    }
    info!("carla-gateway stopped");
    Ok(())
}

/// What every CARLA connection's session is started with.
#[derive(Debug)]
struct Sessions {
    world: String,
    timeout: Duration,
    streaming_port: u16,
    hub: Arc<Hub>,
}

impl Sessions {
    /// Accepts the connections waiting on `rpc` (non-blocking), each
    /// served on its own thread.
    fn accept(&self, rpc: &TcpListener) {
        loop {
            let (socket, peer) = match rpc.accept() {
                Ok(accepted) => accepted,
                Err(e) if e.kind() == std::io::ErrorKind::WouldBlock => return,
                Err(e) => {
                    warn!("accepting a CARLA client: {e}");
                    return;
                }
            };
            // Some systems hand the listener's non-blocking mode on.
            if let Err(e) = socket.set_nonblocking(false) {
                warn!(%peer, "dropping a CARLA client: {e}");
                continue;
            }
            let (world, hub) = (self.world.clone(), self.hub.clone());
            let (timeout, streaming_port) = (self.timeout, self.streaming_port);
            let spawned = std::thread::Builder::new()
                .name("carla-session".into())
                .stack_size(SESSION_STACK)
                .spawn(move || {
                    Session::new(world, timeout, peer, streaming_port, hub).serve(socket)
                });
            if let Err(e) = spawned {
                warn!("no thread for a CARLA client: {e}");
            }
        }
    }
}

#[cfg(test)]
mod tests {
    use super::streaming_port;

    #[test]
    fn the_streaming_port_never_wraps_nor_lands_on_a_privileged_port_unasked() {
        assert_eq!(streaming_port(2000, None).ok(), Some(2001));
        assert_eq!(streaming_port(0, None).ok(), Some(0), "--port 0: both free");
        assert_eq!(streaming_port(1023, None).ok(), Some(1024));
        assert!(streaming_port(65535, None).is_err(), "65535 + 1 wraps");
        assert!(streaming_port(1, None).is_err(), "port 2 is privileged");
        assert!(
            streaming_port(1022, None).is_err(),
            "port 1023 is privileged"
        );
        // Asked for: as given.
        assert_eq!(streaming_port(65535, Some(40000)).ok(), Some(40000));
        assert_eq!(streaming_port(1, Some(2)).ok(), Some(2));
        assert_eq!(streaming_port(0, Some(0)).ok(), Some(0));
    }
}
