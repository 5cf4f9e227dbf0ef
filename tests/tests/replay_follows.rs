//! A replay is frames like any other: in synchronous mode its frames get
//! the server's next frame ids (the recorded id travels in the header, and
//! `watch --json` shows both), it starts a new episode, and lockstep
//! participants follow it tick by tick. Waits that have nothing to wait
//! for say so: a replay into a synchronous world nobody ticks is refused at
//! once, and `autopilot` gives up after `--timeout` on a world that stopped
//! (SIGSTOP) or that nobody ticks.

use std::time::{Duration, Instant};

use sim_client::inspect;
use simbus_tests::{send_signal, wait_for_participants, Scratch, TestWorld};

const T: Duration = Duration::from_secs(30);

/// Records `ticks` frames of `world` (synchronous) to `path`; returns the
/// recorded frame ids.
fn record(world: &TestWorld, path: &std::path::Path, ticks: u32) -> Vec<u64> {
    let client = world.connect();
    let mut ticker = client.claim_ticker().expect("claim");
    client.start_recorder(path, false).expect("start recorder");
    for _ in 0..ticks {
        ticker.tick(T).expect("tick");
    }
    client.stop_recorder().expect("stop recorder");
    let info = inspect::file_info(path.to_str().unwrap(), false).expect("recording info");
    (info.first_frame..info.first_frame + info.frames).collect()
}

#[test]
fn a_synchronous_replay_numbers_its_frames_on_and_a_lockstep_watcher_sees_every_one() {
    let world = TestWorld::start("replay-ls", &["--sync", "--delta-seconds", "0.02"]);
    let scratch = Scratch::new("replay-ls");
    let path = scratch.file("ss.mcap");
    let recorded = record(&world, &path, 17);
    assert_eq!(
        recorded.len(),
        18,
        "the frame current at the start and 17 ticked"
    );

    let client = world.connect();
    let watcher = world.spawn_cli(&["watch", "--json", "--lockstep"]);
    wait_for_participants(&client, 1);
    let ticker = world.spawn_cli(&[
        "tick",
        "--rate",
        "50",
        "--count",
        "150",
        "--participants",
        "1",
    ]);
    let next = || -> serde_json::Value {
        let line = watcher.line(T).unwrap_or_else(|| {
            panic!(
                "the lockstep watcher stopped; stderr:\n{}",
                watcher.stderr()
            )
        });
        serde_json::from_str(&line).unwrap_or_else(|e| panic!("not JSON ({e}): {line}"))
    };
    // The ticker runs: live frames come.
    let mut seen = vec![next()];
    while seen.last().unwrap()["frame"].as_u64() < Some(recorded[recorded.len() - 1] + 3) {
        seen.push(next());
    }
    let replay = world.cli(&["replay", path.to_str().unwrap(), "--mode", "exact"]);
    replay.assert_success();
    assert!(
        replay.stdout.iter().any(|l| l.contains("18 of 18 frames")),
        "{replay}"
    );
    // Every replayed frame, then the live world again.
    loop {
        let frame = next();
        let replayed = frame["replay"] == true;
        let past_replay = seen.iter().any(|f| f["replay"] == true) && !replayed;
        seen.push(frame);
        if past_replay {
            break;
        }
    }
    let ids: Vec<u64> = seen.iter().map(|f| f["frame"].as_u64().unwrap()).collect();
    for pair in ids.windows(2) {
        assert_eq!(pair[1], pair[0] + 1, "frame ids go on one by one: {ids:?}");
    }
    let replayed: Vec<&serde_json::Value> = seen.iter().filter(|f| f["replay"] == true).collect();
    let recorded_ids: Vec<u64> = replayed
        .iter()
        .map(|f| {
            f["recorded_frame"]
                .as_u64()
                .expect("a replayed frame names its recorded id")
        })
        .collect();
    assert_eq!(
        recorded_ids, recorded,
        "every recorded frame, once, in order"
    );
    let live = seen.iter().find(|f| f["replay"] == false).unwrap();
    assert!(live["recorded_frame"].is_null(), "{live}");
    // The replay is an episode of its own, and so is the live world after it.
    let first = seen.iter().position(|f| f["replay"] == true).unwrap();
    let last = seen.iter().rposition(|f| f["replay"] == true).unwrap();
    assert_ne!(seen[first - 1]["episode"], seen[first]["episode"]);
    assert_eq!(seen[first]["episode"], seen[last]["episode"]);
    assert_ne!(seen[last]["episode"], seen[last + 1]["episode"]);
    // Simulation time never goes back either.
    let times: Vec<u64> = seen
        .iter()
        .map(|f| f["elapsed_ns"].as_u64().unwrap())
        .collect();
    assert!(times.windows(2).all(|t| t[1] >= t[0]), "{times:?}");
    ticker.finish(T).assert_success();
}

#[test]
fn a_replay_into_a_synchronous_world_nobody_ticks_is_refused_at_once() {
    let world = TestWorld::start("replay-noticker", &["--sync", "--delta-seconds", "0.02"]);
    let scratch = Scratch::new("replay-noticker");
    let path = scratch.file("r.mcap");
    record(&world, &path, 5);
    let started = Instant::now();
    let out = world.cli(&["--timeout", "20", "replay", path.to_str().unwrap()]);
    out.assert_code(1);
    assert!(out.stderr.contains("nobody ticks it"), "{out}");
    assert!(out.stderr.contains("--detach"), "{out}");
    assert!(
        started.elapsed() < Duration::from_secs(20),
        "said at once, not after --timeout"
    );
    // Nothing changed: no replay runs.
    let status = world.connect().recorder_status().unwrap();
    assert_eq!(status.replay.state, "idle", "{status:?}");
}

#[test]
fn autopilot_gives_up_after_its_timeout_and_says_why() {
    // A synchronous world nobody ticks.
    let world = TestWorld::start("autopilot-noticker", &["--sync", "--delta-seconds", "0.02"]);
    let out = world.cli(&["--timeout", "1", "autopilot"]);
    out.assert_code(1);
    assert!(out.stderr.contains("nobody ticks it"), "{out}");

    // A stopped server.
    let world = TestWorld::start("autopilot-stopped", &["--delta-seconds", "0.02"]);
    let client = world.connect();
    let autopilot = world.spawn_cli(&["--timeout", "1", "autopilot"]);
    wait_for_participants(&client, 1);
    send_signal(world.server.pid(), libc::SIGSTOP).unwrap();
    let out = autopilot.finish(T);
    send_signal(world.server.pid(), libc::SIGCONT).unwrap();
    out.assert_code(1);
    assert!(out.stderr.contains("does not answer"), "{out}");
}
