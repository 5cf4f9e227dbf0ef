//! Standby tickers: ports open and a claim queued while another client
//! ticks; the server grants the world the moment it has no ticker. A
//! standby takes over a SIGKILLed ticker at the next frame, standbys are
//! served in order, a dead one holds nothing, and every wait ends (a
//! timeout naming the ticker, a dead server).

use std::time::Duration;

use sim_client::{Client, RequestError, TickError};
use simbus_tests::{status, TestWorld};

const T: Duration = Duration::from_secs(20);

/// The frames of `tick --json` lines.
fn frames(lines: &[serde_json::Value]) -> Vec<u64> {
    lines.iter().map(|l| l["frame"].as_u64().unwrap()).collect()
}

/// The frame a `tick --standby` run says it took over at.
fn took_over_at(stderr: &str) -> u64 {
    let line = stderr
        .lines()
        .find(|l| l.contains("standby took over world"))
        .unwrap_or_else(|| panic!("no take-over line:\n{stderr}"));
    line.rsplit(' ').next().unwrap().parse().unwrap()
}

#[test]
fn a_standby_takes_over_a_killed_ticker_at_the_next_frame() {
    let world = TestWorld::start("standby-kill", &[]);
    let mut owner = world.spawn_cli(&["tick", "--json", "--rate", "200"]);
    assert!(owner.line(T).is_some(), "ticking: {}", owner.stderr());
    let standby = world.spawn_cli(&["tick", "--standby", "--json", "--count", "3"]);
    standby.wait_stderr("waiting for the ticker sim-client-tick", T);

    owner.guard.kill().unwrap();
    // Every frame the owner printed (its pipe ends with it).
    let mut last_owned = 0;
    while let Some(line) = owner.line(T) {
        let line: serde_json::Value = serde_json::from_str(&line).unwrap();
        last_owned = line["frame"].as_u64().unwrap();
    }
    assert!(last_owned > 0);

    let out = standby.finish(T);
    out.assert_success();
    let at = took_over_at(&out.stderr);
    // Published before the kill: the standby takes over there, or one
    // frame later if the owner's last tick was stepped but not printed.
    assert!(
        (last_owned..=last_owned + 1).contains(&at),
        "owner printed up to {last_owned}, standby took over at {at}"
    );
    assert_eq!(frames(&out.json()), [at + 1, at + 2, at + 3], "{out}");
    assert!(status(&world)["ticker"].is_null(), "released at the end");
}

#[test]
fn a_standby_killed_while_waiting_does_not_hold_the_world() {
    let world = TestWorld::start("standby-dies", &[]);
    let api = Client::connect(&world, T).unwrap();
    let owner = api.claim_ticker().unwrap();
    let mut standby = world.spawn_cli(&["tick", "--standby"]);
    standby.wait_stderr("waiting for the ticker", T);
    standby.guard.kill().unwrap();

    owner.release().unwrap();
    let after = status(&world);
    assert!(
        after["ticker"].is_null(),
        "the world went to a dead standby: {after}"
    );
    let mut next = api.claim_ticker().expect("a later claim succeeds");
    next.tick(T).unwrap();
}

#[test]
fn two_standbys_are_served_first_come_first_served() {
    let world = TestWorld::start("standby-two", &[]);
    let api = Client::connect(&world, T).unwrap();
    let owner = api.claim_ticker().unwrap();
    let first = world.spawn_cli(&["tick", "--standby", "--json", "--count", "3"]);
    first.wait_stderr("waiting for the ticker", T);
    let second = world.spawn_cli(&["tick", "--standby", "--json", "--count", "2"]);
    second.wait_stderr("waiting for the ticker", T);

    owner.release().unwrap();
    let first = first.finish(T);
    first.assert_success();
    let second = second.finish(T);
    second.assert_success();
    let (a, b) = (frames(&first.json()), frames(&second.json()));
    assert_eq!(a.len(), 3, "{first}");
    assert_eq!(b.len(), 2, "{second}");
    // The second waited while the first ticked, and took over after it.
    assert!(
        took_over_at(&second.stderr) >= a[2] && b[0] > a[2],
        "first ticked {a:?}, second {b:?}:\n{second}"
    );
}

#[test]
fn tick_standby_gives_up_after_its_timeout_naming_the_ticker() {
    let world = TestWorld::start("standby-timeout", &[]);
    let api = Client::connect(&world, T).unwrap();
    let mut owner = api.claim_ticker().unwrap();
    let out = world.cli(&["tick", "--standby", "--standby-timeout", "0.3"]);
    out.assert_code(1);
    let me = format!("(pid {})", std::process::id());
    assert!(
        out.stderr
            .contains("still has a ticker after 300ms on standby")
            && out.stderr.contains(&me),
        "{out}"
    );
    // The owner still ticks; once it releases, the world is free (the
    // standby that gave up is not served).
    owner.tick(T).unwrap();
    owner.release().unwrap();
    assert!(status(&world)["ticker"].is_null());
}

#[test]
fn a_standby_of_a_free_world_holds_it_at_once_and_a_dead_server_ends_a_wait() {
    let mut world = TestWorld::start("standby-server", &[]);
    let api = Client::connect(&world, T).unwrap();
    let standby = api.standby_ticker().unwrap();
    assert!(standby.owner().is_none(), "the world was free");
    let owner = standby.wait(Duration::ZERO).expect("granted at once");

    let other = Client::connect(&world, T).unwrap();
    let waiting = other.standby_ticker().unwrap();
    assert!(waiting.owner().is_some(), "queued behind the first");
    world.server.guard.kill().unwrap();
    match waiting.wait(T) {
        Err(TickError::Request(RequestError::ServerGone { .. })) => {}
        other => panic!("the wait did not end with ServerGone: {other:?}"),
    }
    drop(owner);
}
