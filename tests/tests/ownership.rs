//! Ownership while a ticker ticks: only the ticker changes settings; anyone
//! may leave synchronous mode (CARLA's escape hatch), which ends the
//! ticker's ownership, and the ticker's next tick fails naming who did it.
//! A `tick` run puts back the settings it changed, and `--count 0` changes
//! nothing.

use std::time::Duration;

use shared_types::WorldSettings;
use sim_client::{Client, TickError};
use simbus_tests::{client, status, TestWorld};

const T: Duration = Duration::from_secs(10);

#[test]
fn only_the_ticker_changes_settings_and_leaving_sync_mode_revokes_it_by_name() {
    let world = TestWorld::start("revoke", &[]);
    let api = Client::connect(&world, T).unwrap();
    let mut ticker = api.claim_ticker().unwrap();
    let sync = WorldSettings {
        synchronous_mode: true,
        fixed_delta_seconds: Some(0.05),
        ..api.get_settings().unwrap()
    };
    ticker.apply_settings(sync).unwrap();
    let first = ticker.tick(T).unwrap();

    // Another client may not change the ticker's step...
    let out = client(&world, &["config", "--fps", "10"]);
    assert_eq!(out.status.code(), Some(2), "{}", out.stderr);
    assert!(
        out.stderr.contains("world has a ticker")
            && out.stderr.contains("only it changes settings"),
        "{}",
        out.stderr
    );
    assert_eq!(status(&world)["fixed_delta_seconds"], 0.05, "unchanged");
    // ...nor reset them by reloading.
    let out = client(&world, &["reload", "--reset-settings"]);
    assert_eq!(out.status.code(), Some(2), "{}", out.stderr);
    assert!(out.stderr.contains("world has a ticker"), "{}", out.stderr);
    assert_eq!(status(&world)["synchronous_mode"], true, "unchanged");
    let last = ticker.tick(T).unwrap();
    assert_eq!(last, first + 1, "the ticker still ticks");

    // ...but it may leave synchronous mode, and the ticker is told who did.
    let out = client(&world, &["config", "--no-sync"]);
    out.assert_success();
    let after = status(&world);
    assert_eq!(after["synchronous_mode"], false);
    assert!(after["ticker"].is_null(), "ownership ended: {after}");
    match ticker.tick(T) {
        Err(TickError::Revoked { by, .. }) => {
            assert_eq!(by.node_name.to_string_lossy(), "sim-client");
            assert_eq!(by.since_frame, last, "the frame it happened at");
        }
        other => panic!("the revoked ticker was not told: {other:?}"),
    }
    let message = ticker.tick(T).unwrap_err().to_string();
    assert!(
        message.contains("was turned off by sim-client (pid"),
        "{message}"
    );
    ticker
        .release()
        .expect("a revoked ticker may release quietly");
    // The tick service is free again for a new ticker.
    let mut next = api.claim_ticker().expect("a new ticker may claim");
    next.tick(T).unwrap();
}

#[test]
fn the_tick_command_reports_who_turned_sync_mode_off_and_exits_1() {
    let world = TestWorld::start("revoke-cli", &[]);
    let ticker = simbus_tests::Proc::spawn(
        "sim-client",
        &["--world", &world, "tick", "--rate", "50", "--json"],
    );
    assert!(ticker.line(T).is_some(), "ticking: {}", ticker.stderr());
    client(&world, &["config", "--no-sync"]).assert_success();
    let out = ticker.finish(T);
    assert_eq!(out.status.code(), Some(1), "{}", out.stderr);
    assert!(
        out.stderr.contains("was turned off by sim-client"),
        "{}",
        out.stderr
    );
}

#[test]
fn a_tick_run_puts_back_what_it_changed_and_count_0_changes_nothing() {
    let world = TestWorld::start("restore", &[]);
    let before = status(&world);
    assert!(before["fixed_delta_seconds"].is_null(), "variable step");

    let out = client(&world, &["tick", "--count", "0"]);
    out.assert_success();
    assert!(out.stdout.is_empty(), "{:?}", out.stdout);
    let after = status(&world);
    assert_eq!(after["fixed_delta_seconds"], before["fixed_delta_seconds"]);
    assert_eq!(after["synchronous_mode"], false);

    let out = client(&world, &["tick", "--count", "3", "--delta-seconds", "0.02"]);
    out.assert_success();
    assert_eq!(out.stdout.len(), 3);
    let after = status(&world);
    assert!(
        after["fixed_delta_seconds"].is_null(),
        "variable step again: {after}"
    );
    assert_eq!(after["synchronous_mode"], false);
    assert!(after["ticker"].is_null());
}
