//! Limits a user can see and set: `sim-server --max-clients N` sizes every
//! service of the world (the test runs 100), `--max-sensor-readers M` each
//! sensor; a client past a limit gets an error naming the flag that raises
//! it; a watcher holds only a frame subscription and a listener, so it uses
//! none of the ports that commands, sensors and the lockstep need.

use std::time::Duration;

use iceoryx2::prelude::*;
use shared_types::{
    Command, LockstepRequest, LockstepResponse, SensorInfo, SensorRequest, SensorResponseHeader,
    SensorSpec,
};
use sim_client::{Client, ConnectError, RequestError, SensorError};
use simbus_tests::raw::{batch_service, control_service, service_name, service_names};
use simbus_tests::{client, Proc, TestWorld};
use simbus_transport::Bus;

const T: Duration = Duration::from_secs(60);

/// Clients connected to each request-response service of `world`:
/// (control, batch, lockstep, sensors).
fn request_clients(world: &str) -> [usize; 4] {
    let names = service_names(world);
    let node = NodeBuilder::new().create::<Bus>().unwrap();
    let control = control_service(&node, &names);
    let batch = batch_service(&node, &names);
    let lockstep = node
        .service_builder(&service_name(&names.lockstep))
        .request_response::<LockstepRequest, LockstepResponse>()
        .open()
        .unwrap();
    let sensors = node
        .service_builder(&service_name(&names.sensors))
        .request_response::<SensorRequest, [SensorInfo]>()
        .response_user_header::<SensorResponseHeader>()
        .open()
        .unwrap();
    [
        control.dynamic_config().number_of_clients(),
        batch.dynamic_config().number_of_clients(),
        lockstep.dynamic_config().number_of_clients(),
        sensors.dynamic_config().number_of_clients(),
    ]
}

#[test]
fn a_watcher_holds_no_command_sensor_lockstep_or_control_port() {
    let world = TestWorld::start("watcher-ports", &["--delta-seconds", "0.01", "--realtime"]);
    let watcher = Proc::spawn("sim-client", &["--world", &world, "watch"]);
    assert!(watcher.line(T).is_some(), "{}", watcher.stderr());
    assert_eq!(request_clients(&world), [0, 0, 0, 0], "a watcher's ports");
    // A client that asks, spawns and reads sensors opens exactly those.
    let api = Client::connect(&world, T).unwrap();
    assert_eq!(
        request_clients(&world),
        [0, 0, 0, 0],
        "connecting opens none"
    );
    api.status().unwrap();
    api.spawn_actor(Command::spawn_box([0.0, 3.0, 0.0], [0.5; 3]))
        .unwrap();
    api.list_sensors().unwrap();
    assert_eq!(request_clients(&world), [1, 1, 0, 1]);
    let _participant = api.join_lockstep("test").unwrap();
    assert_eq!(request_clients(&world), [1, 1, 1, 1]);
}

#[test]
fn a_client_past_max_clients_is_told_the_flag() {
    let world = TestWorld::start("max-clients", &["--max-clients", "2"]);
    let _first = Client::connect(&world, T).unwrap();
    let _second = Client::connect(&world, T).unwrap();
    match Client::connect(&world, T) {
        Err(e @ ConnectError::Full { .. }) => {
            let message = e.to_string();
            assert!(
                message.contains("(2)") && message.contains("--max-clients"),
                "{message}"
            );
        }
        other => panic!("expected the limit to be named, got {:?}", other.err()),
    }
    let out = client(&world, &["watch", "--frames", "1"]);
    assert_eq!(out.status.code(), Some(1));
    assert!(out.stderr.contains("--max-clients"), "{}", out.stderr);
}

#[test]
fn a_sensor_reader_past_max_sensor_readers_is_told_the_flag() {
    let world = TestWorld::start("max-readers", &["--max-sensor-readers", "1"]);
    let api = Client::connect(&world, T).unwrap();
    let _only = api.spawn_sensor(SensorSpec::imu([0.0; 3])).unwrap();
    match api.sensor(_only.id()) {
        Err(SensorError::Request(e @ RequestError::Full { .. })) => {
            let message = e.to_string();
            assert!(message.contains("--max-sensor-readers"), "{message}");
        }
        other => panic!("expected the limit to be named, got {:?}", other.err()),
    }
}

/// The scale: 64 watchers (in the lockstep, so none may miss a
/// frame), one ticker and 16 readers of one sensor on a world admitting 100
/// clients. Every watcher prints the same consecutive frames with the same
/// digests, and the 16 readers read the same bytes for every capture.
#[test]
fn sixty_four_watchers_a_ticker_and_sixteen_sensor_readers_share_one_world() {
    const WATCHERS: usize = 64;
    const READERS: usize = 16;
    const FRAMES: u64 = 20;
    let world = TestWorld::start(
        "crowd",
        &["--sync", "--delta-seconds", "0.02", "--max-clients", "100"],
    );
    let api = Client::connect(&world, T).unwrap();
    let camera = api
        .spawn_sensor(SensorSpec::depth([-16.0, 3.0, 0.0], 64, 48, 90.0, 40.0))
        .unwrap();
    let mut readers: Vec<_> = (0..READERS - 1)
        .map(|_| api.sensor(camera.id()).unwrap())
        .collect();
    readers.push(camera);
    let frames = (FRAMES + 1).to_string();
    let watchers: Vec<Proc> = (0..WATCHERS)
        .map(|_| {
            Proc::spawn(
                "sim-client",
                &[
                    "--world",
                    &world,
                    "--timeout",
                    "60",
                    "watch",
                    "--lockstep",
                    "--digest",
                    "--frames",
                    &frames,
                ],
            )
        })
        .collect();
    simbus_tests::wait_for_participants(&api, WATCHERS as u32);
    let mut ticker = api.claim_ticker().unwrap();
    for frame in 1..=FRAMES {
        assert_eq!(ticker.tick(T).unwrap(), frame);
        let captures: Vec<_> = readers.iter_mut().map(|r| r.recv(T).unwrap()).collect();
        for capture in &captures {
            assert_eq!(capture.header().frame, frame);
            assert!(capture.bytes() == captures[0].bytes(), "the same bytes");
        }
    }
    let outputs: Vec<Vec<String>> = watchers
        .into_iter()
        .map(|w| {
            let out = w.finish(T);
            out.assert_success();
            out.stdout
        })
        .collect();
    let expected: Vec<String> = (0..=FRAMES).map(|f| format!("frame {f} ")).collect();
    for output in &outputs {
        assert_eq!(output.len(), expected.len(), "{output:?}");
        for (line, prefix) in output.iter().zip(&expected) {
            assert!(line.starts_with(prefix), "{line} is not {prefix}");
        }
        assert_eq!(output, &outputs[0], "every watcher saw the same digests");
    }
}
