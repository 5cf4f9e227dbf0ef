//! `frames`: server throughput, snapshot delivery latency, and the bus as the
//! world grows (the scaling rows, in `scaling.rs`).

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use clap::Args;
use shared_types::{WorldName, WorldSettings};
use sim_client::{Client, WaitMode};
use sim_server::{Scene, Server, ServerConfig};

use crate::stats::{header, Latencies};
use crate::support::{now_ns, BenchServer};

#[derive(Debug, Args)]
pub(crate) struct FramesArgs {
    /// Snapshots measured per wait mode.
    #[arg(long, default_value_t = 5000)]
    samples: u64,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    json: bool,
    /// Scaling rows: `boxes:N` worlds timed against rapier's own step
    /// (N boxes and the ground: N + 1 actors).
    #[arg(long, value_delimiter = ',', default_value = "9,99,999,9999")]
    scale_boxes: Vec<u32>,
    /// Scaling rows: frames timed per world (0.01 s each: falling, then resting).
    #[arg(long, default_value_t = 300)]
    scale_frames: usize,
    /// Scaling rows: frames the reader process reads in place per world.
    #[arg(long, default_value_t = 200)]
    scale_reads: u64,
}

/// Frames per second of an unpaced async fixed-step server (0.01 s) with no
/// subscribers, run in this process.
fn server_fps(scene: Scene, frames: u64) -> anyhow::Result<(u64, f64, f64)> {
    let config = ServerConfig {
        world: WorldName::new(&format!("bench-fps-{}", std::process::id()))?,
        scene,
        settings: WorldSettings {
            fixed_delta_seconds: Some(0.01),
            ..Default::default()
        },
        realtime: false,
        max_fps: 0.0,
        max_frames: Some(frames),
        on_ticker_loss: Default::default(),
        wait_mode: shared_types::WaitMode::Block,
        hybrid_window: Duration::ZERO,
        seed: 0,
        lockstep_timeout: Duration::from_secs(10),
        limits: Default::default(),
        keyframe_seconds: None,
        render_threads: None,
        journal: None,
    };
    let summary = Server::start(config)?.run(&AtomicBool::new(false))?;
    Ok((
        summary.frames,
        summary.wall_seconds,
        summary.frames_per_second(),
    ))
}

/// Publish → `wait_for_tick` returned, against a 1 kHz realtime server.
fn delivery_latency(world: &str, mode: WaitMode, samples: u64) -> anyhow::Result<Latencies> {
    let mut client = Client::connect(world, Duration::from_secs(10))?;
    client.set_wait_mode(mode);
    client.wait_for_tick(Duration::from_secs(5))?;
    let mut latencies = Latencies::new();
    while latencies.len() < samples {
        let snapshot = client.wait_for_tick(Duration::from_secs(5))?;
        let received = now_ns();
        let published = (snapshot.timestamp().platform_timestamp * 1e9) as u64;
        if snapshot.missed == 0 {
            latencies.record(received.saturating_sub(published));
        }
    }
    Ok(latencies)
}

pub(crate) fn run(args: FramesArgs) -> anyhow::Result<()> {
    let runs = [
        (Scene::Empty, 20_000),
        (Scene::Boxes(1000), 300),
        (Scene::Boxes(1000), 3_000),
    ];
    let fps: Vec<(Scene, (u64, f64, f64))> = runs
        .into_iter()
        .map(|(scene, frames)| Ok((scene, server_fps(scene, frames)?)))
        .collect::<anyhow::Result<_>>()?;

    let server = BenchServer::start(
        "latency",
        &[
            "--scene",
            "empty",
            "--fixed-delta-seconds",
            "0.001",
            "--realtime",
        ],
    )?;
    let block = delivery_latency(&server.world, WaitMode::Block, args.samples)?;
    let spin = delivery_latency(&server.world, WaitMode::Spin, args.samples)?;
    // The floor under the same conditions: a round trip every millisecond.
    let floor = crate::futex::floor(args.samples, Duration::from_millis(1))?;
    let hop = floor.quantile_us(0.5) / 2.0;
    let load = crate::support::load_average();
    let scaling = crate::scaling::rows(&args.scale_boxes, args.scale_frames, args.scale_reads)?;

    if args.json {
        let fps_json: Vec<_> = fps
            .iter()
            .map(|(scene, (frames, wall, fps))| {
                serde_json::json!({"scene": scene.to_string(), "frames": frames, "wall_seconds": wall, "fps": fps})
            })
            .collect();
        println!(
            "{}",
            serde_json::json!({
                "server_fps": fps_json,
                "wait_for_tick": {"block": block.json(), "spin": spin.json()},
                "futex_round_trip_every_ms": floor.json(),
                "block_over_futex_hop_p50": block.quantile_us(0.5) / hop,
                "scaling": crate::scaling::json(&scaling),
                "load_average": load,
            })
        );
        return Ok(());
    }
    println!("server throughput: async, fixed step 0.01 s, unpaced, no subscribers");
    println!(
        "{:<14} {:>8} {:>10} {:>12}",
        "scene", "frames", "wall s", "frames/s"
    );
    for (scene, (frames, wall, fps)) in &fps {
        println!(
            "{:<14} {frames:>8} {wall:>10.3} {fps:>12.0}",
            scene.to_string()
        );
    }
    println!();
    println!(
        "wait_for_tick latency: frame published -> snapshot in the client ({} samples each, 1 kHz server, empty scene)",
        args.samples
    );
    println!("{}", header("wait mode"));
    println!("{}", block.row("block (frame-ready event)"));
    println!("{}", spin.row("spin"));
    println!("{}", floor.row("futex round trip, one per ms"));
    println!(
        "block / spin at p50: {:.1}x; block / one futex hop (half the round trip) at p50: {:.2}x",
        block.quantile_us(0.5) / spin.quantile_us(0.5).max(0.001),
        block.quantile_us(0.5) / hop
    );
    println!();
    crate::scaling::print(&scaling, args.scale_frames);
    println!("load average before the scaling rows: {load}");
    Ok(())
}
