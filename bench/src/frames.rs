//! `frames`: server throughput, snapshot delivery latency, and the bus as the
//! world grows (the scaling rows, in `scaling.rs`).

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use clap::Args;
use shared_types::{WorldName, WorldSettings};
use sim_client::{Client, WaitMode};
use sim_server::{Scene, Server, ServerConfig};

use crate::stats::{header, Latencies};
use crate::support::{now_ns, BenchServer, Placement};

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
    /// Scaling rows: frames the reader process reads in place per world
    /// (its four kinds of read take turns: a quarter each).
    #[arg(long, default_value_t = 600)]
    scale_reads: u64,
    /// Where the wait_for_tick rows run: `same` (server, client and the
    /// floor's peer on CPU 0), `split` (the client on CPU 0, the server and
    /// the floor's peer on CPU 1) or `unpinned`. Without it: each in
    /// turn, each against the futex floor measured under it.
    #[arg(long, value_enum)]
    placement: Option<Placement>,
}

/// The wait_for_tick rows under one placement.
struct Delivery {
    placement: Placement,
    block: Latencies,
    /// Blocking `wait_for_frame`: the same frame held in place, no copy.
    block_in_place: Latencies,
    /// None on one CPU: a spinning client leaves the server no CPU.
    spin: Option<Latencies>,
    /// A futex round trip every millisecond under the same placement.
    floor: Latencies,
}

impl Delivery {
    /// Blocking `wait_for_tick` over one futex hop (half the floor's round
    /// trip), at p50.
    fn block_over_hop(&self) -> f64 {
        self.block.quantile_us(0.5) / (self.floor.quantile_us(0.5) / 2.0)
    }
}

/// The wait_for_tick rows against the 1 kHz server `server`, pinned as
/// `placement` says.
fn delivery(server: &BenchServer, placement: Placement, samples: u64) -> anyhow::Result<Delivery> {
    placement.apply(&[server.pid()])?;
    let block = delivery_latency(&server.world, WaitMode::Block, Read::Copy, samples)?;
    let block_in_place = delivery_latency(&server.world, WaitMode::Block, Read::InPlace, samples)?;
    let spin = match placement {
        Placement::Same => None,
        _ => Some(delivery_latency(
            &server.world,
            WaitMode::Spin,
            Read::Copy,
            samples,
        )?),
    };
    Placement::Unpinned.apply(&[server.pid()])?;
    // The floor under the same conditions: a round trip every millisecond.
    let floor = crate::futex::floor_placed(samples, Duration::from_millis(1), placement)?;
    Ok(Delivery {
        placement,
        block,
        block_in_place,
        spin,
        floor,
    })
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

/// How a delivery row takes each frame.
#[derive(Clone, Copy)]
enum Read {
    /// `wait_for_tick`: an owned `WorldSnapshot`.
    Copy,
    /// `wait_for_frame`: the frame held in place in shared memory.
    InPlace,
}

/// Publish → `wait_for_tick` (or `wait_for_frame`) returned, against a
/// 1 kHz realtime server.
fn delivery_latency(
    world: &str,
    mode: WaitMode,
    read: Read,
    samples: u64,
) -> anyhow::Result<Latencies> {
    let mut client = Client::connect(world, Duration::from_secs(10))?;
    client.set_wait_mode(mode);
    client.wait_for_tick(Duration::from_secs(5))?;
    let wait = Duration::from_secs(5);
    let mut latencies = Latencies::new();
    while latencies.len() < samples {
        // (when it was received, when it was published, frames missed)
        let (received, published, missed) = match read {
            Read::Copy => {
                let snapshot = client.wait_for_tick(wait)?;
                let t = snapshot.timestamp().platform_timestamp;
                (now_ns(), t, snapshot.missed)
            }
            Read::InPlace => {
                let view = client.wait_for_frame(wait)?;
                (now_ns(), view.timestamp().platform_timestamp, view.missed())
            }
        };
        if missed == 0 {
            latencies.record(received.saturating_sub((published * 1e9) as u64));
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
    let deliveries: Vec<Delivery> = args
        .placement
        .map_or(Placement::ALL.to_vec(), |p| vec![p])
        .into_iter()
        .map(|placement| delivery(&server, placement, args.samples))
        .collect::<anyhow::Result<_>>()?;
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
                "wait_for_tick": deliveries.iter().map(|d| serde_json::json!({
                    "placement": d.placement.name(),
                    "block": d.block.json(),
                    "block_in_place": d.block_in_place.json(),
                    "spin": d.spin.as_ref().map(Latencies::json),
                    "futex_round_trip_every_ms": d.floor.json(),
                    "block_over_futex_hop_p50": d.block_over_hop(),
                })).collect::<Vec<_>>(),
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
        "wait_for_tick latency: frame published -> snapshot in the client ({} samples each, 1 kHz server, empty scene; in place: wait_for_frame, no copy)",
        args.samples
    );
    for d in &deliveries {
        println!("placement: {}", d.placement.name());
        println!("{}", header("wait mode"));
        println!("{}", d.block.row("block (frame-ready event)"));
        println!("{}", d.block_in_place.row("block, in place"));
        match &d.spin {
            Some(spin) => println!("{}", spin.row("spin")),
            None => println!(
                "{:<28} (not on one CPU: the server would get no time)",
                "spin"
            ),
        }
        println!("{}", d.floor.row("futex round trip, one per ms"));
        println!(
            "block / one futex hop (half the round trip) at p50: {:.2}x",
            d.block_over_hop()
        );
        println!();
    }
    crate::scaling::print(&scaling, args.scale_frames);
    println!("load average before the scaling rows: {load}");
    Ok(())
}
