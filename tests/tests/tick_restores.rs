//! `sim-client tick` puts back what it changed: the world's own step
//! always (with --leave-sync too), and the mode the world had before the
//! run (a world started `--sync` stays synchronous, waiting for the next
//! ticker; --leave-sync keeps any world synchronous); its last line says
//! how it left the world. (A `--sync` server was left running free, and
//! the ticker said "as before": a journaling one then wrote its disk full.)

use std::time::Duration;

use simbus_tests::{send_signal, Finished, TestWorld};

/// Asserts the ticker's last line (stderr), which says how it left the
/// world.
fn assert_last_line(ticked: &Finished, expected: &str) {
    assert_eq!(ticked.stderr.lines().last(), Some(expected), "{ticked}");
}

#[test]
fn leave_sync_keeps_synchronous_mode_but_puts_back_the_worlds_own_step() {
    let world = TestWorld::start("tick-own-step", &["--delta-seconds", "0.02"]);
    let ticked = world.cli(&[
        "tick",
        "--delta-seconds",
        "0.05",
        "--count",
        "3",
        "--leave-sync",
    ]);
    ticked.assert_success();
    world.assert_time_settings(true, Some(0.02), "the world's own step is back: ");
    assert_last_line(
        &ticked,
        "tick: 3 ticks; released ownership, world left in synchronous mode with its own step \
         (0.02 s), waiting for the next ticker",
    );

    // The next plain ticker ticks with, and puts back, the world's own
    // step: the earlier --leave-sync lost nothing. The world was
    // synchronous before it, so it stays so.
    let ticked = world.cli(&["tick", "--count", "2"]);
    ticked.assert_success();
    assert!(ticked.stderr.contains("fixed step 0.02 s"), "{ticked}");
    world.assert_time_settings(true, Some(0.02), "");
    assert_last_line(
        &ticked,
        "tick: 2 ticks; released ownership, world left in synchronous mode with its own step \
         (0.02 s), as before, waiting for the next ticker",
    );
}

#[test]
fn leave_sync_on_a_variable_step_world_puts_the_variable_step_back() {
    let world = TestWorld::start("tick-variable", &[]);
    let ticked = world.cli(&["tick", "--count", "2", "--leave-sync"]);
    ticked.assert_success();
    world.assert_time_settings(true, None, "variable again: ");
    assert_last_line(
        &ticked,
        "tick: 2 ticks; released ownership, world left in synchronous mode with its own \
         variable step, waiting for the next ticker",
    );
    // A plain ticker then uses 0.05 s as on a fresh world and leaves the
    // world as it found it: synchronous, with its variable step.
    let ticked = world.cli(&["tick", "--count", "2"]);
    ticked.assert_success();
    assert!(ticked.stderr.contains("fixed step 0.05 s"), "{ticked}");
    world.assert_time_settings(true, None, "");
}

/// Issue 44, item 3: a server started `--sync` stays synchronous after a
/// bounded ticker, waiting for the next one, and the ticker says so; no
/// frame is computed without a tick meanwhile.
#[test]
fn a_world_started_synchronous_stays_synchronous_after_a_ticker_and_computes_nothing() {
    let world = TestWorld::start("tick-sync-server", &["--sync", "--delta-seconds", "0.02"]);
    let ticked = world.cli(&["tick", "--count", "5", "--delta-seconds", "0.02"]);
    ticked.assert_success();
    assert_last_line(
        &ticked,
        "tick: 5 ticks; released ownership, world left in synchronous mode with its own step \
         (0.02 s), as before, waiting for the next ticker",
    );
    world.assert_time_settings(true, Some(0.02), "");
    let frame = world.status()["frame"].as_u64().expect("a frame");
    // A watcher waiting for new frames gets none (at most the one already
    // published): nothing ticks.
    let watched = world.cli(&["--timeout", "1", "watch", "--frames", "2", "--json"]);
    assert_ne!(watched.status.code(), Some(0), "frames came: {watched}");
    for line in watched.json() {
        assert!(line["frame"].as_u64() <= Some(frame), "{watched}");
    }
    assert_eq!(world.status()["frame"].as_u64(), Some(frame));
    // The next ticker takes over from there.
    let ticked = world.cli(&["tick", "--count", "1", "--json"]);
    ticked.assert_success();
    assert_eq!(
        ticked.json()[0]["frame"].as_u64(),
        Some(frame + 1),
        "{ticked}"
    );
}

#[test]
fn tick_says_it_left_the_world_asynchronous_with_its_settings_as_before() {
    let world = TestWorld::start("tick-last-line", &["--delta-seconds", "0.02"]);
    let ticked = world.cli(&["tick", "--delta-seconds", "0.05", "--count", "3"]);
    ticked.assert_success();
    assert_eq!(ticked.stdout.len(), 3, "{ticked}");
    assert_last_line(
        &ticked,
        "tick: 3 ticks; released ownership, world left in asynchronous mode, with its \
         settings as before",
    );
    world.assert_time_settings(false, Some(0.02), "");
}

#[test]
fn a_ticker_stopped_by_a_signal_gives_the_world_back() {
    let world = TestWorld::start("tick-signal", &["--delta-seconds", "0.02"]);
    for (signal, name) in [
        (libc::SIGINT, "SIGINT"),
        (libc::SIGTERM, "SIGTERM"),
        (libc::SIGHUP, "SIGHUP"),
    ] {
        let ticker = world.spawn_cli(&["tick", "--delta-seconds", "0.05"]);
        let first = ticker.line(Duration::from_secs(30));
        assert!(
            first
                .as_deref()
                .is_some_and(|l| l.starts_with("tick  frame")),
            "{name}: {first:?}; stderr:\n{}",
            ticker.stderr()
        );
        send_signal(ticker.pid(), signal).expect("signalling the ticker");
        let ended = ticker.finish(Duration::from_secs(30));
        ended.assert_success();
        assert!(
            ended.stderr.lines().last().is_some_and(
                |l| l.ends_with("world left in asynchronous mode, with its settings as before")
            ),
            "{name}: {ended}"
        );
        world.assert_time_settings(false, Some(0.02), &format!("{name}: "));
    }
}
