//! Determinism: with synchronous mode, a fixed step, a seed and batched
//! commands — spawns, forces, vehicle controls and the seeded autopilot
//! participant — the same scenario gives bit-identical snapshots frame for
//! frame in two separate server processes, and again after `reload_world` in
//! one of them. A changed seed or command changes the digests.

use std::time::{Duration, Instant};

use shared_types::Command;
use sim_client::Client;
use simbus_tests::{server, unique_world, Proc, TestWorld};

const T: Duration = Duration::from_secs(20);
const FRAMES: u64 = 2000;

/// The scripted commands of the scenario at `frame` (applied before it is
/// stepped). `variant` changes one force, to show the digests notice.
/// Actors are named by their place in the episode (1 = its first actor):
/// ids are never reused, so a reloaded scene's actors have new ids.
fn commands_at(frame: u64, variant: bool, first_id: u64) -> Vec<Command> {
    let id = |nth: u64| first_id + nth - 1;
    match frame {
        10 => vec![
            Command::spawn_box([3.0, 4.0, 2.0], [0.4, 0.4, 0.4]),
            Command::spawn_sphere([6.0, 8.0, -2.0], 0.3),
            Command::spawn_vehicle([-10.0, 1.0, 14.0]),
        ],
        50 => vec![Command::apply_impulse(
            id(3),
            [2.0, if variant { 3.1 } else { 3.0 }, 0.0],
        )],
        // The spawned vehicle is the first id after the scene's actors.
        120 => vec![Command::vehicle_control(id(20), 0.8, 0.3, 0.0, false)],
        400 => vec![
            Command::apply_force(id(4), [0.0, 30.0, 5.0]),
            Command::apply_torque(id(5), [0.0, 2.0, 0.0]),
        ],
        900 => vec![Command::set_target_velocity(
            id(19),
            [0.0, 5.0, 0.0],
            [1.0, 0.0, 0.0],
        )],
        1500 => vec![Command::vehicle_control(id(20), 0.0, 0.0, 1.0, true)],
        _ => Vec::new(),
    }
}

/// Ticks `FRAMES` frames through the scenario and returns the episode's
/// first actor id and every frame's digest.
fn run_scenario(client: &mut Client, variant: bool) -> (u64, Vec<u64>) {
    let mut ticker = client.claim_ticker().expect("claim");
    // The autopilot must be in the lockstep before the first step.
    simbus_tests::wait_for_participants(client, 1);
    let first = client.wait_for_tick(T).expect("frame 0");
    assert_eq!(first.frame(), 0, "the episode starts at frame 0");
    let mut digests = vec![first.digest()];
    for frame in 1..=FRAMES {
        let commands = commands_at(frame, variant, first.header.first_actor_id);
        if !commands.is_empty() {
            let response = client.apply_batch_sync(&commands, false).expect("batch");
            assert!(
                response.errors().is_empty(),
                "frame {frame}: {:?}",
                response.errors()
            );
            assert_eq!(response.frame, frame);
        }
        assert_eq!(ticker.tick(T).expect("tick"), frame);
        let snapshot = client.wait_for_tick(T).expect("snapshot");
        assert_eq!(snapshot.frame(), frame);
        digests.push(snapshot.digest());
    }
    ticker.release().unwrap();
    (first.header.first_actor_id, digests)
}

struct World {
    name: String,
    _server: Proc,
    _autopilot: Proc,
    client: Client,
}

fn world(tag: &str, seed: &str) -> World {
    let name = unique_world(tag);
    let server = server(
        &name,
        &["--sync", "--seed", seed, "--fixed-delta-seconds", "0.02"],
    );
    let autopilot = Proc::spawn(
        "sim-client",
        &["--world", &name, "autopilot", "--seed", "3"],
    );
    let client = Client::connect(&name, T).unwrap();
    World {
        name,
        _server: server,
        _autopilot: autopilot,
        client,
    }
}

fn first_difference(a: &[u64], b: &[u64]) -> Option<usize> {
    a.iter().zip(b).position(|(x, y)| x != y)
}

#[test]
fn the_same_scenario_is_bit_identical_across_processes_and_after_reload() {
    let mut a = world("det-a", "7");
    let mut b = world("det-b", "7");
    let (first_a, run_a) = run_scenario(&mut a.client, false);
    let (_, run_b) = run_scenario(&mut b.client, false);
    assert_eq!(run_a.len() as u64, FRAMES + 1);
    assert_eq!(
        first_difference(&run_a, &run_b),
        None,
        "two server processes diverged"
    );

    let report = a.client.reload_world(false).expect("reload");
    assert_eq!((report.frame, report.episode), (0, 2));
    let (first_again, again) = run_scenario(&mut a.client, false);
    // The scenario's last spawn was the episode's 20th actor: the reloaded
    // scene's ids come after every id the first episode used.
    assert_eq!(first_again, first_a + 20, "actor ids are never reused");
    assert_eq!(
        first_difference(&run_a, &again),
        None,
        "the reloaded world ({}) diverged",
        a.name
    );

    // The check can fail: one changed impulse changes every frame after it.
    b.client.reload_world(false).expect("reload");
    let (_, changed) = run_scenario(&mut b.client, true);
    assert_eq!(first_difference(&run_a, &changed), Some(50));
}

#[test]
fn a_changed_seed_changes_the_digests() {
    let mut a = world("seed-a", "7");
    let mut c = world("seed-c", "8");
    let (_, run_a) = run_scenario(&mut a.client, false);
    let (_, run_c) = run_scenario(&mut c.client, false);
    assert_eq!(first_difference(&run_a, &run_c), Some(0));
}

/// A digest list with gaps proves nothing: a `watch --digest` that falls
/// more than its queue behind (here: stopped while the ticker runs) prints
/// which frames it missed and exits 1, instead of dropping them silently.
#[test]
fn a_digest_watcher_that_misses_frames_says_so_and_fails() {
    // In every output format, at the first gap (not after --frames).
    for format in [&[][..], &["--json"][..]] {
        let name = TestWorld::start("digest-gap", &["--sync", "--delta-seconds", "0.02"]);
        let client = Client::connect(&name, T).unwrap();
        let mut ticker = client.claim_ticker().unwrap();
        let mut args = vec!["--world", &name, "watch", "--digest", "--frames", "100000"];
        args.extend_from_slice(format);
        let mut watcher = Proc::spawn("sim-client", &args);
        assert!(watcher.line(T).is_some(), "the watcher printed frame 0");
        simbus_tests::send_signal(watcher.pid(), libc::SIGSTOP).unwrap();
        // Far more than the 16 frames a subscriber queues.
        for _ in 0..40 {
            ticker.tick(T).unwrap();
        }
        simbus_tests::send_signal(watcher.pid(), libc::SIGCONT).unwrap();
        let deadline = Instant::now() + T;
        while watcher.guard.try_wait().unwrap().is_none() {
            assert!(Instant::now() < deadline, "the watcher ended at the gap");
            ticker.tick(T).unwrap();
        }
        let out = watcher.finish(T);
        assert_eq!(out.status.code(), Some(1), "{format:?}: {}", out.stderr);
        if format.is_empty() {
            assert!(
                out.stdout.iter().any(|l| l.starts_with("missed ")),
                "the gap is in the output: {:?}",
                out.stdout
            );
        } else {
            assert!(
                out.json().iter().any(|f| f["missed"].as_u64() > Some(0)),
                "the gap is in the output: {:?}",
                out.stdout
            );
        }
        assert!(
            out.stderr.contains("the digests have gaps"),
            "{format:?}: {}",
            out.stderr
        );
    }
}
