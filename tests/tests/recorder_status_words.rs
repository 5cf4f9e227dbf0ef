//! What the recorder says after things a user did not ask for (issue 44,
//! items 6, 7 and 13): a recording that fills its disk is reported as
//! stopped by itself at a frame, with the bytes on disk and the cause, by
//! `recorder status` and by a later `recorder stop` (it said "0 bytes",
//! and stop answered "no recording is running" with no reason), and
//! `recorder info` says the file may have been cut short by a full disk; a
//! server that only replayed says it recorded nothing (it read as if the
//! replayed file had been overwritten, "0 frames, 0 bytes"); `recorder
//! collisions` counts time from the recording's start, as `recorder
//! blocked` does and CARLA's recorder.

use std::time::Duration;

use shared_types::SensorSpec;
use simbus_tests::{sync_world_at, Scratch, TestWorld, Tmpfs};

const T: Duration = Duration::from_secs(20);

#[test]
fn a_recording_that_fills_its_disk_says_where_it_stopped_what_it_holds_and_why() {
    let scratch = Scratch::new("rec-full");
    let disk = Tmpfs::mount(scratch.file("small"), "2m");
    let path = disk.0.join("rec.mcap");
    let path_text = path.to_str().unwrap();
    let (world, client, mut ticker) = sync_world_at("rec-full", "0.05", &[]);
    let _camera = client
        .spawn_sensor(SensorSpec::depth([0.0, 3.0, -12.0], 160, 120, 70.0, 50.0))
        .unwrap();
    client.start_recorder(&path, true).unwrap();
    let mut status = client.recorder_status().unwrap();
    for _ in 0..20_000 {
        if !status.recording {
            break;
        }
        ticker.tick(T).unwrap();
        status = client.recorder_status().unwrap();
    }
    assert!(!status.recording, "the disk filled: {status:?}");
    assert!(status.recorded, "{status:?}");
    let on_disk = std::fs::metadata(&path).unwrap().len();
    assert!(on_disk > 1 << 20, "{on_disk} bytes");
    assert_eq!(status.bytes, on_disk, "the bytes on disk: {status:?}");
    assert!(
        status.message.contains("stopped by itself at frame")
            && status.message.contains("No space left on device")
            && status
                .message
                .contains(&format!("the file holds {on_disk} bytes")),
        "{status:?}"
    );

    let stop = world.cli(&["recorder", "stop"]);
    stop.assert_code(2);
    assert!(
        stop.stderr.contains(&format!(
            "no recording is running: the recording to {path_text} stopped by itself at frame"
        )) && stop.stderr.contains("No space left on device"),
        "{stop}"
    );
    let shown = world.cli(&["recorder", "status"]);
    shown.assert_success();
    shown.line_starting(&format!("recorder   stopped; last: {path_text} ("));
    assert!(
        !shown.stdout.iter().any(|l| l.contains(" 0 bytes")),
        "{shown}"
    );
    let info = world.cli(&["recorder", "info", path_text]);
    info.assert_success();
    info.line_starting(
        "closed       no: still being recorded, or cut short (its server was killed or its disk \
         filled); readable up to frame",
    );
}

#[test]
fn a_server_that_only_replayed_says_it_recorded_nothing() {
    let scratch = Scratch::new("rec-replay-only");
    let path = scratch.file("run.mcap");
    {
        let (_world, client, mut ticker) = sync_world_at("rec-source", "0.05", &[]);
        client.start_recorder(&path, false).unwrap();
        for _ in 0..20 {
            ticker.tick(T).unwrap();
        }
        client.stop_recorder().unwrap();
    }
    let world = TestWorld::start("rec-replay-only", &[]);
    world
        .cli(&["replay", path.to_str().unwrap()])
        .assert_success();
    let shown = world.cli(&["recorder", "status"]);
    shown.assert_success();
    assert_eq!(
        shown.stdout[0], "recorder   idle (nothing recorded since the server started)",
        "{shown}"
    );
    shown.line_starting("replay     ");
    assert!(
        shown.stdout[1].contains(&format!(" of {}", path.display())),
        "the replay names its file: {shown}"
    );
    let json = world.cli(&["recorder", "status", "--json"]);
    assert_eq!(json.json()[0]["recorded"], false, "{json}");
}

#[test]
fn collisions_and_blocked_count_time_from_the_recordings_start() {
    let scratch = Scratch::new("rec-times");
    let path = scratch.file("late.mcap");
    let (world, client, mut ticker) = sync_world_at("rec-times", "0.05", &[]);
    // 100 frames (5 s) before the recording starts: the boxes have landed.
    for _ in 0..100 {
        ticker.tick(T).unwrap();
    }
    let (_, start) = ticker.last_frame().expect("ticked");
    client.start_recorder(&path, false).unwrap();
    // Something to collide: a box dropped on the ground, 3 s to land.
    let mut drop_a_box = || {
        client
            .spawn_actor(shared_types::Command::spawn_box(
                [20.0, 3.0, 20.0],
                [0.5; 3],
            ))
            .unwrap();
        for _ in 0..60 {
            ticker.tick(T).unwrap();
        }
    };
    drop_a_box();
    // A reload starts frame ids again, not the recording's time: the
    // second episode's collisions come later.
    client.reload_world(false).unwrap();
    drop_a_box();
    client.stop_recorder().unwrap();
    let out = world.cli(&["recorder", "collisions", "--json", path.to_str().unwrap()]);
    out.assert_success();
    let collisions = out.json()[0].as_array().unwrap().clone();
    assert!(!collisions.is_empty(), "{out}");
    // The first episode's: simulation time less the recording's start.
    let first: Vec<_> = collisions
        .iter()
        .take_while(|c| c["elapsed_seconds"].as_f64().unwrap() > start as f64 / 1e9)
        .collect();
    assert!(!first.is_empty(), "{out}");
    for c in &first {
        let time = c["time_seconds"].as_f64().unwrap();
        let elapsed = c["elapsed_seconds"].as_f64().unwrap();
        assert!((0.0..=3.0).contains(&time), "recording time: {c}");
        let since_start = elapsed - start as f64 / 1e9;
        assert!((time - since_start).abs() < 1e-6, "{c}");
    }
    // Across the reload, in the file's order, recording time never goes
    // back and stays within the recording's 6 s.
    let times: Vec<f64> = collisions
        .iter()
        .map(|c| c["time_seconds"].as_f64().unwrap())
        .collect();
    assert!(times.windows(2).all(|w| w[0] <= w[1]), "{times:?}");
    assert!(times.iter().all(|t| (0.0..=6.05).contains(t)), "{times:?}");
    assert!(
        times.iter().any(|t| *t > 3.0),
        "the second episode's collisions: {times:?}"
    );
    let text = world.cli(&["recorder", "collisions", path.to_str().unwrap()]);
    text.assert_success();
    assert!(
        text.stdout
            .last()
            .unwrap()
            .ends_with("(times are recording seconds: since the recording's start, as CARLA's recorder counts)"),
        "{text}"
    );
}
