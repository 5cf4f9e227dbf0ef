//! The recorder benchmark's journal and snapshot rows: what journaling
//! costs per frame (`--journal-sync frames:1` and `frames:50` against no
//! journal, side by side), how long a resume takes from a 10-minute
//! journal (a keyframe every 10 s), and how long a snapshot takes to save
//! and restore at 10, 1 000 and 10 000 actors.

use std::path::Path;
use std::time::{Duration, Instant};

use sim_client::Client;

use crate::support::{ticked, BenchServer};

const T: Duration = Duration::from_secs(60);

/// One scene's journal row: µs per frame without a journal, with
/// `frames:50` and with `frames:1` (best of five alternating rounds: this
/// VM's frame times swing by a third from one server to the next), and
/// the floors that explain them, measured in the same run: `frames:1000`
/// (the journal's writing with almost no syncs: what is not the disk's)
/// and one `fdatasync` of the journal's directory's disk
/// ([`fdatasync_floor_us`]), which `frames:50` pays every 25 frames.
pub(crate) fn journal_row(
    scene: &str,
    frames: u64,
    dir: &Path,
) -> anyhow::Result<serde_json::Value> {
    let configs: [(&str, Option<&str>); 4] = [
        ("none", None),
        ("frames:50", Some("frames:50")),
        ("frames:1", Some("frames:1")),
        ("frames:1000", Some("frames:1000")),
    ];
    let mut best = [f64::INFINITY; 4];
    for round in 0..5 {
        for (i, (name, sync)) in configs.iter().enumerate() {
            let journal = dir.join(format!(
                "simbus-bench-journal-{}-{name}-{round}-{}",
                scene.replace(':', "-"),
                std::process::id()
            ));
            let journal_text = journal.to_string_lossy().into_owned();
            let mut args = vec!["--scene", scene, "--sync", "--fps", "20", "--seed", "1"];
            if let Some(sync) = sync {
                args.extend(["--journal", &journal_text, "--journal-sync", sync]);
            }
            let server = BenchServer::start(&format!("journal-{i}"), &args)?;
            let client = Client::connect(&server.world, T)?;
            best[i] = best[i].min(ticked(&client, frames)? * 1e6);
            drop(client);
            server.stop()?;
            let _ = std::fs::remove_dir_all(&journal);
        }
    }
    let fdatasync_us = fdatasync_floor_us(dir)?;
    Ok(serde_json::json!({
        "scene": scene,
        "frames": frames,
        "no_journal_frame_us": best[0],
        "frames_50_frame_us": best[1],
        "frames_1_frame_us": best[2],
        "frames_1000_frame_us": best[3],
        "frames_50_overhead": best[1] / best[0] - 1.0,
        "frames_1_overhead": best[2] / best[0] - 1.0,
        "frames_1000_overhead": best[3] / best[0] - 1.0,
        "fdatasync_floor_us": fdatasync_us,
        // frames:50 syncs every half period: one fdatasync per 25 frames.
        "frames_50_sync_share_us": fdatasync_us / 25.0,
    }))
}

/// The floor of a journal's sync on `dir`'s disk: the median of 25
/// rounds of appending 4 KiB to a file and `fdatasync`ing it, in µs.
pub(crate) fn fdatasync_floor_us(dir: &Path) -> anyhow::Result<f64> {
    use std::io::Write;
    let path = dir.join(format!("simbus-bench-fdatasync-{}", std::process::id()));
    let mut file = std::fs::File::create(&path)?;
    let block = [0x5au8; 4096];
    let mut rounds = Vec::with_capacity(25);
    for _ in 0..25 {
        file.write_all(&block)?;
        let start = Instant::now();
        file.sync_data()?;
        rounds.push(start.elapsed().as_secs_f64() * 1e6);
    }
    drop(file);
    let _ = std::fs::remove_file(&path);
    rounds.sort_by(f64::total_cmp);
    Ok(rounds[rounds.len() / 2])
}

/// Seconds from `sim-server --resume` to its first frame, after a
/// SIGKILL, from a journal of `minutes` simulated minutes of the default
/// scene with a keyframe every 10 s.
pub(crate) fn resume_time(minutes: f64, dir: &Path) -> anyhow::Result<serde_json::Value> {
    let journal = dir.join(format!("simbus-bench-resume-{}", std::process::id()));
    let journal_text = journal.to_string_lossy().into_owned();
    let frames = (minutes * 60.0 * 20.0) as u64;
    let server = BenchServer::start(
        "resume",
        &[
            "--sync",
            "--fps",
            "20",
            "--journal",
            &journal_text,
            "--journal-sync",
            "frames:50",
            "--keyframe-seconds",
            "10",
        ],
    )?;
    let world = server.world.clone();
    let client = Client::connect(&world, T)?;
    let ticking = ticked(&client, frames)?;
    drop(client);
    server.kill()?;
    let started = Instant::now();
    let resumed = BenchServer::resume(&world, &journal_text)?;
    let seconds = started.elapsed().as_secs_f64();
    let mut client = Client::connect(&world, T)?;
    let frame = client.wait_for_tick(T)?.frame();
    drop(client);
    resumed.stop()?;
    let bytes: u64 = std::fs::read_dir(&journal)?
        .filter_map(|e| e.ok()?.metadata().ok())
        .map(|m| m.len())
        .sum();
    let _ = std::fs::remove_dir_all(&journal);
    Ok(serde_json::json!({
        "simulated_minutes": minutes,
        "frames": frames,
        "journal_bytes": bytes,
        "ticked_frame_us": ticking * 1e6,
        "resumed_at": frame,
        "resume_seconds": seconds,
    }))
}

/// Median milliseconds to save and to restore a snapshot of `boxes:N`.
pub(crate) fn snapshot_row(actors: u32) -> anyhow::Result<serde_json::Value> {
    let scene = format!("boxes:{actors}");
    let server = BenchServer::start(
        &format!("snapshot-{actors}"),
        &["--scene", &scene, "--sync", "--fps", "20"],
    )?;
    let client = Client::connect(&server.world, T)?;
    let mut ticker = client.claim_ticker()?;
    for _ in 0..5 {
        ticker.tick(T)?;
    }
    let (mut saves, mut restores) = (Vec::new(), Vec::new());
    for _ in 0..7 {
        let started = Instant::now();
        let id = client.save_snapshot()?;
        saves.push(started.elapsed().as_secs_f64() * 1e3);
        ticker.tick(T)?;
        let started = Instant::now();
        client.restore_snapshot(id)?;
        restores.push(started.elapsed().as_secs_f64() * 1e3);
        client.drop_snapshot(id)?;
        ticker.tick(T)?;
    }
    let median = |v: &mut Vec<f64>| {
        v.sort_by(f64::total_cmp);
        v[v.len() / 2]
    };
    let actor_count = client.status()?.actor_count;
    ticker.release()?;
    drop(client);
    server.stop()?;
    Ok(serde_json::json!({
        "scene": scene,
        "actors": actor_count,
        "save_ms": median(&mut saves),
        "restore_ms": median(&mut restores),
    }))
}
