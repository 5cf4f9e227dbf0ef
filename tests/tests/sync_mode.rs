//! Synchronous mode and the single-ticker rule: nothing moves without a
//! tick, each tick is exactly one frame published before `tick` returns,
//! subscribers that drain between ticks see every frame once, a second
//! ticker is refused by the transport with the owner named, a dead ticker is
//! replaced with no frame skipped or repeated, and nobody ever hangs.

use std::time::Duration;

use serde_json::Value;
use shared_types::WorldSettings;
use sim_client::{Client, TickError, Ticker, WaitError, WaitMode};
use simbus_tests::{
    assert_fails_without_server, client, server, status, unique_world, Proc, TestWorld,
};

const T: Duration = Duration::from_secs(10);

/// Claims the ticker of `world` and enters synchronous mode with `dt`.
fn sync_ticker(client: &Client, dt: f64) -> Ticker {
    let mut ticker = client.claim_ticker().expect("claim");
    let settings = WorldSettings {
        synchronous_mode: true,
        fixed_delta_seconds: Some(dt),
        ..client.get_settings().unwrap()
    };
    ticker.apply_settings(settings).expect("enter sync");
    ticker
}

fn frame_of(line: &str) -> u64 {
    let v: Value = serde_json::from_str(line).unwrap_or_else(|e| panic!("{e}: {line}"));
    v["frame"].as_u64().unwrap()
}

#[test]
fn nothing_moves_without_a_tick_and_each_tick_publishes_exactly_one_frame() {
    let world = TestWorld::start("one-frame", &["--fixed-delta-seconds", "0.01"]);
    let mut client = Client::connect(&world, T).unwrap();
    let mut ticker = client.claim_ticker().expect("claim");
    let first = ticker
        .apply_settings(WorldSettings {
            synchronous_mode: true,
            fixed_delta_seconds: Some(0.02),
            ..client.get_settings().unwrap()
        })
        .expect("enter sync");
    // The world stopped at the frame before the first one computed with
    // the new settings: read the asynchronous frames up to it.
    let frozen = first - 1;
    loop {
        let frame = client
            .wait_for_tick(T)
            .expect("the frames up to the change")
            .frame();
        assert!(
            frame <= frozen,
            "frame {frame} after the world stopped at {frozen}"
        );
        if frame == frozen {
            break;
        }
    }
    // Then no frame comes, however long one waits for it.
    let waited = client.wait_for_tick(Duration::from_millis(300));
    assert!(
        matches!(waited, Err(WaitError::Timeout { .. })),
        "a frame without a tick: {waited:?}"
    );
    assert_eq!(status(&world)["frame"].as_u64(), Some(frozen));
    let start_ns = client.status().unwrap().elapsed_ns;

    for i in 1..=50u64 {
        // Every wait mode ticks the same way.
        ticker.set_wait_mode([WaitMode::Block, WaitMode::Spin, WaitMode::Hybrid][i as usize % 3]);
        let frame = ticker.tick(T).unwrap();
        assert_eq!(frame, frozen + i);
        // tick() returned, so the snapshot is already published.
        let snapshot = client.wait_for_tick(Duration::from_millis(500)).unwrap();
        assert_eq!(snapshot.frame(), frame);
        assert_eq!(snapshot.missed, 0);
        assert_eq!(snapshot.timestamp().delta_ns, 20_000_000);
        assert_eq!(snapshot.timestamp().elapsed_ns, start_ns + i * 20_000_000);
        assert!(snapshot.settings().synchronous_mode);
    }
    assert_eq!(status(&world)["frame"].as_u64(), Some(frozen + 50));
}

#[test]
fn three_subscribers_see_every_frame_once_in_order_across_1000_ticks() {
    let world = TestWorld::start(
        "subscribers",
        &["--fixed-delta-seconds", "0.01", "--scene", "boxes:10"],
    );
    let client = Client::connect(&world, T).unwrap();
    let mut ticker = sync_ticker(&client, 0.01);
    let frozen = status(&world)["frame"].as_u64().unwrap();
    let watchers: Vec<Proc> = (0..3)
        .map(|_| Proc::spawn("sim-client", &["--world", &world, "watch", "--json"]))
        .collect();
    // Each watcher starts with the current frame (the service keeps one).
    for w in &watchers {
        let first = w.line(T).expect("watcher connected");
        assert_eq!(frame_of(&first), frozen);
    }
    for i in 1..=1000 {
        let frame = ticker.tick(T).unwrap();
        assert_eq!(frame, frozen + i);
        // The subscribers drain before the next tick: each sees this frame next.
        for w in &watchers {
            let line = w.line(T).expect("frame delivered");
            assert_eq!(frame_of(&line), frame, "{line}");
            assert!(line.contains("\"missed\":0"), "{line}");
        }
    }
}

#[test]
fn a_second_ticker_is_refused_naming_the_owner_until_the_first_releases() {
    let world = TestWorld::start("second", &["--fixed-delta-seconds", "0.01"]);
    let client = Client::connect(&world, T).unwrap();
    let first = client.claim_ticker_as("first-ticker").unwrap();

    match client.claim_ticker() {
        Err(TickError::NotTicker {
            owner: Some(owner), ..
        }) => {
            assert_eq!(owner.pid, std::process::id());
            assert_eq!(owner.node_name.to_string_lossy(), "first-ticker");
        }
        Err(e) => panic!("expected NotTicker, got {e}"),
        Ok(_) => panic!("a second ticker was admitted"),
    }
    let out = client_cli(&world, &["tick", "--count", "1"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(
        out.stderr.contains(&format!(
            "already has a ticker: first-ticker (pid {})",
            std::process::id()
        )),
        "{}",
        out.stderr
    );
    let owner = &status(&world)["ticker"];
    assert_eq!(owner["node"], "first-ticker");
    assert_eq!(owner["pid"].as_u64(), Some(u64::from(std::process::id())));

    first.release().unwrap();
    assert_eq!(status(&world)["ticker"], Value::Null);
    let out = client_cli(&world, &["tick", "--count", "3", "--json"]);
    out.assert_success();
    assert_eq!(out.json().len(), 3);
    assert_eq!(
        status(&world)["synchronous_mode"],
        false,
        "tick restored async mode"
    );
}

fn client_cli(world: &str, args: &[&str]) -> simbus_tests::Finished {
    client(world, args)
}

#[test]
fn a_ticker_killed_with_sigkill_is_replaced_and_no_frame_is_skipped_or_repeated() {
    let world = TestWorld::start(
        "failover",
        &["--fixed-delta-seconds", "0.01", "--scene", "empty"],
    );
    let mut old = Proc::spawn(
        "sim-client",
        &["--world", &world, "tick", "--rate", "200", "--json"],
    );
    let mut last_ticked = 0;
    for _ in 0..20 {
        last_ticked = frame_of(&old.line(T).expect("old ticker ticks"));
    }
    let watcher = Proc::spawn("sim-client", &["--world", &world, "watch", "--json"]);
    let first_seen = frame_of(&watcher.line(T).expect("watcher connected"));
    assert!(first_seen >= last_ticked);
    old.guard.kill().unwrap();

    // A new ticker claims as soon as the server noticed the dead one.
    let client = Client::connect(&world, T).unwrap();
    world.server.wait_stderr("ticker died", T);
    let mut ticker = client
        .claim_ticker()
        .expect("the claim once the server dropped the dead ticker");
    // The world stayed synchronous (--on-ticker-loss wait) and frozen.
    let frozen = status(&world);
    assert_eq!(frozen["synchronous_mode"], true);
    let last = frozen["frame"].as_u64().unwrap();
    assert_eq!(
        ticker.tick(T).unwrap(),
        last + 1,
        "continues from the next frame"
    );
    assert_eq!(ticker.tick(T).unwrap(), last + 2);

    // The watcher saw every frame exactly once across the handover.
    let mut expected = first_seen + 1;
    while expected <= last + 2 {
        let frame = frame_of(&watcher.line(T).expect("frame"));
        assert_eq!(frame, expected, "no frame skipped or repeated");
        expected += 1;
    }
}

#[test]
fn a_waiting_server_answers_status_and_config_no_sync_resumes_frames() {
    let world = TestWorld::start("no-sync", &["--fixed-delta-seconds", "0.01", "--realtime"]);
    let client = Client::connect(&world, T).unwrap();
    let _ticker = sync_ticker(&client, 0.01);
    let waiting = status(&world);
    assert_eq!(waiting["synchronous_mode"], true);
    assert_eq!(
        status(&world)["frame"],
        waiting["frame"],
        "frozen while waiting"
    );

    // While the ticker holds the world, only it changes settings …
    let out = client_cli(&world, &["config", "--delta-seconds", "0.02", "--json"]);
    assert_eq!(out.status.code(), Some(2), "{}", out.stderr);
    assert_eq!(status(&world)["synchronous_mode"], true);
    assert_eq!(status(&world)["fixed_delta_seconds"], 0.01);
    // … but anyone may leave sync mode.
    client_cli(&world, &["config", "--no-sync"]).assert_success();
    let out = client_cli(&world, &["watch", "--frames", "6", "--json"]);
    out.assert_success();
    // The first line may be the frame the world was frozen at (a new
    // subscriber gets the latest frame); the ones after it are new.
    let frozen = waiting["frame"].as_u64().unwrap();
    let new: Vec<_> = out
        .json()
        .into_iter()
        .filter(|f| f["frame"].as_u64().unwrap() > frozen)
        .collect();
    assert!(new.len() >= 5, "frames flow again: {new:?}");
    assert!(new.iter().all(|f| f["synchronous_mode"] == false));
    assert!(new.iter().all(|f| f["delta_ns"] == 10_000_000));
    assert!(status(&world)["frame"].as_u64() > waiting["frame"].as_u64());
}

#[test]
fn tick_without_a_server_fails_clearly_within_its_timeout() {
    let world = unique_world("tick-nobody");
    assert_fails_without_server(&world, &["tick", "--count", "1"]);
}

#[test]
fn a_server_killed_mid_tick_makes_the_ticker_fail_cleanly() {
    let world = unique_world("server-dies");
    let mut server = server(
        &world,
        &["--fixed-delta-seconds", "0.01", "--scene", "empty"],
    );
    let ticker = Proc::spawn(
        "sim-client",
        &[
            "--world",
            &world,
            "--timeout",
            "5",
            "tick",
            "--rate",
            "100",
            "--json",
        ],
    );
    for _ in 0..10 {
        ticker.line(T).expect("ticking");
    }
    server.guard.kill().unwrap();
    let out = ticker.finish(Duration::from_secs(30));
    assert_eq!(out.status.code(), Some(1), "{}", out.stderr);
    assert!(
        out.stderr.contains("has exited") || out.stderr.contains("did not answer"),
        "{}",
        out.stderr
    );
}

#[test]
fn on_ticker_loss_async_falls_back_to_asynchronous_mode() {
    let world = TestWorld::start(
        "loss-async",
        &[
            "--fixed-delta-seconds",
            "0.01",
            "--realtime",
            "--on-ticker-loss",
            "async",
        ],
    );
    let mut ticker = Proc::spawn("sim-client", &["--world", &world, "tick", "--rate", "50"]);
    ticker.line(T).expect("ticking");
    assert_eq!(status(&world)["synchronous_mode"], true);
    ticker.guard.kill().unwrap();
    world
        .server
        .wait_stderr("ticker died; falling back to asynchronous mode", T);
    assert_eq!(status(&world)["synchronous_mode"], false);
    let out = client_cli(&world, &["watch", "--frames", "3"]);
    out.assert_success();
}

#[test]
fn the_tick_command_refuses_a_variable_step_unless_allowed() {
    let world = TestWorld::start("variable-sync", &[]);
    let out = client_cli(&world, &["tick", "--count", "1", "--delta-seconds", "0"]);
    assert_eq!(out.status.code(), Some(2));
    assert!(
        out.stderr.contains("--allow-variable-step"),
        "{}",
        out.stderr
    );
    assert_eq!(status(&world)["synchronous_mode"], false, "nothing changed");
    let out = client_cli(
        &world,
        &[
            "tick",
            "--count",
            "2",
            "--delta-seconds",
            "0",
            "--allow-variable-step",
        ],
    );
    out.assert_success();
    assert!(out.stderr.contains("warning"), "{}", out.stderr);
}

/// `Ticker::tick_and_read`, the tick answered by its frame: in every wait
/// mode it returns the snapshot of the frame it ticked (the next id, the
/// ticker's last frame, none missed), frames queued before it are skipped,
/// a tick held by a lockstep participant waits for it, a revoked ticker
/// gets its error, not a timeout, and in an asynchronous world the tick is
/// answered and the newest frame returned.
#[test]
fn a_tick_answered_by_its_frame_returns_that_frame_or_the_refusal() {
    let (world, mut client, mut ticker) =
        simbus_tests::sync_world("by-frame", &["--lockstep-timeout", "60"]);
    // Ticked the usual way and never read: queued, then skipped.
    let first = ticker.tick(T).unwrap();
    let mut expected = first + 1;
    for mode in [WaitMode::Spin, WaitMode::Hybrid, WaitMode::Block] {
        client.set_wait_mode(mode);
        for _ in 0..10 {
            let frame = ticker.tick_and_read(&mut client, T).unwrap();
            assert_eq!(frame.frame(), expected, "{mode:?}");
            assert_eq!(frame.missed(), 0, "{mode:?}");
            assert_eq!(ticker.last_frame().map(|(f, _)| f), Some(expected));
            expected += 1;
        }
    }

    // Held by a participant until its done, past the tick's own timeout.
    let (name, server) = (world.name(), &world.server);
    std::thread::scope(|scope| {
        let (joined_tx, joined_rx) = std::sync::mpsc::channel();
        let participant = scope.spawn(move || {
            let client = Client::connect(name, T).unwrap();
            let participant = client.join_lockstep("slow").unwrap();
            joined_tx.send(()).unwrap();
            server.wait_stderr("a tick waits for a lockstep participant", T);
            let (episode, frame) = participant.joined_at();
            participant.done(episode, frame).unwrap();
        });
        joined_rx.recv_timeout(T).unwrap();
        let held = ticker
            .tick_and_read(&mut client, Duration::from_millis(500))
            .expect("the tick waits for the participant's done");
        assert_eq!(held.frame(), expected);
        participant.join().unwrap();
    });

    // Another client reloads while the tick waits: the reload's frame (0
    // of the next episode) is not the tick's; the stepped frame 1 is.
    let episode = client.status().unwrap().episode;
    std::thread::scope(|scope| {
        let (joined_tx, joined_rx) = std::sync::mpsc::channel();
        let participant = scope.spawn(move || {
            let client = Client::connect(name, T).unwrap();
            let participant = client.join_lockstep("reloading").unwrap();
            joined_tx.send(()).unwrap();
            let held = format!(
                "a tick waits for a lockstep participant pid={} name=reloading",
                std::process::id()
            );
            server.wait_stderr(&held, T);
            client.reload_world(false).unwrap();
            participant.done(episode + 1, 0).unwrap();
        });
        joined_rx.recv_timeout(T).unwrap();
        let stepped = ticker
            .tick_and_read(&mut client, Duration::from_millis(500))
            .unwrap();
        assert_eq!((stepped.episode(), stepped.frame()), (episode + 1, 1));
        participant.join().unwrap();
    });
    expected = 2;

    // Another client leaves synchronous mode: the ticker is told why.
    let other = Client::connect(world.name(), T).unwrap();
    let settings = WorldSettings {
        synchronous_mode: false,
        ..other.get_settings().unwrap()
    };
    other.apply_settings(settings).unwrap();
    let refused = ticker.tick_and_read(&mut client, T).unwrap_err();
    assert!(matches!(refused, TickError::Revoked { .. }), "{refused}");

    // An asynchronous world: its tick is answered, and the newest frame
    // after the answer comes back.
    drop(ticker);
    let mut ticker = client.claim_ticker().unwrap();
    let frame = ticker.tick_and_read(&mut client, T).unwrap();
    assert!(!frame.settings().synchronous_mode);
    assert!(
        frame.frame() > expected,
        "{} after {expected}",
        frame.frame()
    );
}
