//! Lockstep participants: in synchronous mode the server steps only when the
//! tick has arrived and every participant is done with the current frame
//! (or, with a window of W frames, with the frame W before); a participant
//! that dies is dropped and the world goes on.

use std::time::{Duration, Instant};

use shared_types::ResponseStatus;
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

/// Lockstep windows (CARLA PR #9450's per-participant synchronous windows):
/// a participant with a window of W frames lets the world step past frame N
/// once it is done with frame N − W. One that stops reporting never holds
/// the ticker for W + 1 frames; the next tick waits for it, and its next
/// "done" releases it. Status reports its window and how far behind it is.
#[test]
fn a_participant_with_a_window_of_three_holds_the_ticker_only_four_frames_behind() {
    let world = TestWorld::start(
        "window",
        &[
            "--sync",
            "--fixed-delta-seconds",
            "0.02",
            "--lockstep-timeout",
            "60",
        ],
    );
    let client = Client::connect(&world, T).unwrap();
    let mut ticker = client.claim_ticker().unwrap();
    let (to_participant, orders) = std::sync::mpsc::channel::<u64>();
    let (joined_tx, joined_rx) = std::sync::mpsc::channel();
    let name = world.name().to_owned();
    // The participant on a thread of its own (its ports are its thread's):
    // it reports done with each frame the test sends it, nothing else.
    let participant = std::thread::spawn(move || {
        let client = Client::connect(&name, T).unwrap();
        let participant = client.join_lockstep_with_window("windowed", 3).unwrap();
        assert_eq!(participant.window(), 3);
        joined_tx.send(participant.joined_at()).unwrap();
        for frame in orders {
            participant.done(participant.joined_at().0, frame).unwrap();
        }
    });
    let (episode, joined) = joined_rx.recv_timeout(T).unwrap();
    assert_eq!(episode, client.status().unwrap().episode);
    to_participant.send(joined).unwrap();
    // Done with `joined`, then silent: four steps need nothing more of it.
    for n in 1..=4 {
        assert_eq!(ticker.tick(T).unwrap(), joined + n, "within the window");
    }
    let status = client.status().unwrap();
    let p = &status.lockstep[0];
    assert_eq!((p.name.as_str(), p.window), ("windowed", 3));
    assert_eq!((p.done_frame, p.lag), (joined, Some(4)), "{p:?}");
    assert!(
        !world
            .server
            .stderr()
            .contains("a tick waits for a lockstep participant"),
        "no tick waited within the window"
    );
    // The fifth needs it done with joined + 1: the tick waits until it is.
    let (name, server) = (world.name(), &world.server);
    std::thread::scope(|scope| {
        let release = to_participant.clone();
        let observer = scope.spawn(move || {
            let observer = Client::connect(name, T).unwrap();
            server.wait_stderr("a tick waits for a lockstep participant", T);
            let held_at = observer.status().unwrap().frame;
            release.send(joined + 1).unwrap();
            held_at
        });
        assert_eq!(ticker.tick(T).unwrap(), joined + 5, "released by its done");
        assert_eq!(observer.join().unwrap(), joined + 4, "held four behind");
    });
    drop(to_participant);
    participant.join().unwrap();
}

/// `watch --lockstep --window 3` joins with that window and still prints
/// every frame; killed, it is dropped as any participant and the world goes
/// on. A window larger than a participant may ask for is refused by the
/// client library, and by the server from a raw request, which joins nothing.
#[test]
fn a_windowed_watcher_sees_every_frame_and_dies_like_any_participant() {
    let world = TestWorld::start("window-watch", &["--sync", "--fixed-delta-seconds", "0.02"]);
    let client = Client::connect(&world, T).unwrap();
    let mut ticker = client.claim_ticker().unwrap();
    let too_large = client
        .join_lockstep_with_window("greedy", 1001)
        .unwrap_err();
    assert!(
        too_large.to_string().contains("more than the 1000"),
        "{too_large}"
    );
    assert_eq!(raw_join(world.name(), 5000), ResponseStatus::Refused as u32);
    assert_eq!(client.status().unwrap().participants, 0, "nothing joined");

    let mut watcher = Proc::spawn(
        "sim-client",
        &[
            "--world",
            &world,
            "watch",
            "--lockstep",
            "--window",
            "3",
            "--json",
        ],
    );
    simbus_tests::wait_for_participants(&client, 1);
    assert_eq!(client.status().unwrap().lockstep[0].window, 3);
    let first = ticker.tick(T).unwrap();
    for _ in 0..19 {
        ticker.tick(T).unwrap();
    }
    // Every frame from its first, in order, none missed.
    let mut expected = None;
    while expected.is_none_or(|f| f <= first + 19) {
        let line = watcher.line(T).expect("a frame line");
        let frame: serde_json::Value = serde_json::from_str(&line).unwrap();
        let got = frame["frame"].as_u64().unwrap();
        assert_eq!(frame["missed"], 0, "{line}");
        if let Some(expected) = expected {
            assert_eq!(got, expected, "in order");
        }
        expected = Some(got + 1);
    }
    watcher.guard.kill().unwrap();
    for _ in 0..5 {
        ticker
            .tick(T)
            .expect("the world goes on without the dead watcher");
    }
    assert_eq!(client.status().unwrap().participants, 0, "dropped");
}

/// Sends a lockstep join with `window` over a raw port (what no simbus
/// client sends past the limit) and returns the answer's status.
fn raw_join(world: &str, window: u32) -> u32 {
    use shared_types::{LockstepKind, LockstepRequest, LockstepResponse};
    let names = simbus_tests::raw::service_names(world);
    let node = simbus_transport::node("raw-lockstep").unwrap();
    let port = node
        .service_builder(&simbus_tests::raw::service_name(&names.lockstep))
        .request_response::<LockstepRequest, LockstepResponse>()
        .open()
        .unwrap()
        .client_builder()
        .create()
        .unwrap();
    let wake = node
        .service_builder(&simbus_tests::raw::service_name(&names.control_wake))
        .event()
        .open()
        .unwrap()
        .notifier_builder()
        .create()
        .unwrap();
    let request = LockstepRequest {
        window,
        ..LockstepRequest::new(LockstepKind::Join, "greedy", 0, 0)
    };
    let pending = port.send_copy(request).unwrap();
    wake.notify().unwrap();
    let deadline = Instant::now() + T;
    loop {
        if let Some(answer) = pending.receive().unwrap() {
            return answer.status;
        }
        assert!(Instant::now() < deadline, "no answer to the raw join");
        std::thread::yield_now();
    }
}
