//! `sim-client`: watch, inspect and configure simbus worlds.

use std::process::ExitCode;
use std::time::Duration;

use clap::{Parser, Subcommand};
use shared_types::WorldName;
use simbus_input as input;
use tracing_subscriber::EnvFilter;

use cli::failure::Failure;

#[macro_use]
mod census;
mod cli;
#[cfg(test)]
mod doc_commands;

/// The heading of the options every subcommand takes, after its own.
const GLOBAL: &str = "Global options";

/// Watch, inspect and configure a simbus world.
///
/// Every command talks to the server of one world (--world, or SIMBUS_WORLD).
/// Start one with `sim-server`, or try everything at once with `sim-client demo`.
///
/// A closed stdout (`sim-client watch | head -1`) ends a command quietly
/// with exit status 0, after it has put back what it changed (a ticker
/// gives the world back, as `tick` promises).
#[derive(Debug, Parser)]
#[command(name = "sim-client", version)]
struct Args {
    /// World to talk to [default: default; `demo`: a new world demo-<pid>].
    #[arg(long, global = true, env = "SIMBUS_WORLD", help_heading = GLOBAL)]
    world: Option<WorldName>,

    /// Seconds to wait for the server to answer, and for each frame or
    /// capture a command waits for.
    #[arg(long, global = true, value_name = "S", default_value = "5", allow_negative_numbers = true, value_parser = input::timeout, help_heading = GLOBAL)]
    timeout: Duration,

    /// More logging (-v debug, -vv trace); RUST_LOG overrides.
    #[arg(short, long, global = true, action = clap::ArgAction::Count, help_heading = GLOBAL)]
    verbose: u8,

    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Print one line per frame as the world publishes them.
    ///
    /// Frames come in order, each once. A watcher slower than the server
    /// skips to the newest frame and says how many it missed (`missed`), in
    /// synchronous mode too when the ticker outruns it (16 frames of slack);
    /// --every-frame keeps every queued frame in asynchronous mode; only
    /// --lockstep makes the server wait for this watcher, so it sees every
    /// frame.
    Watch(cli::watch::WatchArgs),
    /// Show the world's mode, settings and current frame.
    Status(cli::status::StatusArgs),
    /// One refreshing screen of a world: mode, settings, frame rate and
    /// real-time factor, the ticker, lockstep participants, every client with
    /// the services it has ports on, every sensor with its readers and
    /// capture rate, and the shared memory the server maps.
    ///
    /// `--once --json` prints one JSON object for scripts.
    Top(cli::top::TopArgs),
    /// Serve the world live to Foxglove over its WebSocket protocol.
    ///
    /// Actors as a scene (`/simbus/scene`), the simulation clock, depth
    /// cameras as images and lidars as point clouds, at the frame rate or at
    /// most --max-hz. Open ws://HOST:PORT in Foxglove. A server that exits
    /// ends it (a resumed one too: start it again).
    #[cfg(feature = "foxglove")]
    Foxglove(cli::foxglove::FoxgloveArgs),
    /// Publish the world on ROS 2 over DDS, for stock ROS 2 nodes (rclpy,
    /// rviz2, rosbag2) with no ROS install here.
    ///
    /// `/clock` every frame (the frame's exact time, for `use_sim_time`),
    /// every sensor in `sensor_msgs` under `<namespace>/sensor_<id>/`,
    /// every actor's pose on `/tf`, sensor mounts on `/tf_static`, each
    /// vehicle's odometry and control topics, the scene as markers; with
    /// --tick-from-ros a ROS node ticks the world. Every message is stamped
    /// with the simulation time of its frame.
    #[cfg(feature = "ros2")]
    Ros2(cli::ros2::Ros2Args),
    /// Bridge the world to other hosts: `bridge zenoh --listen` exports it
    /// from the server's host, `bridge zenoh --connect` mirrors it into
    /// another host's shared memory for unmodified local clients.
    #[cfg(feature = "zenoh")]
    Bridge(cli::bridge::BridgeArgs),
    /// Change the time settings, like CARLA's config.py.
    ///
    /// Changes hold from the frame printed. Invalid settings are refused with
    /// the rule they break (exit 2), and nothing changes. Synchronous mode can
    /// be left here (--no-sync) but not entered: the tick owner enters it
    /// (`sim-client tick`), so a world is never left waiting for ticks nobody
    /// sends.
    Config(cli::config::ConfigArgs),
    /// Be the ticker: synchronous mode with a fixed step, one frame per tick.
    ///
    /// Claims tick ownership (only one client may tick: a second one is
    /// refused with the owner named), switches the world to synchronous mode
    /// with a fixed step and ticks. --count and --until-sim-time bound the
    /// run, --rate paces it; without a bound it ticks until Ctrl-C. However
    /// it ends (a bound, Ctrl-C, SIGTERM, an error, a closed stdout, a
    /// panic) the world gets its settings back as they were before the run
    /// (a world that was asynchronous runs free again; one that was
    /// synchronous, `sim-server --sync`, stays synchronous and waits for
    /// the next ticker; --leave-sync keeps it synchronous in any case), and
    /// ownership is released. A journaling server (`sim-server --journal`)
    /// that exits is waited for and, once resumed (`sim-server --resume`),
    /// claimed again: ticking goes on from the frame it resumed at, none
    /// printed twice or skipped. With --standby it waits, ports open and
    /// claim queued, until the world has no ticker, then takes over from
    /// the next frame.
    Tick(cli::tick::TickArgs),
    /// Spawn an actor (box, sphere, capsule, vehicle, walker) and print its id.
    ///
    /// A spawn whose body would overlap another body (the ground
    /// included) is refused, exit 2, naming the actor that is there, as
    /// CARLA refuses one; a body resting on another is spawned.
    Spawn(cli::actors::SpawnArgs),
    /// Destroy an actor.
    Destroy(cli::actors::DestroyArgs),
    /// Reload the current scene as a new episode.
    Reload(cli::actors::ReloadArgs),
    /// Load a scene as a new episode.
    Load(cli::actors::LoadArgs),
    /// Drive the world's vehicles as a lockstep participant (seeded).
    ///
    /// In synchronous mode the server waits, every frame, until the autopilot
    /// has sent its commands for the next frame. The same seed drives the same
    /// way, and every new episode starts the random sequence again, so runs
    /// repeat bit for bit. A server that exits ends it, also one that is
    /// then resumed from its journal: start it again on the resumed world.
    Autopilot(cli::autopilot::AutopilotArgs),
    /// Sensors: spawn, list, watch, save pictures, destroy.
    ///
    /// Depth camera, lidar and IMU, written by the server straight into shared
    /// memory and read in place.
    Sensor(cli::sensor::SensorArgs),
    /// Start a server on the default scene, watch it, and print a live summary.
    ///
    /// The server runs in its own world (demo-<pid>) at wall-clock speed with
    /// a fixed step; the demo stops and reaps it after --frames frames or Ctrl-C.
    Demo(cli::demo::DemoArgs),
    /// Record the world (start, stop, status) and inspect recordings (info,
    /// collisions, blocked), like CARLA's recorder, on MCAP files.
    Recorder(cli::recorder::RecorderArgs),
    /// Replay a recording: exact, interpolated, or re-simulated and verified.
    ///
    /// Without --detach it follows the replay to its end; a server that
    /// exits ends it (a server resumed from its journal does not go on
    /// replaying).
    Replay(cli::recorder::ReplayArgs),
    /// Save the whole world in the server's memory and restore it later as
    /// a new episode from exactly that state (save, restore, list, drop).
    ///
    /// While a ticker holds the world only its process saves and restores
    /// (this command is then refused, naming it); the Rust and Python
    /// clients have the same calls for the ticker's own program.
    Snapshot(cli::snapshot::SnapshotArgs),
    /// Serve the world to CARLA's own Python client (`import carla`).
    ///
    /// Speaks CARLA 0.9.16's RPC and streaming protocols on --port and
    /// --port + 1. A CARLA connection that turns synchronous mode on becomes
    /// the world's ticker (a second one is refused, naming the owner); its
    /// ownership ends with its connection.
    #[cfg(feature = "carla")]
    CarlaGateway(cli::carla::GatewayArgs),
}

fn init_logging(verbose: u8) {
    let default = match verbose {
        // Zenoh's own warnings (a connection being retried) are not the
        // user's business unless asked for (-v, RUST_LOG): the bridge
        // says itself what failed. DDS's likewise (RustDDS logs a foreign
        // participant's quirks as errors; the ROS 2 adapter reports what
        // it dropped).
        0 => "warn,zenoh=error,rustdds=off,ros2_client=off",
        1 => "debug",
        _ => "trace",
    };
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(default));
    iceoryx2::prelude::set_log_level_from_env_or(iceoryx2::prelude::LogLevel::Error);
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
}

fn main() -> ExitCode {
    let args = Args::parse();
    init_logging(args.verbose);
    let timeout = args.timeout;
    let world = args
        .world
        .clone()
        .unwrap_or_else(|| WorldName::new("default").expect("'default' is a valid world name"));
    let world = &world;
    let run = || match args.command {
        Command::Watch(a) => cli::watch::run(world, timeout, a),
        Command::Status(a) => cli::status::run(world, timeout, a),
        Command::Top(a) => cli::top::run(world, timeout, a),
        #[cfg(feature = "foxglove")]
        Command::Foxglove(a) => cli::foxglove::run(world, timeout, a),
        #[cfg(feature = "ros2")]
        Command::Ros2(a) => cli::ros2::run(world, timeout, a),
        #[cfg(feature = "zenoh")]
        Command::Bridge(a) => cli::bridge::run(world, timeout, a),
        Command::Config(a) => cli::config::run(world, timeout, a),
        Command::Tick(a) => cli::tick::run(world, timeout, a),
        Command::Spawn(a) => cli::actors::spawn(world, timeout, a),
        Command::Destroy(a) => cli::actors::destroy(world, timeout, a),
        Command::Reload(a) => cli::actors::reload(world, timeout, a),
        Command::Load(a) => cli::actors::load(world, timeout, a),
        Command::Autopilot(a) => cli::autopilot::run(world, timeout, a),
        Command::Sensor(a) => cli::sensor::run(world, timeout, a),
        Command::Demo(a) => cli::demo::run(args.world, timeout, a),
        Command::Recorder(a) => cli::recorder::run(world, timeout, a),
        Command::Replay(a) => cli::recorder::replay(world, timeout, a),
        Command::Snapshot(a) => cli::snapshot::run(world, timeout, a),
        #[cfg(feature = "carla")]
        Command::CarlaGateway(a) => cli::carla::run(world, timeout, a),
    };
    let result = match cli::output::run(run) {
        cli::output::Ended::Returned(result) => result,
        // Nobody reads any more: what the command changed is put back (its
        // guards ran while it unwound); nothing to say, and nowhere to.
        cli::output::Ended::StdoutClosed => Ok(()),
        cli::output::Ended::StdoutFailed(e) => Err(Failure::Runtime(
            anyhow::Error::from(e).context("writing to stdout"),
        )),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(Failure::Runtime(e)) => {
            eprintln!("sim-client: error: {e:#}");
            ExitCode::FAILURE
        }
        Err(Failure::Refused(e)) => {
            eprintln!("sim-client: refused: {e:#}");
            ExitCode::from(2)
        }
        Err(Failure::Interrupted(e)) => {
            eprintln!("sim-client: interrupted: {e:#}");
            ExitCode::from(130)
        }
    }
}
