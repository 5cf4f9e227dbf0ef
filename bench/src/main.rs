//! `simbus-bench`: latency and throughput of simbus, measured side by side
//! with baselines in one run on one machine. The workspace's `cargo build
//! --release` builds it (`cargo run -p simbus-bench` would resolve other
//! features and build the heavy crates a second time):
//!
//! ```text
//! target/release/simbus-bench tick [--iterations N] [--json]
//! target/release/simbus-bench frames [--samples N] [--scale-boxes N,..] [--json]
//! target/release/simbus-bench failover [--trials N] [--json]
//! target/release/simbus-bench commands [--batches N] [--ticks N] [--json]
//! target/release/simbus-bench sensors [--samples N] [--frames N] [--json]
//! target/release/simbus-bench recorder [--frames N] [--big-gib G] [--json]
//! target/release/simbus-bench carla [--ticks N] [--frames N] [--python P] [--json]
//! target/release/simbus-bench python [--ticks N] [--frames N] [--captures N] [--python P] [--json]
//! target/release/simbus-bench substeps [--out DIR] [--seconds S] [--json]
//! target/release/simbus-bench zenoh [--ticks N] [--captures N] [--no-veth] [--json]
//! ```

use std::process::ExitCode;

use clap::{Parser, Subcommand};

mod baselines;
mod blob;
mod breakdown;
mod carla;
mod carla_traffic;
mod commands;
mod failover;
mod fanout;
mod frames;
mod futex;
mod gym;
mod journal;
mod peer;
mod plot;
mod python;
mod recorder;
mod ros2;
mod scaling;
mod sensors;
mod shapes;
mod stats;
mod substeps;
mod support;
mod tick;
mod walkers;
mod zenoh;
mod zenoh_breakdown;
mod zenoh_hosts;
mod zenoh_peer;

/// simbus benchmarks. Each prints a table (or --json) of figures measured in
/// one run on this machine; compare ratios, not absolute numbers, across machines.
#[derive(Debug, Parser)]
#[command(name = "simbus-bench")]
struct Args {
    #[command(subcommand)]
    command: Command,
}

#[derive(Debug, Subcommand)]
enum Command {
    /// Server frames per second (empty, boxes:1000), wait_for_tick
    /// latency, blocking and spinning, and the bus's cost over rapier's step
    /// as the world grows (10 to 10 000 actors).
    Frames(frames::FramesArgs),
    /// Tick round trip: raw iceoryx2 ping-pong (the floor), simbus spin and
    /// blocking, and the same exchange over TCP loopback.
    Tick(tick::TickArgs),
    /// Ticker failover: time from SIGKILL of the ticker until the server
    /// notices, and until a new ticker holds ownership.
    Failover(failover::FailoverArgs),
    /// Cost of a batch of 1000 commands (vs 1000 single commands) and of a
    /// lockstep participant on the tick round trip.
    Commands(commands::CommandsArgs),
    /// Sensor delivery latency from 8 B to 8 MiB against TCP loopback, and
    /// the frame time with a depth camera and a lidar.
    Sensors(sensors::SensorsArgs),
    /// Recording overhead (default scene, boxes:1000), bytes per frame,
    /// compression, and exact replay and re-simulation speed.
    Recorder(recorder::RecorderArgs),
    /// CARLA's own Python client through `sim-client carla-gateway` next to
    /// the native client: tick round trip, wait_for_tick latency, depth
    /// 640x480 frames per second (needs `cargo build --release`).
    Carla(carla::CarlaArgs),
    /// simbus's Python package (a release wheel built here) next to the
    /// Rust client and CARLA's client through the gateway: tick round
    /// trip, wait_for_frame, 8 B and 8 MiB captures to numpy, depth
    /// 640x480 frames per second (needs `cargo build --release`).
    Python(python::PythonArgs),
    /// Fan-out: the last of 1, 4, 16, 64 subscriber processes to hold a
    /// frame or an 8 MiB capture, spinning and blocking.
    Fanout(fanout::FanoutArgs),
    Substeps(substeps::SubstepsArgs),
    /// The server's physics step with 100 and 1 000 walkers (pedestrians)
    /// against the empty ground, per frame and per walker.
    Walkers(walkers::WalkersArgs),
    /// The Zenoh bridge: tick round trip and frame latency locally, through
    /// a mirror on loopback and across a veth pair (root), against TCP;
    /// 1 and 8 MiB captures across the link; ticks per second with 1000
    /// actors; the ownership release bound after the link drops.
    Zenoh(zenoh::ZenohArgs),
    /// ROS 2: `sim-client ros2` to a stock rclpy node, beside rclpy to
    /// rclpy (the DDS floor): /clock and 800x600 image latency, /clock
    /// ticks per second with none missed, four 800x600 cameras' frames per
    /// second (needs `cargo build --release` and the test suite's venv).
    Ros2(ros2::Ros2Args),
    /// Reinforcement learning: `simbus.gym`'s VectorEnv (sync, async, a
    /// camera) beside Gymnasium's Sync/AsyncVectorEnv and highway-env, in
    /// steps and simulated seconds per second for N worlds; reset p50 and
    /// Python's share of a step (needs the test suite's venv).
    Gym(gym::GymArgs),
    /// The measuring client of `zenoh` (run in the host it measures from).
    #[command(hide = true)]
    ZenohPeer(zenoh_peer::ZenohPeerArgs),
    /// A fan-out subscriber (used by `fanout`).
    #[command(hide = true)]
    FanoutPeer(fanout::FanoutPeerArgs),
    /// The other end of a baseline (used by the benchmarks).
    #[command(hide = true)]
    Peer(peer::PeerArgs),
}

fn main() -> ExitCode {
    let args = Args::parse();
    let result = match args.command {
        Command::Frames(a) => frames::run(a),
        Command::Tick(a) => tick::run(a),
        Command::Failover(a) => failover::run(a),
        Command::Commands(a) => commands::run(a),
        Command::Sensors(a) => sensors::run(a),
        Command::Recorder(a) => recorder::run(a),
        Command::Carla(a) => carla::run(a),
        Command::Python(a) => python::run(a),
        Command::Fanout(a) => fanout::run(a),
        Command::Substeps(a) => substeps::run(a),
        Command::Walkers(a) => walkers::run(a),
        Command::Zenoh(a) => zenoh::run(a),
        Command::Ros2(a) => ros2::run(a),
        Command::Gym(a) => gym::run(a),
        Command::ZenohPeer(a) => zenoh_peer::peer(a),
        Command::FanoutPeer(a) => fanout::peer(a),
        Command::Peer(a) => peer::peer(a),
    };
    match result {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("simbus-bench: error: {e:#}");
            ExitCode::FAILURE
        }
    }
}
