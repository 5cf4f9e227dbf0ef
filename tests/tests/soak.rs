//! Soak: a long synchronous run loses nothing and grows nothing.
//!
//! A ticker steps the default scene as fast as it can while 16 watchers and
//! a reader of an IMU follow every frame (lockstep, so none may fall
//! behind). Asserted: every watcher and the reader saw every frame, in
//! order, once; the server's resident memory and its count of shared-memory
//! files are flat once the run has warmed up (sampled as the ticker passes
//! each tenth of the run).
//!
//! CI runs 4 000 frames (flat from frame 1 000); `cargo test --test soak --
//! --ignored` runs the 100 000-frame soak (flat from frame 10 000).

use std::time::Duration;

use simbus_tests::{unique_world, PrivateRoot, Proc};

/// The server's resident set, in KiB.
fn rss_kib(pid: u32) -> u64 {
    std::fs::read_to_string(format!("/proc/{pid}/status"))
        .ok()
        .and_then(|s| {
            s.lines()
                .find(|l| l.starts_with("VmRSS:"))
                .and_then(|l| l.split_whitespace().nth(1)?.parse().ok())
        })
        .expect("the server's VmRSS")
}

/// `seen` is exactly `from..=to`, each once, in order.
fn assert_every_frame(who: &str, seen: &[u64], from: u64, to: u64) {
    let expected = from..=to;
    if let Some((i, (got, want))) = seen
        .iter()
        .zip(expected.clone())
        .enumerate()
        .find(|(_, (got, want))| **got != *want)
    {
        panic!("{who}: item {i} is frame {got}, not {want}");
    }
    assert_eq!(
        seen.len() as u64,
        to - from + 1,
        "{who} saw {} frames, not every frame of {from}..={to}",
        seen.len()
    );
}

fn soak(frames: u64, warm: u64) {
    let root = PrivateRoot::new("soak");
    let world = unique_world("soak");
    let server = root.server(
        &world,
        &[
            "--scene",
            "default",
            "--fixed-delta-seconds",
            "0.01",
            "--sync",
            "--lockstep-timeout",
            "10",
        ],
    );
    let spawn = |args: &[&str]| root.client(&world, "30", args);
    let spawned = spawn(&["sensor", "spawn", "imu", "--json"]).finish(Duration::from_secs(60));
    spawned.assert_success();
    let sensor = spawned.json()[0]["id"]
        .as_u64()
        .expect("sensor id")
        .to_string();
    let count = frames.to_string();
    // Watchers also see frame 0, the world before the first tick.
    let with_first = (frames + 1).to_string();
    let watchers: Vec<Proc> = (0..16)
        .map(|_| spawn(&["watch", "--digest", "--lockstep", "--frames", &with_first]))
        .collect();
    let reader = spawn(&[
        "sensor",
        "watch",
        &sensor,
        "--json",
        "--lockstep",
        "--captures",
        &count,
    ]);
    let ticker = spawn(&[
        "tick",
        "--json",
        "--count",
        &count,
        "--delta-seconds",
        "0.01",
        "--participants",
        "17",
        // Stay synchronous after the last tick: nothing may be stepped
        // (asynchronously, with nobody waiting) behind the followers' backs.
        "--leave-sync",
    ]);

    // Sample the server as the ticker passes each tenth of the run.
    let step = (frames / 10).max(1);
    let mut samples = Vec::new();
    let mut ticked = Vec::new();
    while let Some(line) = ticker.line(Duration::from_secs(60)) {
        let json: serde_json::Value = serde_json::from_str(&line).expect("tick --json");
        let frame = json["frame"].as_u64().expect("frame");
        ticked.push(frame);
        // The last frame is left out: the followers leave as it lands.
        let n = ticked.len() as u64;
        if n.is_multiple_of(step) && n < frames {
            samples.push((
                ticked.len() as u64,
                rss_kib(server.pid()),
                root.shared_memory().len(),
            ));
        }
        if ticked.len() as u64 == frames {
            break;
        }
    }
    assert_eq!(ticked.len() as u64, frames, "the ticker stopped early");
    let ticker = ticker.finish(Duration::from_secs(30));
    ticker.assert_success();
    let (first, last) = (ticked[0], ticked[ticked.len() - 1]);

    for (i, watcher) in watchers.into_iter().enumerate() {
        let done = watcher.finish(Duration::from_secs(60));
        done.assert_success();
        let seen: Vec<u64> = done
            .stdout
            .iter()
            .filter_map(|l| l.strip_prefix("frame ")?.split(' ').next()?.parse().ok())
            .collect();
        assert_every_frame(&format!("watcher {i}"), &seen, first - 1, last);
    }
    let reader = reader.finish(Duration::from_secs(60));
    reader.assert_success();
    let captured: Vec<u64> = reader
        .json()
        .iter()
        .filter_map(|j| j["frame"].as_u64())
        .collect();
    assert_every_frame("the sensor reader", &captured, first, last);

    // Flat from the warm-up on: the same shared-memory files, and resident
    // memory within 1 MiB (a leak of 16 bytes a frame over the 90 000
    // frames after warm-up would exceed it).
    let warmed: Vec<&(u64, u64, usize)> = samples.iter().filter(|s| s.0 >= warm).collect();
    assert!(warmed.len() >= 2, "too few samples: {samples:?}");
    let (_, rss0, files0) = *warmed[0];
    for &&(frame, rss, files) in &warmed {
        assert_eq!(
            files, files0,
            "shared-memory files went from {files0} to {files} by frame {frame}: {samples:?}"
        );
        assert!(
            rss <= rss0 + 1024,
            "the server's RSS grew from {rss0} KiB to {rss} KiB by frame {frame}: {samples:?}"
        );
    }
    eprintln!("soak: {frames} frames; (frame, server RSS KiB, shm files): {samples:?}");
    drop(server);
}

#[test]
fn a_long_sync_run_loses_no_frame_and_grows_nothing() {
    soak(4_000, 1_000);
}

#[test]
#[ignore = "100 000 frames: run by bench/run-fault-suite or with --ignored"]
fn soak_of_a_hundred_thousand_frames() {
    soak(100_000, 10_000);
}
