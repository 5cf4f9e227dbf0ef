//! `recorder`: what recording costs and how fast recordings play back.
//!
//! For the default scene and `boxes:1000`, in one run, each on a synchronous
//! server in its own process driven by ticks from here: the frame time
//! without and with recording (their ratio is the overhead), the bytes per
//! frame and the compression ratio, then the same recording replayed
//! `exact` and re-simulated (`resimulate`), one recorded frame per tick,
//! next to the live frame time. `--big-gib N` also records `boxes:1000`
//! until the file passes N GiB and reads it back (no size limit short of
//! the disk); it is slow and not part of CI.

use std::path::{Path, PathBuf};
use std::time::{Duration, Instant};

use clap::Args;
use shared_types::ReplayMode;
use sim_client::{Client, ReplayOptions};
use simbus_recording::inspect;

use crate::support::{load_average, ticked, BenchServer};

const T: Duration = Duration::from_secs(60);

#[derive(Debug, Args)]
pub(crate) struct RecorderArgs {
    /// Frames ticked per measurement on the default scene (boxes:1000 gets a fifth).
    #[arg(long, default_value_t = 1000)]
    frames: u64,
    /// Also record boxes:1000 until the file passes this many GiB.
    #[arg(long, value_name = "GIB")]
    big_gib: Option<f64>,
    /// Where the recordings go (deleted afterwards).
    #[arg(long, default_value = "/tmp")]
    dir: PathBuf,
    /// Print one JSON object instead of tables.
    #[arg(long)]
    json: bool,
    /// Simulated minutes of the journal the resume row resumes from.
    #[arg(long, default_value_t = 10.0)]
    resume_minutes: f64,
    /// Leave out the journal, resume and snapshot rows.
    #[arg(long)]
    no_journal: bool,
}

/// Ticks until the replay started on `client` ends; seconds per frame.
fn ticked_replay(
    client: &Client,
    path: &Path,
    mode: ReplayMode,
) -> anyhow::Result<(f64, u64, Option<u64>)> {
    let options = ReplayOptions {
        mode: Some(mode),
        ..Default::default()
    };
    let total = client.replay(path, &options)?.replay.total;
    let mut ticker = client.claim_ticker()?;
    let started = Instant::now();
    for _ in 0..total {
        ticker.tick(T)?;
    }
    let seconds = started.elapsed().as_secs_f64() / total as f64;
    ticker.release()?;
    let status = client.recorder_status()?;
    anyhow::ensure!(status.replay.state == "finished", "replay {status:?}");
    Ok((seconds, total, status.replay.mismatch.map(|m| m.frame)))
}

struct SceneFigures {
    scene: &'static str,
    frames: u64,
    live_us: f64,
    recording_us: f64,
    stop_ms: f64,
    bytes: u64,
    compression: f64,
    exact_us: f64,
    resimulate_us: f64,
    identical: bool,
    /// Asynchronous replay at time factor 10: (wall seconds, expected).
    pacing: (f64, f64),
}

fn measure(scene: &'static str, frames: u64, dir: &Path) -> anyhow::Result<SceneFigures> {
    let server = BenchServer::start(
        &format!("rec-{}", scene.replace(':', "-")),
        &[
            "--scene",
            scene,
            "--sync",
            "--delta-seconds",
            "0.05",
            "--seed",
            "1",
        ],
    )?;
    let client = Client::connect(&server.world, T)?;
    let path = dir.join(format!(
        "simbus-bench-{}-{}.mcap",
        scene.replace(':', "-"),
        std::process::id()
    ));
    // Side by side, twice each, alternating: live, recording, live, recording.
    let (mut live, mut recording, mut stop) = (Vec::new(), Vec::new(), 0.0);
    for round in 0..2 {
        live.push(ticked(&client, frames)?);
        client.start_recorder(&path, false)?;
        recording.push(ticked(&client, frames)?);
        let stopping = Instant::now();
        client.stop_recorder()?;
        stop = stopping.elapsed().as_secs_f64() * 1e3;
        if round == 0 {
            std::fs::remove_file(&path)?;
        }
    }
    let best = |v: &[f64]| v.iter().copied().fold(f64::INFINITY, f64::min) * 1e6;
    let info = inspect::file_info(path.to_str().unwrap_or_default(), false)?;
    let (exact, _, _) = ticked_replay(&client, &path, ReplayMode::Exact)?;
    let (resimulate, _, mismatch) = ticked_replay(&client, &path, ReplayMode::Resimulate)?;
    let pacing = paced(&path, 10.0)?;
    std::fs::remove_file(&path)?;
    Ok(SceneFigures {
        scene,
        frames: info.frames,
        live_us: best(&live),
        recording_us: best(&recording),
        stop_ms: stop,
        bytes: info.bytes,
        compression: info.compression_ratio,
        exact_us: exact * 1e6,
        resimulate_us: resimulate * 1e6,
        identical: mismatch.is_none(),
        pacing,
    })
}

/// Wall seconds an asynchronous exact replay of `path` takes at `factor`,
/// against the recording's own length over the factor.
fn paced(path: &Path, factor: f64) -> anyhow::Result<(f64, f64)> {
    let server = BenchServer::start("rec-pace", &[])?;
    let client = Client::connect(&server.world, T)?;
    let info = inspect::file_info(path.to_str().unwrap_or_default(), false)?;
    let options = ReplayOptions {
        mode: Some(ReplayMode::Exact),
        time_factor: factor,
        ..Default::default()
    };
    client.replay(path, &options)?;
    let started = Instant::now();
    while client.recorder_status()?.replay.state == "running" {
        std::thread::sleep(Duration::from_millis(1));
    }
    Ok((
        started.elapsed().as_secs_f64(),
        info.duration_seconds / factor,
    ))
}

/// Records boxes:1000 until the file passes `gib` GiB, then reads it back.
fn big(gib: f64, dir: &Path) -> anyhow::Result<serde_json::Value> {
    let server = BenchServer::start(
        "rec-big",
        &["--scene", "boxes:1000", "--sync", "--delta-seconds", "0.05"],
    )?;
    let client = Client::connect(&server.world, T)?;
    let path = dir.join(format!("simbus-bench-big-{}.mcap", std::process::id()));
    let limit = (gib * (1u64 << 30) as f64) as u64;
    client.start_recorder(&path, false)?;
    let mut ticker = client.claim_ticker()?;
    let started = Instant::now();
    let mut frames = 0u64;
    while std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0) < limit {
        for _ in 0..100 {
            ticker.tick(T)?;
        }
        frames += 100;
    }
    ticker.release()?;
    client.stop_recorder()?;
    let record_s = started.elapsed().as_secs_f64();
    let reading = Instant::now();
    let info = inspect::file_info(path.to_str().unwrap_or_default(), false)?;
    let read_s = reading.elapsed().as_secs_f64();
    // A replay from near the end seeks through the whole file.
    let seeking = Instant::now();
    client.replay(
        &path,
        &ReplayOptions {
            start: -1.0,
            ..Default::default()
        },
    )?;
    let seek_s = seeking.elapsed().as_secs_f64();
    client.stop_replayer(false)?;
    std::fs::remove_file(&path)?;
    anyhow::ensure!(
        info.frames == frames + 1,
        "{} frames read of {}",
        info.frames,
        frames + 1
    );
    Ok(serde_json::json!({
        "bytes": info.bytes, "frames": info.frames, "record_seconds": record_s,
        "info_seconds": read_s, "replay_start_seconds": seek_s,
    }))
}

pub(crate) fn run(args: RecorderArgs) -> anyhow::Result<()> {
    let load_before = load_average();
    let scenes = [
        measure("default", args.frames, &args.dir)?,
        measure("boxes:1000", (args.frames / 5).max(10), &args.dir)?,
    ];
    let big = args.big_gib.map(|gib| big(gib, &args.dir)).transpose()?;
    let durability = if args.no_journal {
        serde_json::Value::Null
    } else {
        let journal = [
            crate::journal::journal_row("default", args.frames, &args.dir)?,
            crate::journal::journal_row("boxes:1000", (args.frames / 5).max(10), &args.dir)?,
        ];
        let resume = crate::journal::resume_time(args.resume_minutes, &args.dir)?;
        let snapshots = [10, 1000, 10000]
            .into_iter()
            .map(crate::journal::snapshot_row)
            .collect::<anyhow::Result<Vec<_>>>()?;
        serde_json::json!({"journal": journal, "resume": resume, "snapshots": snapshots})
    };
    if args.json {
        let rows: Vec<_> = scenes
            .iter()
            .map(|s| {
                serde_json::json!({
                    "scene": s.scene, "frames": s.frames,
                    "live_frame_us": s.live_us, "recording_frame_us": s.recording_us,
                    "overhead_ratio": s.recording_us / s.live_us, "stop_ms": s.stop_ms,
                    "bytes": s.bytes, "bytes_per_frame": s.bytes as f64 / s.frames as f64,
                    "compression_ratio": s.compression,
                    "exact_replay_frame_us": s.exact_us, "resimulate_frame_us": s.resimulate_us,
                    "exact_replay_fps": 1e6 / s.exact_us, "resimulate_fps": 1e6 / s.resimulate_us,
                    "live_fps": 1e6 / s.live_us, "resimulation_identical": s.identical,
                    "async_replay_x10_seconds": s.pacing.0, "async_replay_x10_expected_seconds": s.pacing.1,
                })
            })
            .collect();
        println!(
            "{}",
            serde_json::json!({"load_average_before": load_before, "load_average_after": load_average(), "scenes": rows, "big": big, "durability": durability})
        );
        return Ok(());
    }
    println!("recorder (sync, fixed 0.05 s, one tick per frame; load average {load_before} before, {} after)", load_average());
    println!(
        "{:<12} {:>7} {:>10} {:>10} {:>8} {:>10} {:>8} {:>10} {:>10} {:>10}",
        "scene",
        "frames",
        "live µs",
        "record µs",
        "ratio",
        "B/frame",
        "zstd",
        "exact µs",
        "resim µs",
        "identical"
    );
    for s in &scenes {
        println!(
            "{:<12} {:>7} {:>10.1} {:>10.1} {:>8.2} {:>10.0} {:>7.1}x {:>10.1} {:>10.1} {:>10}",
            s.scene,
            s.frames,
            s.live_us,
            s.recording_us,
            s.recording_us / s.live_us,
            s.bytes as f64 / s.frames as f64,
            s.compression,
            s.exact_us,
            s.resimulate_us,
            s.identical
        );
    }
    for s in &scenes {
        println!(
            "{}: live {:.0} frames/s, exact replay {:.0} frames/s ({:.1}x live), re-simulation {:.0} frames/s; stopping the recorder took {:.1} ms; an asynchronous replay at time factor 10 took {:.3} s for {:.3} s expected",
            s.scene,
            1e6 / s.live_us,
            1e6 / s.exact_us,
            s.live_us / s.exact_us,
            1e6 / s.resimulate_us,
            s.stop_ms,
            s.pacing.0,
            s.pacing.1
        );
    }
    if let Some(big) = big {
        println!("big recording: {big}");
    }
    if !durability.is_null() {
        print_durability(&durability);
    }
    Ok(())
}

/// The journal, resume and snapshot rows as tables.
fn print_durability(d: &serde_json::Value) {
    let f = |v: &serde_json::Value, k: &str| v[k].as_f64().unwrap_or(f64::NAN);
    println!("journal (sync, 20 FPS, µs per ticked frame; best of five alternating rounds)");
    println!(
        "{:<12} {:>10} {:>12} {:>8} {:>12} {:>8} {:>14} {:>8} {:>12}",
        "scene",
        "none µs",
        "frames:50 µs",
        "+%",
        "frames:1 µs",
        "+%",
        "frames:1000 µs",
        "+%",
        "fdatasync µs"
    );
    for row in d["journal"].as_array().into_iter().flatten() {
        println!(
            "{:<12} {:>10.1} {:>12.1} {:>7.1}% {:>12.1} {:>7.1}% {:>14.1} {:>7.1}% {:>12.1}",
            row["scene"].as_str().unwrap_or(""),
            f(row, "no_journal_frame_us"),
            f(row, "frames_50_frame_us"),
            f(row, "frames_50_overhead") * 100.0,
            f(row, "frames_1_frame_us"),
            f(row, "frames_1_overhead") * 100.0,
            f(row, "frames_1000_frame_us"),
            f(row, "frames_1000_overhead") * 100.0,
            f(row, "fdatasync_floor_us"),
        );
    }
    let r = &d["resume"];
    println!(
        "resume after SIGKILL from a {:.0}-minute journal ({} frames, {:.1} MB, keyframe every 10 s): {:.3} s to the first frame (resumed at frame {})",
        f(r, "simulated_minutes"),
        r["frames"],
        f(r, "journal_bytes") / 1e6,
        f(r, "resume_seconds"),
        r["resumed_at"]
    );
    println!("snapshots (median of 7, request round trip included)");
    for row in d["snapshots"].as_array().into_iter().flatten() {
        println!(
            "{:<12} {:>6} actors  save {:>8.2} ms  restore {:>8.2} ms",
            row["scene"].as_str().unwrap_or(""),
            row["actors"],
            f(row, "save_ms"),
            f(row, "restore_ms")
        );
    }
}
