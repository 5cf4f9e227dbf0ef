//! The CLI rides through a server's crash and resume as the library does
//! (issue 44, items 1 and 9): `sim-client tick` on a journaling world waits
//! for the server resumed from its journal, claims it again and ticks on,
//! no frame skipped or printed twice; a fresh server (another run) ends it
//! with a clear message and is left as it is. `watch --digest
//! --follow-restarts` prints each frame once across the restart, and the
//! resumed server publishes the frame it resumed at as it was first
//! published (its substeps), not as a frame of no physics.

use std::time::{Duration, Instant};

use serde_json::Value;
use simbus_tests::*;

const LONG: Duration = Duration::from_secs(60);

/// A synchronous 20 FPS world journaling into `dir`, with `extra` flags.
fn journaling_with(tag: &str, dir: &std::path::Path, extra: &[&str]) -> TestWorld {
    let mut args = vec!["--sync", "--fps", "20", "--journal", dir.to_str().unwrap()];
    args.extend_from_slice(extra);
    TestWorld::start(tag, &args)
}

/// A synchronous 20 FPS world journaling into `dir`.
fn journaling(tag: &str, dir: &std::path::Path) -> TestWorld {
    journaling_with(tag, dir, &[])
}

/// SIGKILLs `world`'s server and resumes it from its journal in `dir`;
/// the resumed server, up.
fn kill_and_resume(world: &mut TestWorld, dir: &std::path::Path) -> Proc {
    world.server.guard.kill().expect("SIGKILL the server");
    let resumed = Proc::spawn("sim-server", &["--resume", dir.to_str().unwrap()]);
    wait_until_up(world.name(), &resumed);
    resumed
}

/// Waits for `ticker` to end by itself, successfully; its run and every
/// frame it printed, `before` (the lines already read) first.
fn ticked_frames(ticker: Proc, mut before: Vec<Value>) -> (Finished, Vec<u64>) {
    let done = ticker.finish(LONG);
    done.assert_success();
    before.extend(done.json());
    let ticked = frames(&before);
    assert_consecutive(&ticked, &done);
    (done, ticked)
}

/// The frame of each JSON line of a ticker or a watcher that has one.
fn frames(lines: &[Value]) -> Vec<u64> {
    lines.iter().filter_map(|l| l["frame"].as_u64()).collect()
}

/// Reads `proc`'s JSON lines until one's frame reaches `frame`.
fn read_until(proc: &Proc, frame: u64) -> Vec<Value> {
    let deadline = Instant::now() + LONG;
    let mut lines = Vec::new();
    loop {
        let line = proc
            .line(deadline.saturating_duration_since(Instant::now()))
            .unwrap_or_else(|| panic!("no frame {frame}; stderr:\n{}", proc.stderr()));
        let line: Value = serde_json::from_str(&line).expect("a JSON line");
        let reached = line["frame"].as_u64().is_some_and(|f| f >= frame);
        lines.push(line);
        if reached {
            return lines;
        }
    }
}

/// Asserts `frames` go up one at a time: none skipped, none repeated.
fn assert_consecutive(frames: &[u64], context: &dyn std::fmt::Display) {
    for pair in frames.windows(2) {
        assert_eq!(pair[1], pair[0] + 1, "{frames:?}\n{context}");
    }
}

#[test]
fn a_cli_ticker_and_a_digest_watch_ride_through_a_resume_without_a_frame_skipped_or_repeated() {
    let scratch = Scratch::new("tick-follows");
    let dir = scratch.file("j");
    let mut world = journaling("tick-follows", &dir);
    let name = world.name().to_owned();
    // The watcher holds every frame (lockstep), so its digest list has no
    // gap to stop at.
    let watcher = world.spawn_cli(&[
        "--timeout",
        "60",
        "watch",
        "--digest",
        "--lockstep",
        "--follow-restarts",
    ]);
    let ticker = world.spawn_cli(&[
        "--timeout",
        "30",
        "tick",
        "--count",
        "120",
        "--rate",
        "200",
        "--participants",
        "1",
        "--json",
    ]);
    let printed = read_until(&ticker, 30);
    let _resumed = kill_and_resume(&mut world, &dir);
    let (done, ticked) = ticked_frames(ticker, printed);
    assert_eq!(ticked.len(), 120, "every tick counted once: {done}");
    assert!(done.stderr.contains("ticking on"), "{done}");
    // Left as it was: synchronous, waiting for the next ticker.
    assert_eq!(status(&name)["synchronous_mode"], true);

    simbus_process::send_signal(watcher.pid(), libc::SIGINT).unwrap();
    let watched = watcher.finish(LONG);
    watched.assert_success();
    let digests: Vec<u64> = watched
        .stdout
        .iter()
        .filter_map(|l| l.strip_prefix("frame "))
        .map(|l| l.split(' ').next().unwrap().parse().unwrap())
        .collect();
    assert_eq!(
        watched
            .stdout
            .iter()
            .filter(|l| l.starts_with("restarted"))
            .count(),
        1,
        "{watched}"
    );
    assert_consecutive(&digests, &watched);
    assert!(
        digests.contains(ticked.last().unwrap()),
        "the watcher saw the last frame: {watched}"
    );
}

#[test]
fn a_cli_ticker_ends_when_a_fresh_server_takes_the_world_and_leaves_it_as_it_is() {
    let scratch = Scratch::new("tick-fresh");
    let dir = scratch.file("j");
    let mut world = journaling("tick-fresh", &dir);
    let name = world.name().to_owned();
    let ticker = world.spawn_cli(&["--timeout", "30", "tick", "--rate", "100", "--json"]);
    read_until(&ticker, 5);

    world.server.guard.kill().expect("SIGKILL the server");
    // Another run on the same world: not a resume of the journal.
    let fresh = server(&name, &["--delta-seconds", "0.02"]);
    wait_until_up(&name, &fresh);

    let done = ticker.finish(LONG);
    done.assert_code(1);
    assert!(
        done.stderr.contains("a fresh server")
            && done.stderr.contains("not a resume of this run")
            && done.stderr.contains("ticking ended after frame"),
        "{done}"
    );
    // The fresh world is as it started: asynchronous, its own step, no
    // ticker.
    let now = status(&name);
    assert_eq!(now["synchronous_mode"], false, "{now}");
    assert_eq!(now["fixed_delta_seconds"], 0.02, "{now}");
    assert_eq!(now["ticker"], Value::Null, "{now}");
}

#[test]
fn a_resumed_server_publishes_its_first_frame_with_the_substeps_it_was_computed_with() {
    let scratch = Scratch::new("resume-substeps");
    let dir = scratch.file("j");
    let mut world = journaling("resume-substeps", &dir);
    let name = world.name().to_owned();
    let ticked = world.cli(&["tick", "--count", "10", "--json"]);
    ticked.assert_success();
    let last = *frames(&ticked.json()).last().unwrap();
    let before = world.cli(&["watch", "--frames", "1", "--json"]);
    before.assert_success();
    let before = &before.json()[0];
    assert_eq!(before["frame"].as_u64(), Some(last), "{before}");
    // 0.05 s in substeps of at most 0.01 s.
    assert_eq!(before["physics_substeps"], 5, "{before}");

    let _resumed = kill_and_resume(&mut world, &dir);
    let after = client(&name, &["watch", "--frames", "1", "--json"]);
    after.assert_success();
    let after = &after.json()[0];
    assert_eq!(after["frame"].as_u64(), Some(last), "{after}");
    assert_eq!(
        after["physics_substeps"], before["physics_substeps"],
        "{after}"
    );
    assert_eq!(after["digest"], before["digest"], "{after}");
}

/// The bytes of every file in `dir`.
fn bytes_in(dir: &std::path::Path) -> u64 {
    std::fs::read_dir(dir)
        .unwrap()
        .map(|e| e.unwrap().metadata().unwrap().len())
        .sum()
}

/// Issue 44 ("also high"): a journaling world started `--sync` does not run
/// free once a bounded ticker ends, nor one stopped by SIGTERM: nothing is
/// computed and the journal does not grow (it grew by ~53 MB/s, the world
/// going from frame 0 to 68 210 in a second).
#[test]
fn a_journaling_synchronous_world_computes_and_journals_nothing_after_its_ticker_ends() {
    let scratch = Scratch::new("journal-idle");
    let dir = scratch.file("j");
    let world = journaling("journal-idle", &dir);
    world.cli(&["tick", "--count", "5"]).assert_success();
    let ticker = world.spawn_cli(&["tick", "--json"]);
    ticker.line(LONG).expect("a first tick");
    simbus_process::send_signal(ticker.pid(), libc::SIGTERM).unwrap();
    ticker.finish(LONG).assert_success();

    let before = status(world.name());
    assert_eq!(before["synchronous_mode"], true, "{before}");
    let bytes = bytes_in(&dir);
    // A second in which nothing may happen: a watcher waits for new frames.
    let watched = world.cli(&["--timeout", "1", "watch", "--frames", "2", "--json"]);
    assert!(!watched.status.success(), "frames came: {watched}");
    let after = status(world.name());
    assert_eq!(after["frame"], before["frame"], "{after}");
    assert_eq!(bytes_in(&dir), bytes, "the journal grew");
}

/// Ctrl-C while the ticker waits for its server to be resumed ends it as
/// an interruption (exit 130) that says there was nothing to give back.
#[test]
fn a_cli_ticker_waiting_for_a_resume_is_interrupted_with_exit_130() {
    let scratch = Scratch::new("tick-wait-int");
    let dir = scratch.file("j");
    let mut world = journaling("tick-wait-int", &dir);
    let ticker = world.spawn_cli(&["--timeout", "30", "tick", "--rate", "100", "--json"]);
    read_until(&ticker, 3);
    world.server.guard.kill().expect("SIGKILL the server");
    ticker.wait_stderr("to be resumed from its journal", LONG);
    simbus_process::send_signal(ticker.pid(), libc::SIGINT).unwrap();
    let done = ticker.finish(LONG);
    done.assert_code(130);
    assert!(
        done.stderr
            .contains("there was no server to give the world back to"),
        "{done}"
    );
}

/// A journal that makes only every 50th frame durable resumes behind the
/// frames the ticker printed: those are computed again, and printed and
/// counted once.
#[test]
fn a_cli_ticker_resumed_behind_its_printed_frames_prints_each_frame_once() {
    let scratch = Scratch::new("tick-behind");
    let dir = scratch.file("j");
    let mut world = journaling_with("tick-behind", &dir, &["--journal-sync", "frames:50"]);
    let ticker = world.spawn_cli(&[
        "--timeout",
        "30",
        "tick",
        "--count",
        "150",
        "--rate",
        "200",
        "--json",
    ]);
    let printed = read_until(&ticker, 70);
    let _resumed = kill_and_resume(&mut world, &dir);
    let (done, ticked) = ticked_frames(ticker, printed);
    assert_eq!(ticked.len(), 150, "{done}");
    // It did resume behind: the restart line names a frame before the last
    // printed one.
    let resumed_at: u64 = done
        .stderr
        .split("the world resumed at frame ")
        .nth(1)
        .and_then(|rest| rest.split(' ').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("{done}"));
    assert!(resumed_at < 70, "resumed at {resumed_at}: {done}");
}
