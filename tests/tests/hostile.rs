//! A hostile client: a process that opens a world's services with the right
//! types and sends what a broken or malicious client would.
//!
//! Asserted against live servers:
//! - every refused request is answered with a typed error (never silence,
//!   never a crash), and the world is exactly as it would have been without
//!   it: a twin world, same scene and settings, ticked in step, never sees
//!   the garbage, and both publish the same digest frame after frame;
//! - a ticking batch whose header names the ticker's pid, sent by another
//!   process, is refused: ticking is authorised by the sending port's
//!   process, not by what a client writes; so is a settings reset whose
//!   request names the ticker's pid;
//! - a participant and a ticker that write a living process's pid as their
//!   own are dropped and freed when they die (`simbus-forger`);
//! - a request with another protocol version is answered `ProtocolMismatch`
//!   with the server's version;
//! - a flood of requests leaves the server answering and a watcher of the
//!   world seeing every frame.

use std::cell::RefCell;
use std::time::Duration;

use proptest::prelude::*;
use proptest::test_runner::{Config, TestRunner};
use shared_types::{
    BatchHeader, Command, ControlRequest, FixedText, RequestKind, ResponseStatus, WireSettings,
    WorldSettings, PROTOCOL_VERSION,
};
use simbus_tests::raw::RawPorts;
use simbus_tests::{sync_world, Proc, TestWorld};

/// Requests that must all be refused: out-of-range kinds, another protocol
/// version, settings that break a rule, an unknown scene.
/// Each comes with the refusals it may get (settings from a client that is
/// not the ticker of a synchronous world are refused as that first).
fn bad_control_request() -> impl Strategy<Value = (ControlRequest, &'static [ResponseStatus])> {
    let bad_float = prop_oneof![
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(-1.0),
        Just(f64::MAX)
    ];
    prop_oneof![
        (7u32..u32::MAX).prop_map(|kind| {
            let mut r = ControlRequest::new(RequestKind::Status);
            r.kind = kind;
            (r, &[ResponseStatus::UnknownRequest][..])
        }),
        (
            any::<u32>().prop_filter("another version", |v| *v != PROTOCOL_VERSION),
            1u32..7
        )
            .prop_map(|(version, kind)| {
                let mut r = ControlRequest::new(RequestKind::Status);
                r.kind = kind;
                r.protocol_version = version;
                (r, &[ResponseStatus::ProtocolMismatch][..])
            }),
        (
            bad_float.clone(),
            prop_oneof![Just(0u32), 17u32..u32::MAX],
            0usize..3
        )
            .prop_map(|(bad, substeps, which)| {
                let mut r = ControlRequest::new(RequestKind::ApplySettings);
                let mut settings = WireSettings::from(WorldSettings {
                    fixed_delta_seconds: Some(0.02),
                    synchronous_mode: true,
                    ..WorldSettings::default()
                });
                match which {
                    0 => settings.fixed_delta_seconds = bad,
                    1 => settings.max_substep_delta_time = bad,
                    _ => settings.max_substeps = substeps,
                }
                r.settings = settings;
                (
                    r,
                    &[ResponseStatus::InvalidSettings, ResponseStatus::NotTicker][..],
                )
            }),
        "[a-z0-9:]{0,12}x".prop_map(|scene| {
            let mut r = ControlRequest::new(RequestKind::LoadWorld);
            r.scene = FixedText::new(&scene);
            (r, &[ResponseStatus::UnknownScene][..])
        }),
    ]
}

/// Commands the world must refuse: unknown kinds, unknown or static actors,
/// NaN and infinities.
fn bad_command() -> impl Strategy<Value = Command> {
    prop_oneof![
        (100u32..u32::MAX).prop_map(|kind| Command {
            kind,
            ..Command::destroy(2)
        }),
        (1_000_000u64..u64::MAX).prop_map(Command::destroy),
        // Actor 1 is the ground: static, it cannot be pushed.
        Just(Command::set_target_velocity(1, [1.0, 0.0, 0.0], [0.0; 3])),
        prop_oneof![Just(f32::NAN), Just(f32::INFINITY), Just(f32::NEG_INFINITY)]
            .prop_map(|bad| Command::set_target_velocity(2, [bad, 0.0, 0.0], [0.0; 3])),
    ]
}

/// Two worlds, same scene and settings, ticked in step.
struct Twins<'a> {
    client: &'a mut sim_client::Client,
    ticker: &'a mut sim_client::Ticker,
    twin_client: &'a mut sim_client::Client,
    twin_ticker: &'a mut sim_client::Ticker,
}

impl Twins<'_> {
    /// Ticks both; their frames must have the same id and digest.
    fn step(&mut self) -> u64 {
        let timeout = Duration::from_secs(10);
        let a = self.ticker.tick(timeout).expect("tick");
        let b = self.twin_ticker.tick(timeout).expect("twin tick");
        // Frames published before (the world before synchronous mode) are
        // skipped; the ticked one must come.
        let next = |client: &mut sim_client::Client, frame: u64| loop {
            let snapshot = client.wait_for_tick(timeout).expect("frame");
            if snapshot.frame() >= frame {
                assert_eq!(snapshot.frame(), frame, "frame {frame} was skipped");
                break snapshot;
            }
        };
        let sa = next(self.client, a);
        let sb = next(self.twin_client, b);
        assert_eq!(a, b, "the twins are at different frames");
        assert_eq!(
            sa.digest(),
            sb.digest(),
            "frame {a}: the world that got the garbage differs from its twin"
        );
        a
    }
}

#[test]
fn garbage_is_refused_with_typed_errors_and_changes_nothing() {
    let (world, mut client, mut ticker) = sync_world("hostile", &["--scene", "default"]);
    let (twin, mut twin_client, mut twin_ticker) =
        sync_world("hostile-twin", &["--scene", "default"]);
    let watcher = world.spawn_cli(&["watch", "--digest"]);
    let raw = RawPorts::open(&world);
    let twins = RefCell::new(Twins {
        client: &mut client,
        ticker: &mut ticker,
        twin_client: &mut twin_client,
        twin_ticker: &mut twin_ticker,
    });
    twins.borrow_mut().step();

    let mut runner = TestRunner::new(Config {
        cases: 48,
        failure_persistence: None,
        ..Config::default()
    });
    runner
        .run(
            &(
                proptest::collection::vec(bad_control_request(), 1..4),
                proptest::collection::vec(bad_command(), 1..6),
            ),
            |(requests, commands)| {
                for (request, expected) in requests {
                    let answer = raw.control(request);
                    prop_assert_eq!(answer.protocol_version, PROTOCOL_VERSION);
                    let status = ResponseStatus::from_u32(answer.status);
                    prop_assert!(
                        status.is_some_and(|s| expected.contains(&s)),
                        "{:?} answered {:?}, expected one of {:?}",
                        request,
                        status,
                        expected
                    );
                }
                let (header, results) = raw.batch(BatchHeader::new(false), &commands);
                prop_assert_eq!(header.status, ResponseStatus::Ok as u32);
                prop_assert_eq!(results.len(), commands.len());
                for (command, result) in commands.iter().zip(&results) {
                    prop_assert!(
                        result.status != shared_types::CommandStatus::Ok as u32,
                        "{:?} was accepted: {:?}",
                        command,
                        result
                    );
                }
                twins.borrow_mut().step();
                Ok(())
            },
        )
        .unwrap();

    // A flood of fire-and-forget garbage: the server keeps answering, the
    // world stays its twin's.
    let flood = vec![Command::destroy(9_999_999); 8];
    for _ in 0..5_000 {
        twins
            .borrow()
            .client
            .apply_batch(&flood)
            .expect("a queued batch");
    }
    let status = raw.control(ControlRequest::new(RequestKind::Status));
    assert_eq!(status.status, ResponseStatus::Ok as u32);
    let last = twins.borrow_mut().step();

    // The watcher of the attacked world saw every frame, consecutively.
    ticker.release().expect("release");
    let _ = simbus_tests::send_signal(watcher.pid(), libc::SIGINT);
    let watched = watcher.finish(Duration::from_secs(20));
    let frames: Vec<u64> = watched
        .stdout
        .iter()
        .filter_map(|l| l.strip_prefix("frame ")?.split(' ').next()?.parse().ok())
        .collect();
    assert!(
        watched.stdout.iter().all(|l| !l.starts_with("missed")),
        "the watcher missed frames: {watched}"
    );
    assert!(frames.windows(2).all(|w| w[1] == w[0] + 1), "{watched}");
    assert!(frames.contains(&last), "the watcher never saw frame {last}");
    drop((twin, world));
}

#[test]
fn a_ticking_batch_is_authorised_by_its_port_not_by_the_pid_it_claims() {
    let world = TestWorld::start("forged", &["--scene", "default"]);
    // The ticker is another process, ticking slowly.
    let ticker = world.spawn_cli(&["tick", "--json", "--rate", "20", "--delta-seconds", "0.02"]);
    let first: serde_json::Value =
        serde_json::from_str(&ticker.line(Duration::from_secs(20)).expect("a first tick"))
            .expect("tick --json");
    assert!(first["frame"].as_u64().is_some());
    let raw = RawPorts::open(&world);
    let forged = BatchHeader {
        pid: ticker.pid(),
        ..BatchHeader::new(true)
    };
    let (header, results) = raw.batch(forged, &[Command::destroy(2)]);
    assert_eq!(
        ResponseStatus::from_u32(header.status),
        Some(ResponseStatus::NotTicker),
        "a ticking batch from a process that is not the ticker was accepted"
    );
    assert!(results.is_empty(), "its commands were applied: {results:?}");
    // Nothing of it was applied: actor 2 is still in the world.
    let status = raw.control(ControlRequest::new(RequestKind::Status));
    assert_eq!(status.status, ResponseStatus::Ok as u32);
    let mut client = world.connect();
    let snapshot = client
        .wait_for_tick(Duration::from_secs(10))
        .expect("a frame");
    assert!(
        snapshot.find(2).is_some(),
        "actor 2 was destroyed by a refused batch"
    );
    drop(ticker);
}

/// A settings reset while a ticker holds the world is the ticker's alone:
/// a reload with `RESET_SETTINGS` from another process that writes the
/// ticker's pid as its own is refused, and the world keeps its episode and
/// its settings. (Before, the server took the pid the request wrote.)
#[test]
fn a_reset_is_authorised_by_its_port_not_by_the_pid_it_claims() {
    let world = TestWorld::start("forged-reset", &["--scene", "default"]);
    let ticker = world.spawn_cli(&["tick", "--json", "--rate", "20", "--delta-seconds", "0.02"]);
    ticker.line(Duration::from_secs(20)).expect("a first tick");
    let raw = RawPorts::open(&world);
    let before = raw.control(ControlRequest::new(RequestKind::Status)).report;
    let forged = ControlRequest {
        client_pid: ticker.pid(),
        flags: ControlRequest::RESET_SETTINGS,
        ..ControlRequest::new(RequestKind::ReloadWorld)
    };
    let answer = raw.control(forged);
    assert_eq!(
        ResponseStatus::from_u32(answer.status),
        Some(ResponseStatus::NotTicker),
        "a reset from a process that is not the ticker was accepted"
    );
    let after = raw.control(ControlRequest::new(RequestKind::Status)).report;
    assert_eq!(after.episode, before.episode, "the world was reloaded");
    assert_eq!(after.settings, before.settings, "the settings were reset");
    assert_eq!(after.settings.synchronous_mode, 1, "{after:?}");
    drop(ticker);
}

/// A participant and a ticker that write another living process's pid
/// (this test's) as their own: the server records the forger's process,
/// so status names the forger, and its SIGKILL ends its membership and its
/// ownership however long the process it named lives.
#[test]
fn a_forged_pid_keeps_neither_a_dead_participant_nor_a_dead_ticker() {
    let world = TestWorld::start("forged-liveness", &["--sync", "--delta-seconds", "0.02"]);
    let client = world.connect();
    let me = std::process::id().to_string();
    let forger = |mode| Proc::spawn("simbus-forger", &[world.name(), &me, mode]);

    let mut participant = forger("participant");
    let joined = participant.line(Duration::from_secs(20)).expect("joined");
    assert_eq!(joined, format!("joined {}", ResponseStatus::Ok as u32));
    let status = client.status().unwrap();
    assert_eq!(
        status.lockstep[0].pid,
        participant.pid(),
        "the port's process"
    );
    participant.guard.kill().unwrap();
    wait_until(
        || client.status().unwrap().participants == 0,
        "participant dropped",
    );

    let mut ticker = forger("ticker");
    let claimed = ticker.line(Duration::from_secs(20)).expect("claimed");
    assert_eq!(claimed, format!("claimed {}", ResponseStatus::Ok as u32));
    let owner = client.status().unwrap().ticker.expect("an owner");
    assert_eq!(owner.pid, ticker.pid(), "the port's process, not {me}");
    ticker.guard.kill().unwrap();
    wait_until(
        || client.status().unwrap().ticker.is_none(),
        "ownership freed",
    );
    let mut mine = client.claim_ticker().expect("the world is free again");
    mine.tick(Duration::from_secs(10)).expect("and ticks");
}

/// Waits (at most 20 s) until `done` holds; each check is a status round
/// trip (a death has no event of its own here).
fn wait_until(mut done: impl FnMut() -> bool, what: &str) {
    let deadline = std::time::Instant::now() + Duration::from_secs(20);
    while !done() {
        assert!(std::time::Instant::now() < deadline, "never: {what}");
        std::thread::yield_now();
    }
}

#[test]
fn another_protocol_version_is_told_the_servers() {
    let world = TestWorld::start("version", &["--scene", "empty"]);
    let raw = RawPorts::open(&world);
    let mut request = ControlRequest::new(RequestKind::Hello);
    request.protocol_version = PROTOCOL_VERSION + 1;
    let answer = raw.control(request);
    assert_eq!(
        ResponseStatus::from_u32(answer.status),
        Some(ResponseStatus::ProtocolMismatch)
    );
    assert_eq!(answer.protocol_version, PROTOCOL_VERSION);
    let (header, _) = raw.batch(
        BatchHeader {
            protocol_version: PROTOCOL_VERSION + 1,
            ..BatchHeader::new(false)
        },
        &[Command::destroy(2)],
    );
    assert_eq!(
        ResponseStatus::from_u32(header.status),
        Some(ResponseStatus::ProtocolMismatch)
    );
    assert_eq!(header.protocol_version, PROTOCOL_VERSION);
}
