//! A mirrored world that makes no frames (synchronous, nobody ticks):
//! every answer from its server still reaches the mirror's host. The
//! exporting bridge waits for answers on the world's frame-ready event,
//! which the server rings after answering what a client announced, so a
//! batch, a sensor spawn and list, a recorder call and a status request
//! from another host are each answered with what the server said, though
//! no frame wakes the exporter.
//!
//! The client runs in this test process, in the mirror's host's iceoryx2
//! root (shared memory needs no network namespace).

use std::time::Duration;

use shared_types::{Command, CommandStatus, SensorSpec};
use sim_client::Client;
use simbus_tests::{unique_world, TwoHosts};

const LONG: Duration = Duration::from_secs(30);

#[test]
fn batch_sensor_and_recorder_calls_through_a_mirror_are_answered_while_no_frame_comes() {
    let hosts = TwoHosts::new("za");
    let world = unique_world("za");
    let _bridge = hosts.mirrored(&world, &["--sync", "--delta-seconds", "0.05"], &[]);

    // This process becomes a client on the mirror's host.
    for (key, value) in hosts.b.root.env() {
        std::env::set_var(key, value);
    }
    let mut client = Client::connect(&world, LONG).expect("connect through the mirror");
    client.set_request_timeout(LONG);
    let before = client.status().expect("status through the mirror");
    assert_eq!(before.frame, 0, "nobody ticks: the world stays at frame 0");
    // The mirror serves the world here: its run is not one it resumed
    // (issue 44, item 10: status said "resumed the run of pid <server>").
    assert_eq!(before.run_pid, before.server_pid, "{before:?}");
    let shown = hosts.b.client(&world, "10", &["status"]).finish(LONG);
    shown.assert_success();
    assert!(
        !shown.stdout.iter().any(|l| l.contains("resumed the run")),
        "{shown}"
    );

    let batch = client
        .apply_batch_sync(&[Command::spawn_vehicle([0.0, 1.0, 20.0])], false)
        .expect("a batch through the mirror");
    assert_eq!(batch.frame, 1, "the batch shows from the next frame");
    assert_eq!(batch.results.len(), 1, "{batch:?}");
    assert_eq!(
        batch.results[0].status,
        CommandStatus::Ok as u32,
        "{batch:?}"
    );
    assert_ne!(batch.results[0].actor, 0, "the spawn names its actor");

    let sensor = client
        .spawn_sensor(SensorSpec::imu([0.0; 3]))
        .expect("a sensor spawned through the mirror");
    let listed = client
        .list_sensors()
        .expect("the sensors through the mirror");
    assert!(
        listed.iter().any(|info| info.id == sensor.id()),
        "the new sensor {} is listed: {listed:?}",
        sensor.id()
    );

    let recorder = client
        .recorder_status()
        .expect("the recorder's status through the mirror");
    assert!(!recorder.recording, "{recorder:?}");

    let after = client.status().expect("status through the mirror");
    assert_eq!(after.frame, 0, "still no frame: answers came without one");
    assert_eq!(
        after.actor_count,
        before.actor_count + 1,
        "the batch's vehicle is in the world"
    );
}
