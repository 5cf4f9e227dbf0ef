//! Lockstep participants: in synchronous mode the server steps only when the
//! tick has arrived and every participant is done with the current frame; a
//! participant that dies is dropped and the world goes on.

use std::time::{Duration, Instant};

use sim_client::{Client, TickError};
use simbus_tests::{send_signal, server, unique_world, Proc};

const T: Duration = Duration::from_secs(10);

#[test]
fn the_server_waits_for_a_participant_and_drops_it_when_it_is_sigkilled() {
    let world = unique_world("lockstep");
    let _server = server(&world, &["--sync", "--fixed-delta-seconds", "0.02"]);
    let client = Client::connect(&world, T).unwrap();
    let mut ticker = client.claim_ticker().unwrap();
    let mut autopilot = Proc::spawn("sim-client", &["--world", &world, "autopilot"]);
    let deadline = Instant::now() + T;
    while client.status().unwrap().participants != 1 {
        assert!(Instant::now() < deadline, "the autopilot joined");
        std::thread::sleep(Duration::from_millis(10));
    }
    for frame in 1..=20 {
        assert_eq!(ticker.tick(T).unwrap(), frame, "the participant keeps up");
    }

    // Freeze the participant: the server must wait for it.
    send_signal(autopilot.pid(), libc::SIGSTOP).unwrap();
    let mut waited = false;
    for _ in 0..3 {
        match ticker.tick(Duration::from_millis(500)) {
            Ok(_) => continue, // it may have been done with this frame already
            Err(TickError::Request(_)) => {
                waited = true;
                break;
            }
            Err(e) => panic!("{e}"),
        }
    }
    assert!(waited, "the server waited for the frozen participant");
    let frozen = client.status().unwrap().frame;
    std::thread::sleep(Duration::from_millis(300));
    assert_eq!(
        client.status().unwrap().frame,
        frozen,
        "no step without the participant"
    );

    autopilot.guard.kill().unwrap();
    // The stale tick is now stepped, and the next tick completes.
    let next = ticker.tick(T).expect("the world goes on");
    assert!(next > frozen);
    assert_eq!(client.status().unwrap().participants, 0, "dropped");
}

#[test]
fn a_hung_participant_is_dropped_after_the_lockstep_timeout() {
    let world = unique_world("hung");
    let _server = server(
        &world,
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
    let deadline = Instant::now() + T;
    while client.status().unwrap().participants != 1 {
        assert!(Instant::now() < deadline, "the autopilot joined");
        std::thread::sleep(Duration::from_millis(10));
    }
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
