//! Asynchronous mode: every watcher sees the same frames, fixed-step time is
//! exact to the nanosecond thousands of frames in, and variable-step deltas
//! sum exactly to the elapsed time, which follows wall time.

use std::collections::BTreeMap;
use std::time::Duration;

use serde_json::Value;
use simbus_tests::{client, Proc, TestWorld};

fn u64_of(v: &Value, key: &str) -> u64 {
    v[key]
        .as_u64()
        .unwrap_or_else(|| panic!("{key} missing in {v}"))
}

#[test]
fn three_watchers_of_a_realtime_server_see_the_same_consecutive_frames() {
    let world = TestWorld::start(
        "watchers",
        &[
            "--realtime",
            "--fixed-delta-seconds",
            "0.1",
            "--scene",
            "default",
        ],
    );
    // --every-frame: 16 queued frames (1.6 s) of slack for a watcher the
    // machine schedules late, instead of skipping to the newest frame.
    let watchers: Vec<Proc> = (0..3)
        .map(|_| {
            Proc::spawn(
                "sim-client",
                &[
                    "--world",
                    &world,
                    "watch",
                    "--frames",
                    "30",
                    "--json",
                    "--every-frame",
                ],
            )
        })
        .collect();
    let runs: Vec<Vec<Value>> = watchers
        .into_iter()
        .map(|w| {
            let out = w.finish(Duration::from_secs(60));
            out.assert_success();
            out.json()
        })
        .collect();

    let mut by_frame: BTreeMap<u64, Vec<&Value>> = BTreeMap::new();
    for run in &runs {
        assert_eq!(run.len(), 30);
        for pair in run.windows(2) {
            assert_eq!(
                u64_of(&pair[1], "frame"),
                u64_of(&pair[0], "frame") + 1,
                "frames are consecutive"
            );
            assert_eq!(u64_of(&pair[1], "missed"), 0);
        }
        for frame in run {
            by_frame
                .entry(u64_of(frame, "frame"))
                .or_default()
                .push(frame);
        }
    }
    let shared: Vec<_> = by_frame.values().filter(|seen| seen.len() == 3).collect();
    assert!(
        shared.len() >= 20,
        "the watchers overlap on {} frames only",
        shared.len()
    );
    for seen in shared {
        assert!(
            seen.iter().all(|f| *f == seen[0]),
            "every watcher sees the same frame: {seen:?}"
        );
    }
}

#[test]
fn unpaced_fixed_step_time_is_exact_thousands_of_frames_in() {
    let world = TestWorld::start(
        "exact",
        &["--fixed-delta-seconds", "0.01", "--scene", "default"],
    );
    // The server runs flat out; wait (on its frames) until it is far ahead.
    let mut api = sim_client::Client::connect(&world, Duration::from_secs(20)).unwrap();
    while api.wait_for_frame(Duration::from_secs(20)).unwrap().frame() <= 2000 {}
    drop(api);
    let out = client(&world, &["watch", "--frames", "200", "--json"]);
    out.assert_success();
    let frames = out.json();
    assert_eq!(frames.len(), 200);
    assert!(
        u64_of(&frames[0], "frame") > 1000,
        "thousands of frames in: {}",
        frames[0]
    );
    for f in &frames {
        let frame = u64_of(f, "frame");
        assert_eq!(u64_of(f, "elapsed_ns"), frame * 10_000_000, "{f}");
        assert_eq!(u64_of(f, "delta_ns"), 10_000_000, "{f}");
        assert_eq!(f["delta_seconds"].as_f64(), Some(0.01));
        assert_eq!(u64_of(f, "physics_substeps"), 1);
    }
}

#[test]
fn variable_step_deltas_sum_to_elapsed_and_follow_wall_time() {
    let world = TestWorld::start("variable", &["--max-fps", "50"]);
    let out = client(
        &world,
        &["watch", "--frames", "60", "--json", "--every-frame"],
    );
    out.assert_success();
    let frames = out.json();
    let mut checked = 0;
    for pair in frames.windows(2) {
        if u64_of(&pair[1], "missed") == 0 {
            assert_eq!(
                u64_of(&pair[1], "elapsed_ns"),
                u64_of(&pair[0], "elapsed_ns") + u64_of(&pair[1], "delta_ns"),
                "consecutive frames: elapsed grows by exactly delta"
            );
            checked += 1;
        }
        assert_eq!(pair[1]["fixed_delta_seconds"], Value::Null);
    }
    assert!(checked >= 30, "only {checked} consecutive pairs");
    let (first, last) = (&frames[0], &frames[frames.len() - 1]);
    let sim = (u64_of(last, "elapsed_ns") - u64_of(first, "elapsed_ns")) as f64 * 1e-9;
    let wall = last["platform_timestamp"].as_f64().unwrap()
        - first["platform_timestamp"].as_f64().unwrap();
    assert!(
        (sim - wall).abs() < 0.05 + 0.1 * wall,
        "simulation time {sim} s follows wall time {wall} s"
    );
}
