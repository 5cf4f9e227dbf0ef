//! `sim-client carla-gateway`: CARLA 0.9.16's own Python client library
//! drives a simbus world through this process, which speaks CARLA's RPC
//! (msgpack-RPC) and streaming protocols on TCP and is an ordinary client
//! of the world: it holds simbus ports, and a CARLA connection that turns
//! synchronous mode on claims the world's tick ownership like any ticker.
//!
//! Each CARLA connection is served on its own thread with its own simbus
//! client; a connection that sends garbage, too much, or vanishes is
//! dropped (and its tick ownership released) without touching the others.

mod blueprints;
mod commands;
pub(crate) mod convert;
mod rpc;
mod sensors;
mod session;
mod stream;

use std::io::{BufReader, Write};
use std::net::{TcpListener, TcpStream};
use std::sync::Arc;
use std::time::Duration;

use anyhow::Context;
use clap::Args;
use shared_types::WorldName;
use tracing::{debug, info, warn};

use crate::Failure;
use rpc::ReadError;
use session::Session;
use stream::Hub;

/// The stack of a connection's thread: room for a batch's `.then(...)` and
/// the simbus client's calls, whatever the build.
const SESSION_STACK: usize = 8 << 20;

/// Serve a simbus world to CARLA's Python client (`import carla`).
#[derive(Debug, Args)]
pub(crate) struct GatewayArgs {
    /// The address to listen on.
    #[arg(long, default_value = "127.0.0.1")]
    host: String,
    /// The RPC port (CARLA's `carla.Client(host, port)`); 0: any free port
    /// (and any free streaming port), printed once listening.
    #[arg(long, default_value_t = 2000, allow_negative_numbers = true)]
    port: u16,
    /// The streaming port (0: any free port) [default: --port + 1; with
    /// --port 0, any free port]. Give it to use a privileged port
    /// (below 1024) for the streams, or with --port 65535.
    #[arg(long, value_name = "PORT", allow_negative_numbers = true)]
    streaming_port: Option<u16>,
    /// Once listening, print one JSON object on stdout instead of the
    /// sentence: {"world", "host", "port", "streaming_port"}, the ports
    /// actually bound (so scripts can use --port 0).
    #[arg(long)]
    json: bool,
}

/// The streaming port to bind for RPC port `port`: `--streaming-port` as
/// given; else `port + 1`, refused where that wraps past 65535 or lands
/// on a privileged port (below 1024) nobody asked for; with `--port 0`,
/// any free port (0).
fn streaming_port(port: u16, explicit: Option<u16>) -> Result<u16, Failure> {
    if let Some(explicit) = explicit {
        return Ok(explicit);
    }
    if port == 0 {
        return Ok(0);
    }
    match port.checked_add(1) {
        None => Err(Failure::Refused(anyhow::anyhow!(
            "--port {port} leaves no port for the streams (--port + 1 is past 65535): \
             give --streaming-port PORT, or --port 0 for two free ports"
        ))),
        Some(next) if next < 1024 => Err(Failure::Refused(anyhow::anyhow!(
            "--port {port} would put the streams on port {next} (--port + 1), a privileged port \
             (below 1024): give --streaming-port {next} to mean it, or another --port"
        ))),
        Some(next) => Ok(next),
    }
}

pub(crate) fn run(world: &WorldName, timeout: Duration, args: GatewayArgs) -> Result<(), Failure> {
    let streaming_port = streaming_port(args.port, args.streaming_port)?;
    let rpc = TcpListener::bind((args.host.as_str(), args.port))
        .with_context(|| format!("listening for CARLA clients on {}:{}", args.host, args.port))?;
    let streams = TcpListener::bind((args.host.as_str(), streaming_port)).with_context(|| {
        format!(
            "listening for CARLA streams on {}:{streaming_port}",
            args.host
        )
    })?;
    // The ports actually bound (--port 0 binds any free one): these go to
    // the user and into every stream token CARLA clients get.
    let port = rpc
        .local_addr()
        .context("the RPC listener's address")?
        .port();
    let streaming_port = streams
        .local_addr()
        .context("the streaming listener's address")?
        .port();
    let hub = Arc::new(Hub::default());
    {
        let hub = hub.clone();
        std::thread::spawn(move || stream::accept(streams, hub));
    }
    {
        let (world, hub) = (world.to_string(), hub.clone());
        std::thread::spawn(move || stream::pump(world, hub));
    }
    let stop = super::interrupted();
    if args.json {
        println!(
            "{}",
            serde_json::json!({"world": world.as_str(), "host": args.host,
                "port": port, "streaming_port": streaming_port})
        );
    } else {
        println!(
            "carla-gateway: world '{world}' served to CARLA clients on {}:{port} (streams on port {streaming_port})",
            args.host
        );
    }
    let _ = std::io::stdout().flush();
    let world = world.to_string();
    std::thread::spawn(move || {
        for socket in rpc.incoming() {
            let socket = match socket {
                Ok(socket) => socket,
                Err(e) => {
                    warn!("accepting a CARLA client: {e}");
                    continue;
                }
            };
            let (world, hub) = (world.clone(), hub.clone());
            let spawned = std::thread::Builder::new()
                .name("carla-session".into())
                .stack_size(SESSION_STACK)
                .spawn(move || serve(socket, world, timeout, streaming_port, hub));
            if let Err(e) = spawned {
                warn!("no thread for a CARLA client: {e}");
            }
        }
    });
    // Ctrl-C / SIGTERM end the gateway; the server sees its tick
    // ownership and ports go with the process.
    while !stop.load(std::sync::atomic::Ordering::Relaxed) {
        std::thread::sleep(Duration::from_millis(100));
    }
    info!("carla-gateway stopped");
    Ok(())
}

/// Serves one CARLA connection until it closes or misbehaves.
fn serve(socket: TcpStream, world: String, timeout: Duration, streaming_port: u16, hub: Arc<Hub>) {
    let Ok(peer) = socket.peer_addr() else {
        return;
    };
    let _ = socket.set_nodelay(true);
    // A client that stops reading its answers is dropped.
    let _ = socket.set_write_timeout(Some(Duration::from_secs(10)));
    let Ok(mut writer) = socket.try_clone() else {
        return;
    };
    let mut reader = BufReader::new(socket);
    let mut session = Session::new(world, timeout, peer, streaming_port, hub);
    info!(%peer, "CARLA client connected");
    loop {
        let request = match rpc::read_request(&mut reader) {
            Ok(request) => request,
            Err(ReadError::Closed) => break,
            Err(e) => {
                warn!(%peer, "dropping a CARLA client: {e}");
                break;
            }
        };
        debug!(%peer, method = request.method, asynchronous = request.asynchronous, "CARLA call");
        let answer = session.answer(&request);
        if writer
            .write_all(&rpc::response(request.id, answer))
            .is_err()
        {
            break;
        }
    }
    // The session (and its tick ownership) ends with the connection.
    info!(%peer, "CARLA client gone");
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
