//! A recording's life: a killed server leaves every complete chunk
//! readable and replayable, a stopped server (SIGTERM) and a load of another
//! scene close the file cleanly, sensor captures are recorded and the
//! recorded sensors capture the replayed scene bit for bit, sensors spawned
//! during a replay follow the chosen actor, and re-simulation from a
//! keyframe gives the same digests as the original run.

use std::time::Duration;

use shared_types::{ReplayMode, SensorSpec};
use sim_client::{Client, ReplayOptions, Ticker};
use simbus_recording::inspect;
use simbus_recording::{Entry, RecordingReader};
use simbus_tests::{replayed_frames, send_signal, Scratch, TestWorld};

const T: Duration = Duration::from_secs(20);

fn frame_ids(path: &str) -> Vec<u64> {
    let mut reader = RecordingReader::open(path).unwrap();
    let mut ids = Vec::new();
    while let Some(entry) = reader.next() {
        if let Entry::Frame { header, .. } = entry.unwrap() {
            ids.push(header.timestamp.frame);
        }
    }
    ids
}

#[test]
fn a_killed_server_leaves_every_complete_chunk_readable_and_replayable() {
    let scratch = Scratch::new("rec-kill");
    let path = scratch.file("killed.mcap");
    let file = path.to_str().unwrap();
    // 300 boxes: about 30 kB a frame, so the file holds several 1 MiB chunks.
    let (world, client, mut ticker) = sync_world("rec-kill", &["--scene", "boxes:300"]);
    client.start_recorder(&path, false).unwrap();
    for _ in 0..150 {
        ticker.tick(T).unwrap();
    }
    send_signal(world.server.pid(), libc::SIGKILL).unwrap();
    world.server.finish(T);

    let info = inspect::file_info(file, false).expect("readable up to the last complete chunk");
    assert!(info.truncated, "{info:?}");
    assert_eq!(info.stopped, None);
    // Frames still queued for the writer die with the server; what reached
    // the disk in complete chunks is read.
    assert!(
        info.frames >= 1 && info.frames < 151,
        "{} frames",
        info.frames
    );
    let ids = frame_ids(file);
    assert!(
        ids.windows(2).all(|w| w[1] == w[0] + 1),
        "consecutive from the start: {ids:?}"
    );

    let (_fresh, mut replay_client, mut replay_ticker) = sync_world("rec-kill-b", &[]);
    let options = ReplayOptions {
        mode: Some(ReplayMode::Exact),
        ..Default::default()
    };
    let status = replay_client.replay(&path, &options).unwrap();
    assert_eq!(status.replay.total, info.frames);
    let replayed = replayed_frames(&mut replay_client, &mut replay_ticker);
    assert_eq!(
        replayed
            .iter()
            .map(|s| s.recorded_frame().expect("a replayed frame"))
            .collect::<Vec<_>>(),
        ids
    );
}

#[test]
fn a_stopped_server_and_a_load_close_the_recording_cleanly() {
    let scratch = Scratch::new("rec-close");
    // SIGTERM: the server finishes the file before it exits.
    let signal = scratch.file("signal.mcap");
    let (world, client, mut ticker) = sync_world("rec-term", &[]);
    client.start_recorder(&signal, false).unwrap();
    for _ in 0..20 {
        ticker.tick(T).unwrap();
    }
    drop(ticker);
    send_signal(world.server.pid(), libc::SIGTERM).unwrap();
    let finished = world.server.finish(T);
    assert!(finished.status.success(), "{finished}");
    let info = inspect::file_info(signal.to_str().unwrap(), false).unwrap();
    assert_eq!(info.stopped.as_deref(), Some("server stopped by a signal"));
    assert!(!info.truncated);
    assert_eq!(info.frames, 21);

    // Loading another scene ends the recording (a reload does not).
    let load = scratch.file("load.mcap");
    let (_world, client, mut ticker) = sync_world("rec-load", &[]);
    client.start_recorder(&load, false).unwrap();
    ticker.tick(T).unwrap();
    client.reload_world(false).unwrap();
    assert!(
        client.recorder_status().unwrap().recording,
        "a reload is recorded"
    );
    ticker.tick(T).unwrap();
    client.load_world("empty", false).unwrap();
    let status = client.recorder_status().unwrap();
    assert!(!status.recording);
    assert_eq!(
        status.frames, 4,
        "frame 0, a tick, the reloaded frame 0, a tick"
    );
    let info = inspect::file_info(load.to_str().unwrap(), false).unwrap();
    assert_eq!(info.stopped.as_deref(), Some("load"));
    assert_eq!((info.frames, info.episodes), (4, 1));
}

#[test]
fn recorded_sensors_capture_the_replayed_scene_bit_for_bit() {
    let scratch = Scratch::new("rec-sensors");
    let path = scratch.file("sensors.mcap");
    let (_world, client, mut ticker) = sync_world("rec-sens", &[]);
    let depth = client
        .spawn_sensor(SensorSpec::depth([0.0, 3.0, -12.0], 32, 24, 70.0, 50.0))
        .unwrap();
    client.start_recorder(&path, true).unwrap();
    for _ in 0..20 {
        ticker.tick(T).unwrap();
    }
    client.stop_recorder().unwrap();
    drop(depth);
    let file = path.to_str().unwrap();
    let info = inspect::file_info(file, false).unwrap();
    assert_eq!((info.sensors, info.captures), (1, 20));
    let mut recorded = std::collections::BTreeMap::new();
    let mut reader = RecordingReader::open(file).unwrap();
    while let Some(entry) = reader.next() {
        if let Entry::Capture { header, data } = entry.unwrap() {
            recorded.insert(header.frame, data);
        }
    }

    let (_fresh, mut replay_client, mut replay_ticker) = sync_world("rec-sens-b", &[]);
    let options = ReplayOptions {
        mode: Some(ReplayMode::Exact),
        replay_sensors: true,
        ..Default::default()
    };
    replay_client.replay(&path, &options).unwrap();
    replay_ticker.tick(T).unwrap();
    let sensors = replay_client.list_sensors().unwrap();
    assert_eq!(sensors.len(), 1, "the recorded sensor is back");
    let mut sensor = replay_client.sensor(sensors[0].id).unwrap();
    let mut compared = 0;
    for _ in 0..10 {
        let frame = replay_ticker.tick(T).unwrap();
        let capture = sensor.recv(T).unwrap();
        assert_eq!(capture.header().frame, frame);
        // The replayed frame's id is the server's; the recorded one is in its header.
        let snapshot = loop {
            let snapshot = replay_client.wait_for_tick(T).unwrap();
            if snapshot.frame() == frame {
                break snapshot;
            }
        };
        let recorded_frame = snapshot.recorded_frame().expect("a replayed frame");
        assert_eq!(
            Some(capture.bytes()),
            recorded.get(&recorded_frame).map(|d| d.as_slice()),
            "frame {frame} (recorded {recorded_frame})"
        );
        compared += 1;
    }
    assert_eq!(compared, 10);
    replay_client.stop_replayer(false).unwrap();

    // A sensor spawned during a replay rides on the followed actor.
    let follow = 3;
    let options = ReplayOptions {
        follow_id: follow,
        ..Default::default()
    };
    replay_client.replay(&path, &options).unwrap();
    replay_ticker.tick(T).unwrap();
    let imu = replay_client
        .spawn_sensor(SensorSpec::imu([0.0; 3]))
        .unwrap();
    assert_eq!(imu.spec().attach_to, follow);
}

#[test]
fn resimulating_from_a_keyframe_gives_the_original_digests() {
    let scratch = Scratch::new("rec-key");
    let path = scratch.file("keys.mcap");
    let (_world, mut client, mut ticker) = sync_world("rec-key", &["--keyframe-seconds", "1"]);
    client.wait_for_tick(T).unwrap();
    client.start_recorder(&path, false).unwrap();
    let mut original = std::collections::BTreeMap::new();
    for i in 0..100u64 {
        if i == 10 {
            let vehicle = shared_types::Command::spawn_vehicle([-6.0, 1.0, 8.0]);
            client.apply_batch_sync(&[vehicle], false).unwrap();
        }
        let frame = ticker.tick(T).unwrap();
        let snapshot = client.wait_for_tick(T).unwrap();
        assert_eq!(snapshot.frame(), frame);
        original.insert(frame, snapshot.digest());
    }
    client.stop_recorder().unwrap();
    let info = inspect::file_info(path.to_str().unwrap(), false).unwrap();
    assert_eq!(
        info.keyframes, 6,
        "one at the start and one every simulated second of 5"
    );

    // From 3.2 s: the keyframe at 3 s, then real physics.
    let options = ReplayOptions {
        start: 3.2,
        mode: Some(ReplayMode::Resimulate),
        ..Default::default()
    };
    let status = client.replay(&path, &options).unwrap();
    assert_eq!(status.replay.total, 37, "3.2 s to 5 s at 0.05 s");
    let replayed = replayed_frames(&mut client, &mut ticker);
    assert_eq!(replayed.len(), 37);
    for snapshot in &replayed {
        let recorded_frame = snapshot.recorded_frame().expect("a replayed frame");
        assert_eq!(
            Some(&snapshot.digest()),
            original.get(&recorded_frame),
            "frame {} (recorded {recorded_frame})",
            snapshot.frame()
        );
    }
    let status = client.recorder_status().unwrap();
    assert_eq!((status.replay.verified, status.replay.mismatch), (37, None));
}

/// A synchronous world with a fixed 0.05 s step on the default scene (and
/// `args`), seeded; a client and its claim on the ticker.
fn sync_world(tag: &str, args: &[&str]) -> (TestWorld, Client, Ticker) {
    let mut all = vec!["--seed", "4"];
    all.extend_from_slice(args);
    simbus_tests::sync_world_at(tag, "0.05", &all)
}
