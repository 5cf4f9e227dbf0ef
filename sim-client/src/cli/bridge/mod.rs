//! `sim-client bridge zenoh`: a world beyond one machine, over Zenoh.
//!
//! One bridge per host, symmetric. On the server's host, `--listen`
//! **exports** the world: frames and sensor captures become Zenoh
//! publications under `simbus/<world>/…`, the world's request services
//! (control, tick, batch, lockstep, sensors, recorder) become queryables
//! whose requests the bridge sends to the server through ordinary simbus
//! ports. On another host, `--connect` **mirrors** the world into that
//! host's shared memory: the bridge creates the world's services there, as
//! a server would, publishes every frame and capture it receives and
//! forwards every request, so unmodified local clients (`watch`, `tick`,
//! `sensor watch`, the CARLA gateway, the Rust API) work as if the server
//! were local. Frames cross the network once per host.
//!
//! The single-ticker rule holds across hosts: a remote ticker claims
//! through its mirror; the exporting bridge holds the world's tick
//! ownership on its behalf (the server reports the remote ticker's node and
//! pid) and refuses every other claimant. Each bridge declares a Zenoh
//! liveliness token; when a mirror's token goes (its link dropped or it
//! died) the exporter releases the ownership it held for it, and when the
//! exporter's goes, the mirror answers every request with
//! [`shared_types::ResponseStatus::Unreachable`]. Both happen within the
//! Zenoh lease (`--lease-ms`).

mod answers;
mod export;
mod frames;
mod link;
mod local;
mod mirror;
mod relay;

use std::path::PathBuf;
use std::time::Duration;

use clap::{Args, Subcommand};
use shared_types::WorldName;

use crate::Failure;

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
    /// `simbus/<world>/sensor/<id>`, requests on `simbus/<world>/rpc/*`,
    /// status and settings as JSON on `simbus/<world>/status|settings`, and
    /// with --ros2-clock the simulation time as ROS 2 `rosgraph_msgs/Clock`
    /// (CDR) on `clock`.
    ///
    /// Mirror: every local simbus client of the world works as if its server
    /// ran here.
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
    #[arg(long, value_name = "S", default_value = "60", allow_negative_numbers = true, value_parser = shared_types::input::timeout)]
    request_timeout: Duration,
}

pub(crate) fn run(world: &WorldName, timeout: Duration, args: BridgeArgs) -> Result<(), Failure> {
    let Protocol::Zenoh(args) = args.protocol;
    let stop = crate::cli::interrupted();
    match (&args.listen, &args.connect) {
        (Some(endpoint), _) => {
            let session = link::open(&args, link::Role::Listen(endpoint))?;
            export::run(world, timeout, &args, session, stop)
        }
        (None, Some(endpoint)) => {
            let session = link::open(&args, link::Role::Connect(endpoint))?;
            mirror::run(world, timeout, &args, session, stop)
        }
        (None, None) => Err(Failure::Refused(anyhow::anyhow!(
            "give --listen ENDPOINT (export) or --connect ENDPOINT (mirror)"
        ))),
    }
}
