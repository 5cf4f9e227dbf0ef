//! A mirrored world whose link is down: every request service answers
//! through the client library's one status→error mapping, so a batch, a
//! sensor spawn and a recorder call from the mirror's host each fail with
//! `RequestError::Unreachable` (not "status 13, which this client does not
//! expect").
//!
//! The client runs in this test process, in the mirror's host's iceoryx2
//! root (shared memory needs no network namespace): it connects while the
//! link is up, and calls once it is down.

use std::time::Duration;

use shared_types::SensorSpec;
use sim_client::{Client, RecorderError, RequestError, SensorError};
use simbus_tests::{unique_world, TwoHosts};

const LONG: Duration = Duration::from_secs(30);

fn unreachable(e: &RequestError, world: &str) {
    assert!(
        matches!(e, RequestError::Unreachable { world: w } if w == world),
        "expected Unreachable, got: {e}"
    );
}

#[test]
fn batch_sensor_and_recorder_calls_on_a_mirror_whose_link_is_down_are_unreachable() {
    let hosts = TwoHosts::new("zu");
    let world = unique_world("zu");
    let bridge = hosts.mirrored(&world, &[], &["--lease-ms", "1000"]);

    // This process becomes a client on the mirror's host.
    for (key, value) in hosts.b.root.env() {
        std::env::set_var(key, value);
    }
    let client = Client::connect(&world, LONG).expect("connect through the mirror");
    client
        .apply_batch_sync(&[], false)
        .expect("a batch through the live link");

    hosts.b.set_link(false);
    bridge.mirror.wait_line("link down", LONG);

    match client.apply_batch_sync(&[], false) {
        Err(sim_client::BatchError::Request(e)) => unreachable(&e, &world),
        other => panic!("batch: expected Unreachable, got {other:?}"),
    }
    match client.spawn_sensor(SensorSpec::imu([0.0; 3])) {
        Err(SensorError::Request(e)) => unreachable(&e, &world),
        Err(e) => panic!("sensor spawn: expected Unreachable, got {e}"),
        Ok(_) => panic!("sensor spawn: expected Unreachable, got a sensor"),
    }
    match client.recorder_status() {
        Err(RecorderError::Request(e)) => unreachable(&e, &world),
        other => panic!("recorder: expected Unreachable, got {other:?}"),
    }
}
