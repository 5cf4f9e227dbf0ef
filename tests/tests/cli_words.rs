//! What the commands say fits what happened: counts in the singular for
//! one (`1 frame`, `1 actor`); a demo server that exits without a word is
//! reported as such (not "its message is above"); `config --no-sync` with
//! another change, while a ticker holds the world, does both, as CARLA's
//! `config.py` does (it was refused with advice to run what was typed).

use std::os::unix::fs::PermissionsExt;
use std::time::Duration;

use shared_types::Command;
use simbus_tests::{unique_world, Scratch, TestWorld};

const T: Duration = Duration::from_secs(20);

#[test]
fn one_is_counted_in_the_singular() {
    let world = unique_world("one-frame");
    let demo = simbus_tests::client(&world, &["demo", "--frames", "1", "--scene", "empty"]);
    demo.assert_success();
    let last = demo.stdout.last().expect("the demo's last line");
    assert!(
        last.starts_with("demo finished: watched 1 frame (0 missed); server stopped"),
        "{demo}"
    );

    let world = TestWorld::start("one-actor", &["--scene", "empty"]);
    world
        .connect()
        .apply_batch_sync(&[Command::spawn_box([0.0, 5.0, 0.0], [0.5; 3])], false)
        .expect("a box");
    let status = world.cli(&["status"]);
    status.assert_success();
    let lines = status.stdout.join("\n");
    assert!(lines.contains("scene     empty (1 actor)\n"), "{status}");
    assert!(lines.contains("lockstep  0 participants"), "{status}");
}

#[test]
fn a_demo_server_that_exits_says_whether_it_left_a_message() {
    let out = simbus_tests::client(
        &unique_world("demo-true"),
        &["demo", "--server", "/bin/true"],
    );
    out.assert_code(1);
    assert!(
        out.stderr
            .contains("the demo server exited at once (exit status: 0) without a message"),
        "{out}"
    );
    assert!(!out.stderr.contains("above"), "{out}");

    let dir = Scratch::new("demo-talker");
    let talker = dir.write(
        "talker.sh",
        b"#!/bin/sh\necho 'sim-server: refused: no scene named nowhere' >&2\nexit 2\n",
    );
    std::fs::set_permissions(&talker, std::fs::Permissions::from_mode(0o755)).unwrap();
    let out = simbus_tests::client(
        &unique_world("demo-talker"),
        &["demo", "--server", talker.to_str().expect("path")],
    );
    out.assert_code(1);
    let message = out
        .stderr
        .find("sim-server: refused: no scene named nowhere")
        .unwrap_or_else(|| panic!("the server's message is shown: {out}"));
    let report = out
        .stderr
        .find("the demo server exited at once (exit status: 2); its message is above")
        .unwrap_or_else(|| panic!("{out}"));
    assert!(message < report, "{out}");
}

#[test]
fn config_no_sync_with_a_new_step_does_both_while_a_ticker_holds_the_world() {
    let (world, client, mut ticker) = simbus_tests::sync_world("no-sync-fps", &[]);
    ticker.tick(T).expect("the ticker ticks");
    let out = world.cli(&["config", "--no-sync", "--fps", "10"]);
    out.assert_success();
    let settings = client.get_settings().expect("settings");
    assert!(!settings.synchronous_mode, "{settings:?}");
    assert_eq!(settings.fixed_delta_seconds, Some(0.1), "{settings:?}");
    // Leaving synchronous mode ended the ticker's ownership.
    assert!(
        ticker.tick(T).is_err(),
        "the old ticker is no longer the ticker"
    );
}
