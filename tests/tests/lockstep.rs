//! Lockstep participants: in synchronous mode the server steps only when the
//! tick has arrived and every participant is done with the current frame; a
//! participant that dies is dropped and the world goes on.

use std::time::{Duration, Instant};

use sim_client::Client;
use simbus_tests::{send_signal, Proc, TestWorld};

const T: Duration = Duration::from_secs(10);

/// Waits until `pid` is stopped (state `T` in /proc), so a SIGSTOP has
/// taken effect.
fn wait_until_stopped(pid: u32) {
    let deadline = Instant::now() + T;
    loop {
        let stat = std::fs::read_to_string(format!("/proc/{pid}/stat")).unwrap_or_default();
        let state = stat
            .rfind(')')
            .and_then(|i| stat[i + 1..].split_whitespace().next());
        if state == Some("T") {
            return;
        }
        assert!(Instant::now() < deadline, "{pid} did not stop");
        std::thread::yield_now();
    }
}

#[test]
fn the_server_waits_for_a_participant_and_drops_it_when_it_is_sigkilled() {
    let world = TestWorld::start("lockstep", &["--sync", "--fixed-delta-seconds", "0.02"]);
    let client = Client::connect(&world, T).unwrap();
    let mut ticker = client.claim_ticker().unwrap();
    let mut autopilot = Proc::spawn("sim-client", &["--world", &world, "autopilot"]);
    simbus_tests::wait_for_participants(&client, 1);
    for frame in 1..=20 {
        assert_eq!(ticker.tick(T).unwrap(), frame, "the participant keeps up");
    }

    // Freeze the participant: the server must wait for it.
    send_signal(autopilot.pid(), libc::SIGSTOP).unwrap();
    wait_until_stopped(autopilot.pid());
    let frozen = client.status().unwrap().frame;
    let (name, server) = (world.name(), &world.server);
    let held_up = format!(
        "a tick waits for a lockstep participant pid={}",
        autopilot.pid()
    );
    std::thread::scope(|scope| {
        // Meanwhile (ports are per thread): once the server says a tick
        // waits for the participant, look, then kill the participant.
        let observer = scope.spawn(|| {
            let observer = Client::connect(name, T).unwrap();
            server.wait_stderr(&held_up, T);
            let frame = observer.status().unwrap().frame;
            autopilot.guard.kill().unwrap();
            frame
        });
        // It may have reported the frozen frame done before it stopped, so
        // one more step may happen; the next one waits until it is gone.
        ticker.tick(T).expect("the world goes on");
        assert_eq!(ticker.tick(T).expect("the world goes on"), frozen + 2);
        let seen = observer.join().unwrap();
        assert!(
            seen <= frozen + 1,
            "no step without the participant: {seen} after {frozen}"
        );
    });
    assert_eq!(client.status().unwrap().participants, 0, "dropped");
}

/// The defaults must compose: a ticker whose own timeout is shorter than
/// the server's lockstep timeout is told which participant holds it up and
/// waits for the server to drop it, instead of failing first and leaving
/// the participant in place. The dropped reader, resumed, learns it was
/// dropped and exits with an error instead of carrying on out of step.
#[test]
fn a_tick_held_up_by_a_hung_reader_outwaits_its_own_timeout_and_the_reader_learns_it_was_dropped() {
    let world = TestWorld::start(
        "held-up",
        &[
            "--sync",
            "--delta-seconds",
            "0.02",
            "--lockstep-timeout",
            "2",
        ],
    );
    let client = Client::connect(&world, T).unwrap();
    let mut ticker = client.claim_ticker().unwrap();
    let watcher = Proc::spawn("sim-client", &["--world", &world, "watch", "--lockstep"]);
    simbus_tests::wait_for_participants(&client, 1);
    for frame in 1..=5 {
        assert_eq!(ticker.tick(T).unwrap(), frame);
    }
    send_signal(watcher.pid(), libc::SIGSTOP).unwrap();
    wait_until_stopped(watcher.pid());
    // Shorter than the lockstep timeout: before, such a tick failed first.
    // The reader may have reported frame 5 before it stopped, so one tick
    // may go through at once; the other waits for the server to drop it.
    let short = Duration::from_millis(500);
    for frame in 6..=7 {
        let ticked = ticker
            .tick(short)
            .expect("the tick waits for the server to drop the hung reader");
        assert_eq!(ticked, frame);
    }
    assert_eq!(client.status().unwrap().participants, 0, "dropped");

    send_signal(watcher.pid(), libc::SIGCONT).unwrap();
    // The world goes on; the resumed reader finds out at its next report.
    let mut watcher = watcher;
    let deadline = Instant::now() + T;
    let status = loop {
        if let Some(status) = watcher.guard.try_wait().unwrap() {
            break status;
        }
        assert!(Instant::now() < deadline, "the dropped watcher carried on");
        ticker.tick(T).unwrap();
    };
    let out = watcher.finish(T);
    assert_eq!(status.code(), Some(1), "{}", out.stderr);
    assert!(
        out.stderr.contains("dropped from the lockstep"),
        "{}",
        out.stderr
    );
}

#[test]
fn a_hung_participant_is_dropped_after_the_lockstep_timeout() {
    let world = TestWorld::start(
        "hung",
        &[
            "--sync",
            "--fixed-delta-seconds",
            "0.02",
            "--lockstep-timeout",
            "1",
        ],
    );
    let client = Client::connect(&world, T).unwrap();
    let mut ticker = client.claim_ticker().unwrap();
    let autopilot = Proc::spawn("sim-client", &["--world", &world, "autopilot"]);
    simbus_tests::wait_for_participants(&client, 1);
    ticker.tick(T).unwrap();
    // Alive but hung: only the timeout can release the world.
    send_signal(autopilot.pid(), libc::SIGSTOP).unwrap();
    for _ in 0..3 {
        ticker
            .tick(T)
            .expect("the world goes on after the lockstep timeout");
    }
    assert_eq!(client.status().unwrap().participants, 0, "dropped");
    send_signal(autopilot.pid(), libc::SIGCONT).unwrap();
}
