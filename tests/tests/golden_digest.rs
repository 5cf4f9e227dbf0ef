//! Physics results are pinned: a short fixed scenario (the default scene,
//! seed 7, synchronous mode with a fixed step, a few batched commands) must
//! give the digests committed here, frame for frame, on every machine and
//! every build — as rapier's `tests/snapshot_portability.rs` pins its own.
//! An upgrade of rapier, a change of the scene or of a command's meaning
//! that changes results fails this test; if the change is intended, update
//! the digests and say so in the commit.

use std::time::Duration;

use shared_types::Command;
use sim_client::Client;
use simbus_tests::TestWorld;

const T: Duration = Duration::from_secs(20);

/// (frame, digest) checkpoints of the scenario.
const GOLDEN: [(u64, u64); 3] = [
    (0, 0x462b055fd4df3212),
    (100, 0x7cdc18bba2df6782),
    (300, 0x4f11bd305e805d22),
];

#[test]
fn a_fixed_scenario_gives_the_committed_digests() {
    let world = TestWorld::start(
        "golden",
        &["--sync", "--seed", "7", "--delta-seconds", "0.02"],
    );
    let mut client = Client::connect(&world, T).unwrap();
    let mut ticker = client.claim_ticker().unwrap();
    let first = client.wait_for_tick(T).unwrap();
    let id = |nth: u64| first.header.first_actor_id + nth - 1;
    let mut digests = vec![(0, first.digest())];
    for frame in 1..=300 {
        let commands = match frame {
            10 => vec![Command::apply_impulse(id(3), [2.0, 3.0, 0.0])],
            20 => vec![Command::vehicle_control(id(16), 0.8, 0.3, 0.0, false)],
            150 => vec![Command::spawn_box([0.0, 6.0, 0.0], [0.4, 0.4, 0.4])],
            _ => Vec::new(),
        };
        if !commands.is_empty() {
            let response = client.apply_batch_sync(&commands, false).unwrap();
            assert!(response.errors().is_empty(), "{:?}", response.errors());
        }
        assert_eq!(ticker.tick(T).unwrap(), frame);
        let snapshot = client.wait_for_tick(T).unwrap();
        if GOLDEN.iter().any(|(f, _)| *f == frame) {
            digests.push((frame, snapshot.digest()));
        }
    }
    let printed: Vec<String> = digests
        .iter()
        .map(|(f, d)| format!("({f}, 0x{d:016x})"))
        .collect();
    assert_eq!(digests, GOLDEN, "digests now: [{}]", printed.join(", "));
}
