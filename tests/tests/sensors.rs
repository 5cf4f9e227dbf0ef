//! Sensors: a depth camera reads the distance to a box and the far range
//! elsewhere; a lidar over flat ground returns points on the plane; in
//! synchronous mode every capture arrives once, stamped with its frame, at
//! exactly the frames its period implies; two readers see the same bytes of
//! an 8 MiB capture; a reader killed with SIGKILL stalls nothing.

use std::time::Duration;

use shared_types::{Command, SensorSpec};
use sim_client::{Client, Ticker};
use simbus_tests::{Proc, TestWorld};

const T: Duration = Duration::from_secs(20);

fn sync_world(tag: &str, scene: &str) -> (TestWorld, Client, Ticker) {
    simbus_tests::sync_world(tag, &["--scene", scene, "--max-sensor-readers", "4"])
}

#[test]
fn a_depth_camera_reads_the_distance_to_a_box_and_far_elsewhere() {
    let (_server, client, mut ticker) = sync_world("depth", "empty");
    let spawned = client
        .apply_batch_sync(
            &[Command::spawn_box([10.0, 5.0, 0.0], [1.0, 1.0, 1.0])],
            false,
        )
        .unwrap();
    let id = spawned.results[0].actor;
    client
        .apply_batch_sync(&[Command::set_gravity(id, false)], false)
        .unwrap();
    let (w, h) = (64usize, 48usize);
    let mut camera = client
        .spawn_sensor(SensorSpec::depth(
            [0.0, 5.0, 0.0],
            w as u32,
            h as u32,
            60.0,
            100.0,
        ))
        .unwrap();
    let frame = ticker.tick(T).unwrap();
    let capture = camera.recv(T).unwrap();
    assert_eq!(capture.header().frame, frame);
    assert_eq!(capture.header().size, [w as u32, h as u32]);
    let depth = capture.depth().unwrap();
    assert_eq!(depth.len(), w * h);
    // The box's near face is 9 m ahead, square to the optical axis: planar
    // depth is 9 m at every pixel that sees it (tolerance 1 mm).
    for (u, v) in [
        (w / 2, h / 2),
        (w / 2 - 2, h / 2 + 2),
        (w / 2 + 3, h / 2 - 1),
    ] {
        let d = depth[v * w + u];
        assert!((d - 9.0).abs() < 1e-3, "pixel ({u}, {v}) reads {d}");
    }
    for (u, v) in [(0, 0), (w - 1, h - 1), (0, h / 2), (w - 1, 0)] {
        assert_eq!(depth[v * w + u], 100.0, "pixel ({u}, {v}) sees nothing");
    }
}

#[test]
fn a_lidar_over_flat_ground_returns_points_on_the_plane() {
    let (_server, client, mut ticker) = sync_world("lidar", "boxes:1");
    let position = [15.0, 2.0, 15.0];
    let mut lidar = client
        .spawn_sensor(SensorSpec::lidar(position, 16, 360, 50.0, -10.0, -40.0))
        .unwrap();
    ticker.tick(T).unwrap();
    let capture = lidar.recv(T).unwrap();
    let points = capture.points().unwrap();
    assert!(points.len() > 16 * 360 / 2, "{} returns", points.len());
    for p in points {
        // Identity orientation: the world point is the sensor position plus p.
        let y = position[1] + p.y;
        assert!(y.abs() < 1e-3, "a return {y} m off the ground: {p:?}");
        assert!(p.intensity > 0.0 && p.intensity < 1.0);
    }
}

#[test]
fn in_sync_mode_every_capture_arrives_once_at_the_frames_its_period_implies() {
    let (_server, client, mut ticker) = sync_world("periods", "default");
    let periods = [0.0, 0.04, 0.1];
    let mut sensors: Vec<_> = periods
        .iter()
        .map(|&p| {
            client
                .spawn_sensor(SensorSpec::imu([0.0, 1.0, 0.0]).attached_to(3).every(p))
                .unwrap()
        })
        .collect();
    let mut counts = [0u64; 3];
    for _ in 0..1000 {
        let frame = ticker.tick(T).unwrap();
        let elapsed_ns = frame * 20_000_000;
        for (i, sensor) in sensors.iter_mut().enumerate() {
            let captures: Vec<_> = sensor
                .queue()
                .map(|c| *c.expect("a capture").header())
                .collect();
            let period_ns = (periods[i] * 1e9).round() as u64;
            let due = period_ns == 0 || elapsed_ns % period_ns == 0;
            assert_eq!(
                captures.len(),
                usize::from(due),
                "sensor {i} at frame {frame}"
            );
            for header in captures {
                assert_eq!(header.frame, frame, "stamped with its frame");
                assert_eq!(header.elapsed_ns, elapsed_ns);
                counts[i] += 1;
                assert_eq!(header.sequence, counts[i], "none lost, none repeated");
            }
        }
    }
    assert_eq!(counts, [1000, 500, 200]);
    assert!(sensors.iter().all(|s| s.missed() == 0));
}

#[test]
fn two_readers_see_the_same_bytes_of_an_8_mib_capture() {
    let (_server, client, mut ticker) = sync_world("eight-mib", "empty");
    let spec = SensorSpec::depth([0.0, 1.0, 0.0], 2048, 1024, 90.0, 100.0);
    let mut first = client.spawn_sensor(spec).unwrap();
    let mut second = client.sensor(first.id()).unwrap();
    client
        .apply_batch_sync(&[Command::spawn_sphere([5.0, 1.0, 0.0], 1.0)], false)
        .unwrap();
    ticker.tick(T).unwrap();
    let a = first.recv(T).unwrap();
    let b = second.recv(T).unwrap();
    assert_eq!(a.bytes().len(), 8 * 1024 * 1024);
    assert_eq!(a.header(), b.header());
    assert!(a.bytes() == b.bytes(), "the same bytes for both readers");
    assert!(
        a.depth().unwrap().iter().any(|d| *d < 100.0),
        "the sphere is in view"
    );
}

#[test]
fn a_reader_killed_with_sigkill_does_not_stall_the_server() {
    let (_server, client, mut ticker) = sync_world("dead-reader", "empty");
    let world = client.world().to_string();
    let sensor = client
        .spawn_sensor(SensorSpec::depth([0.0; 3], 256, 256, 90.0, 50.0))
        .unwrap();
    let id = sensor.id().to_string();
    let mut readers: Vec<Proc> = (0..3)
        .map(|_| {
            Proc::spawn(
                "sim-client",
                &["--world", &world, "sensor", "watch", &id, "--json"],
            )
        })
        .collect();
    // Tick until every reader has subscribed and received a capture.
    let mut waiting: Vec<&Proc> = readers.iter().collect();
    for _ in 0..400 {
        ticker.tick(T).unwrap();
        waiting.retain(|r| r.line(Duration::from_millis(50)).is_none());
        if waiting.is_empty() {
            break;
        }
    }
    assert!(waiting.is_empty(), "every reader received a capture");
    for reader in &mut readers {
        reader.guard.kill().unwrap();
    }
    // The world goes on, every tick within its timeout...
    for _ in 0..50 {
        ticker.tick(Duration::from_secs(5)).unwrap();
    }
    // ... and the dead readers' places are free again for new ones (the
    // sensor admits 4 readers: `sensor` itself and 3 more).
    let mut fresh: Vec<_> = (0..3)
        .map(|_| client.sensor(sensor.id()).unwrap())
        .collect();
    match client.sensor(sensor.id()) {
        Err(e) => assert!(
            e.to_string()
                .contains("the most readers of this sensor admitted (4)")
                && e.to_string().contains("--max-sensor-readers"),
            "{e}"
        ),
        Ok(_) => panic!("a fifth reader was admitted"),
    }
    let frame = ticker.tick(T).unwrap();
    for reader in &mut fresh {
        assert_eq!(reader.recv(T).unwrap().header().frame, frame);
    }
}

#[test]
fn the_sensor_commands_spawn_list_watch_and_save_pictures() {
    let world = TestWorld::start(
        "sensor-cli",
        &["--fixed-delta-seconds", "0.05", "--realtime"],
    );
    let out = simbus_tests::client(
        &world,
        &[
            "sensor",
            "spawn",
            "depth",
            "--size",
            "32,24",
            "--at=-12,3,0",
            "--json",
        ],
    );
    out.assert_success();
    let id = out.json()[0]["id"].as_u64().unwrap();
    let lidar = simbus_tests::client(
        &world,
        &["sensor", "spawn", "lidar", "--attach", "3", "--json"],
    );
    lidar.assert_success();

    let list = simbus_tests::client(&world, &["sensor", "list", "--json"]);
    list.assert_success();
    let kinds: Vec<_> = list
        .json()
        .iter()
        .map(|s| s["kind"].as_str().unwrap().to_owned())
        .collect();
    assert_eq!(kinds, ["depth", "lidar"]);

    let watched = simbus_tests::client(
        &world,
        &[
            "sensor",
            "watch",
            &id.to_string(),
            "--captures",
            "3",
            "--json",
        ],
    );
    watched.assert_success();
    let captures = watched.json();
    assert_eq!(captures.len(), 3);
    assert!(captures.iter().all(|c| c["bytes"] == 32 * 24 * 4));
    assert!(captures
        .windows(2)
        .all(|w| w[1]["frame"].as_u64() > w[0]["frame"].as_u64()));

    let dir = std::env::temp_dir().join(world.name());
    let saved = simbus_tests::client(
        &world,
        &[
            "sensor",
            "save",
            &id.to_string(),
            "--out",
            dir.to_str().unwrap(),
        ],
    );
    saved.assert_success();
    let png = std::fs::read_dir(&dir)
        .unwrap()
        .next()
        .unwrap()
        .unwrap()
        .path();
    assert_eq!(&std::fs::read(&png).unwrap()[..8], b"\x89PNG\r\n\x1a\n");
    std::fs::remove_dir_all(&dir).ok();

    for (args, message) in [
        (
            &["sensor", "spawn", "sonar"][..],
            "unknown sensor kind 'sonar': expected depth, rgb, semantic, instance, lidar, semantic-lidar, radar",
        ),
        (
            &["sensor", "spawn", "depth", "--size", "0,10"][..],
            "two whole numbers of pixels in 1..=8192",
        ),
        (
            &["sensor", "spawn", "depth", "--size", "8192,8192"][..],
            "width x height at most 8388608 pixels (32 MiB per capture)",
        ),
        (
            &["sensor", "spawn", "imu", "--attach", "999"][..],
            "unknown actor",
        ),
        (
            &["sensor", "watch", "77", "--captures", "1"][..],
            "unknown sensor",
        ),
    ] {
        let out = simbus_tests::client(&world, args);
        assert_eq!(out.status.code(), Some(2), "{args:?}: {}", out.stderr);
        assert!(out.stderr.contains(message), "{args:?}: {}", out.stderr);
    }
}

#[test]
fn listen_calls_back_with_every_capture_until_stopped() {
    let (_server, client, mut ticker) = sync_world("listen", "empty");
    let camera = client
        .spawn_sensor(SensorSpec::depth([0.0; 3], 8, 8, 60.0, 10.0))
        .unwrap();
    let (seen, captures) = std::sync::mpsc::channel();
    let listening = camera
        .listen(move |c| {
            seen.send((c.header().frame, c.bytes().len()))
                .expect("the test reads every capture")
        })
        .unwrap();
    for _ in 0..20 {
        let frame = ticker.tick(T).unwrap();
        // The callback has the capture before the next tick.
        let (captured, bytes) = captures.recv_timeout(T).expect("the callback of a capture");
        assert_eq!(
            (captured, bytes),
            (frame, 8 * 8 * 4),
            "every capture once, in order"
        );
    }
    // Stopping ends the callbacks (and drops the callback) before it
    // returns: a capture of the next frame is never passed to it.
    listening.stop();
    ticker.tick(T).unwrap();
    assert_eq!(
        captures.recv_timeout(T),
        Err(std::sync::mpsc::RecvTimeoutError::Disconnected),
        "no capture after stop"
    );
}

#[test]
fn a_lockstep_reader_gets_every_capture_and_its_death_stalls_nothing() {
    let (_server, client, mut ticker) = sync_world("lockstep-reader", "empty");
    let world = client.world().to_string();
    let sensor = client
        .spawn_sensor(SensorSpec::depth([0.0; 3], 64, 64, 90.0, 50.0))
        .unwrap();
    let mut reader = Proc::spawn(
        "sim-client",
        &[
            "--world",
            &world,
            "sensor",
            "watch",
            &sensor.id().to_string(),
            "--lockstep",
            "--json",
        ],
    );
    simbus_tests::wait_for_participants(&client, 1);
    // However fast the ticker, the server waits for the reader: every
    // capture arrives, in order, stamped with its frame.
    let ticked: Vec<u64> = (0..30).map(|_| ticker.tick(T).unwrap()).collect();
    for frame in &ticked {
        let line = reader.line(T).expect("a capture for every frame");
        let capture: serde_json::Value = serde_json::from_str(&line).unwrap();
        assert_eq!(capture["frame"].as_u64(), Some(*frame));
        assert_eq!(capture["missed"], 0);
    }
    reader.guard.kill().unwrap();
    for _ in 0..10 {
        ticker
            .tick(Duration::from_secs(5))
            .expect("the world goes on without the dead reader");
    }
    assert_eq!(client.status().unwrap().participants, 0);
}
