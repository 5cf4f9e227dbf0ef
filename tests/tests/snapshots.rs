//! Snapshots: the ticker saves the whole world in the server's memory and
//! restores it later as a new episode from exactly that state. The frame
//! ids go on; the same commands after a restore give the digests they
//! gave after the save, frame for frame. Only the ticker's process saves
//! and restores while it holds the world.

use std::time::Duration;

use shared_types::{Command, SensorSpec};
use sim_client::{Client, SnapshotError, SnapshotId, Ticker};
use simbus_tests::*;

const WAIT: Duration = Duration::from_secs(10);

/// Step `i` of the scripted sequence: a push, a box, a vehicle's control.
fn script(i: u64, vehicle: u64, some_box: u64) -> Vec<Command> {
    let mut commands = Vec::new();
    if i.is_multiple_of(10) {
        commands.push(Command::apply_impulse(some_box, [0.5, 2.0, -0.3]));
    }
    if i % 33 == 5 {
        commands.push(Command::spawn_box(
            [1.0 + i as f32 * 0.01, 5.0, 2.0],
            [0.3; 3],
        ));
    }
    if i.is_multiple_of(25) {
        let throttle = 0.3 + (i % 4) as f32 * 0.15;
        commands.push(Command::vehicle_control(vehicle, throttle, 0.2, 0.0, false));
    }
    commands
}

/// Runs the script for `frames` frames: (frame, source frame, digest) each.
fn run(
    client: &mut Client,
    ticker: &mut Ticker,
    frames: u64,
    ids: (u64, u64),
) -> Vec<(u64, u64, u64)> {
    (0..frames)
        .map(|i| {
            let commands = script(i, ids.0, ids.1);
            if !commands.is_empty() {
                client.apply_batch_sync(&commands, false).unwrap();
            }
            ticker.tick(WAIT).unwrap();
            let frame = client.wait_for_tick(WAIT).unwrap();
            let source = frame.header.source_timestamp().frame;
            (frame.frame(), source, frame.digest())
        })
        .collect()
}

#[test]
fn a_restored_snapshot_gives_the_digests_of_the_run_after_its_save() {
    let (world, mut client, mut ticker) = sync_world("snapshot", &["--seed", "4"]);
    let depth = client
        .spawn_sensor(SensorSpec::depth([0.0, 3.0, -12.0], 32, 24, 70.0, 50.0))
        .unwrap();
    let first = client.wait_for_tick(WAIT).unwrap();
    let vehicle = first
        .actors
        .iter()
        .find(|a| a.kind == shared_types::ActorKind::Vehicle as u32)
        .unwrap()
        .id;
    let some_box = first
        .actors
        .iter()
        .find(|a| a.kind == shared_types::ActorKind::Box as u32)
        .unwrap()
        .id;
    for _ in 0..100 {
        ticker.tick(WAIT).unwrap();
        client.wait_for_tick(WAIT).unwrap();
    }
    let id = client.save_snapshot().unwrap();
    let list = client.snapshots().unwrap();
    assert_eq!(list.len(), 1);
    assert_eq!((list[0].id, list[0].frame, list[0].sensors), (id.0, 100, 1));

    let after_save = run(&mut client, &mut ticker, 100, (vehicle, some_box));
    assert_eq!(after_save[0].0, 101);

    // A restore by another process while this one ticks: refused, naming
    // the ticker, and nothing changes.
    let other = world.cli(&["snapshot", "restore", &id.0.to_string()]);
    assert_eq!(other.status.code(), Some(2), "{other}");
    assert!(other.stderr.contains("only the ticker"), "{other}");
    assert!(
        other.stderr.contains(&std::process::id().to_string()),
        "{other}"
    );

    let restored_frame = client.restore_snapshot(id).unwrap();
    assert_eq!(restored_frame, 201, "frame ids go on");
    let restored = client.wait_for_tick(WAIT).unwrap();
    assert_eq!(restored.frame(), 201);
    assert_eq!(restored.header.source_timestamp().frame, 100);
    assert_eq!(restored.episode(), first.episode() + 1);
    // The snapshot's sensor is back under its id, and captures again.
    let mut reader = client.sensor(depth.id()).unwrap();

    let after_restore = run(&mut client, &mut ticker, 100, (vehicle, some_box));
    for (saved, again) in after_save.iter().zip(&after_restore) {
        assert_eq!(again.0, saved.0 + 101, "frame ids go on");
        assert_eq!(again.1, saved.1, "the same line of frames");
        assert_eq!(again.2, saved.2, "frame {} after the restore", again.0);
    }
    let capture = reader.recv(WAIT).unwrap();
    assert!(capture.header().frame > 201);

    // Unknown ids are refused; a dropped snapshot is gone.
    assert!(matches!(
        client.restore_snapshot(SnapshotId(99)),
        Err(SnapshotError::Unknown { .. })
    ));
    client.drop_snapshot(id).unwrap();
    assert!(client.snapshots().unwrap().is_empty());
}
