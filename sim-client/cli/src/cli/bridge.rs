//! `sim-client bridge zenoh`: the world beyond one machine, over Zenoh.
//! The bridge itself is the `simbus-zenoh` crate; here are its flags, what
//! it says to the user, and its errors as exit codes.

use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, Subcommand};
use shared_types::WorldName;
use simbus_zenoh::{BridgeError, JsonViews, Notice, Options, Role};

use crate::cli::failure::Failure;

/// Bridge a world to other hosts.
#[derive(Debug, Args)]
pub(crate) struct BridgeArgs {
    #[command(subcommand)]
    protocol: Protocol,
}

#[derive(Debug, Subcommand)]
enum Protocol {
    /// Export a world over Zenoh (--listen, on the server's host) or mirror
    /// one into this host's shared memory (--connect).
    ///
    /// Export: frames on `simbus/<world>/frames` (the frame header then the
    /// actors, as in shared memory: see the README), captures on
    /// `simbus/<world>/sensor/<id>`, requests on `simbus/<world>/rpc/*`
    /// (a mirror's ticks on `simbus/<world>/tick/ask|answer`),
    /// status and settings as JSON on `simbus/<world>/status|settings`, and
    /// with --ros2-clock the simulation time as ROS 2 `rosgraph_msgs/Clock`
    /// (CDR) on `clock`.
    ///
    /// Mirror: every local simbus client of the world works as if its server
    /// ran here.
    ///
    /// The export follows a server restart: when the server exits and
    /// `sim-server --resume DIR` brings the world back within --timeout,
    /// it goes on with the resumed server (mirrors see the link drop and
    /// come back; a remote ticker keeps the world). A server that does not
    /// come back, or a fresh one, ends the export.
    Zenoh(ZenohArgs),
}

/// `bridge zenoh`'s options.
#[derive(Debug, Args)]
pub(crate) struct ZenohArgs {
    /// Export the world, listening on this Zenoh endpoint (tcp/ADDR:PORT).
    #[arg(
        long,
        value_name = "ENDPOINT",
        conflicts_with = "connect",
        required_unless_present = "connect"
    )]
    listen: Option<String>,
    /// Mirror the world exported at this Zenoh endpoint (tcp/HOST:PORT).
    #[arg(long, value_name = "ENDPOINT")]
    connect: Option<String>,
    /// A Zenoh configuration file (JSON5: TLS, routers, scouting...). The
    /// endpoint given with --listen/--connect is added to it.
    #[arg(long, value_name = "FILE")]
    zenoh_config: Option<PathBuf>,
    /// Exporting: also publish the simulation time as ROS 2
    /// `rosgraph_msgs/msg/Clock` in CDR on the Zenoh key `clock` (what
    /// zenoh-bridge-ros2dds forwards to `/clock`).
    #[arg(long)]
    ros2_clock: bool,
    /// Zenoh's lease: a silent link is declared dead after this long, which
    /// bounds how late a lost remote ticker's ownership is released.
    #[arg(long, value_name = "MS", default_value_t = 1000, allow_negative_numbers = true, value_parser = clap::value_parser!(u64).range(100..=60_000))]
    lease_ms: u64,
    /// Mirroring: how long a forwarded request may wait for its answer.
    #[arg(long, value_name = "S", default_value = "60", allow_negative_numbers = true, value_parser = simbus_input::timeout)]
    request_timeout: Duration,
    /// How long the bridge looks for a tick's next event, yielding the
    /// CPU, before it sleeps (the hybrid wait of clients and server): the
    /// exporter while the server has a remote tick, the mirror after it
    /// answered one (the ticker's next tick is coming). Each event found
    /// within it saves a wake-up (~10 µs on an idle CPU); 0 sleeps at once.
    #[arg(long, value_name = "US", default_value_t = 100, allow_negative_numbers = true, value_parser = clap::value_parser!(u64).range(0..=10_000))]
    poll_us: u64,
}

/// The JSON `status --json` and `config --json` print, for Zenoh tools.
const JSON: JsonViews = JsonViews {
    status: super::status::status_json,
    settings: super::describe::settings_json,
};

pub(crate) fn run(world: &WorldName, timeout: Duration, args: BridgeArgs) -> Result<(), Failure> {
    let Protocol::Zenoh(args) = args.protocol;
    let role = match (&args.listen, &args.connect) {
        (Some(endpoint), _) => Role::Export(endpoint),
        (None, Some(endpoint)) => Role::Mirror(endpoint),
        (None, None) => {
            return Err(Failure::Refused(anyhow::anyhow!(
                "give --listen ENDPOINT (export) or --connect ENDPOINT (mirror)"
            )))
        }
    };
    let options = Options {
        zenoh_config: args.zenoh_config,
        ros2_clock: args.ros2_clock,
        lease_ms: args.lease_ms,
        request_timeout: args.request_timeout,
        poll: Duration::from_micros(args.poll_us),
        json: JSON,
    };
    // `SIMBUS_STAMPS=FILE`: the stamps of the ticks it relays, written on
    // exit (`simbus-bench zenoh --breakdown`).
    let stamps_file = simbus_transport::stamps::enable_from_env();
    let stop = crate::cli::interrupt::interrupted();
    let result = simbus_zenoh::run(world, timeout, role, &options, stop, &mut say).map_err(failure);
    if let Some(path) = stamps_file {
        let stamps = simbus_transport::stamps::take();
        if let Err(e) = simbus_transport::stamps::write(&path, &stamps) {
            tracing::warn!("writing the stamps to {}: {e}", path.display());
        }
    }
    result
}

/// What the bridge tells its user, on stdout.
fn say(notice: Notice) {
    match notice {
        Notice::Exporting {
            world,
            endpoint,
            server_pid,
            frame,
        } => println!("exporting world '{world}' on {endpoint} (server pid {server_pid}, frame {frame})"),
        Notice::Mirroring {
            world,
            endpoint,
            server_pid,
            frame,
        } => println!(
            "mirroring world '{world}' from {endpoint} (server pid {server_pid} there, frame {frame}); local clients connect as usual"
        ),
        Notice::Resumed {
            world,
            server_pid,
            previous_pid,
            frame,
        } => println!(
            "the server of world '{world}' restarted (pid {previous_pid} -> {server_pid}): resumed at frame {frame}; exporting goes on"
        ),
        Notice::LinkUp => println!("link up: the exporting bridge is reachable again"),
        Notice::LinkDown => println!("link down: the exporting bridge is out of reach"),
        _ => {}
    }
}

/// Refused input (a bad endpoint or configuration) exits 2; the rest 1.
fn failure(e: BridgeError) -> Failure {
    if e.is_refused() {
        Failure::Refused(e.into())
    } else {
        Failure::Runtime(e.into())
    }
}
