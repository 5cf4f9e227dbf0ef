//! A sensor lives as long as its parent and its episode: destroying the actor
//! it rides on, or loading/reloading the world, ends it, and its readers get
//! a clear end-of-stream error instead of silence. Actor ids are never
//! reused within a server's life, so no new actor inherits an old sensor.
//! Every wait of `sensor watch` / `sensor save` honours `--timeout`.

use std::time::Duration;

use shared_types::{Command, SensorEnd, SensorSpec};
use sim_client::{Client, Sensor, WaitError};
use simbus_tests::{client, server, unique_world, Proc, TestWorld};

const T: Duration = Duration::from_secs(20);

/// Reads `sensor` past the captures it had queued and asserts its stream
/// then ends for `reason`.
fn assert_ends(sensor: &mut Sensor, reason: SensorEnd) {
    let ended = loop {
        match sensor.recv(T) {
            Ok(_) => continue,
            Err(e) => break e,
        }
    };
    match ended {
        WaitError::SensorEnded { reason: got, .. } => assert_eq!(got, reason),
        other => panic!("expected the end ({reason}), got: {other}"),
    }
}

fn sensor_ids(world: &str) -> Vec<u64> {
    let out = client(world, &["sensor", "list", "--json"]);
    out.assert_success();
    out.json()
        .iter()
        .map(|s| s["id"].as_u64().unwrap())
        .collect()
}

#[test]
fn destroying_the_parent_ends_the_sensor_and_tells_its_readers() {
    let world = TestWorld::start("orphan", &["--delta-seconds", "0.01", "--realtime"]);
    let api = Client::connect(&world, T).unwrap();
    let parent = api
        .spawn_actor(Command::spawn_box([0.0, 1.0, 0.0], [0.5; 3]))
        .unwrap();
    let mut imu = api
        .spawn_sensor(SensorSpec::imu([0.0, 1.0, 0.0]).attached_to(parent))
        .unwrap();
    let watcher = Proc::spawn(
        "sim-client",
        &["--world", &world, "sensor", "watch", &imu.id().to_string()],
    );
    // The watcher is reading captures before the parent goes.
    assert!(watcher.line(T).is_some(), "{}", watcher.stderr());
    imu.recv(T).unwrap();

    let listening = imu.listen(|_| {}).unwrap();
    api.destroy(parent).unwrap();
    let out = watcher.finish(T);
    assert_eq!(out.status.code(), Some(1), "{}", out.stderr);
    assert!(
        out.stderr.contains(&format!(
            "sensor {} ended: the actor it rode on was destroyed",
            imu.id()
        )),
        "{}",
        out.stderr
    );
    // The API reader ends the same way, after the captures it had queued.
    assert_ends(&mut imu, SensorEnd::ParentDestroyed);
    // CARLA's `listen` learns it too: its callbacks end, and say why.
    let deadline = std::time::Instant::now() + T;
    let ended = loop {
        if let Some(ended) = listening.ended() {
            break ended;
        }
        assert!(std::time::Instant::now() < deadline, "listen never ended");
        std::thread::yield_now();
    };
    assert!(
        matches!(
            ended,
            WaitError::SensorEnded {
                reason: SensorEnd::ParentDestroyed,
                ..
            }
        ),
        "{ended}"
    );
    assert!(
        sensor_ids(&world).is_empty(),
        "the sensor is no longer listed"
    );
}

#[test]
fn a_reload_ends_every_sensor_and_new_actors_never_reuse_an_id() {
    let world = TestWorld::start("reload-sensors", &["--delta-seconds", "0.01", "--realtime"]);
    let api = Client::connect(&world, T).unwrap();
    let parent = api
        .spawn_actor(Command::spawn_box([0.0, 1.0, 0.0], [0.5; 3]))
        .unwrap();
    let mut on_actor = api
        .spawn_sensor(SensorSpec::imu([0.0; 3]).attached_to(parent))
        .unwrap();
    let mut in_world = api.spawn_sensor(SensorSpec::imu([0.0; 3])).unwrap();
    on_actor.recv(T).unwrap();

    let report = api.reload_world(false).unwrap();
    for sensor in [&mut on_actor, &mut in_world] {
        assert_ends(sensor, SensorEnd::EpisodeEnded);
    }
    assert!(
        sensor_ids(&world).is_empty(),
        "a new episode has no sensors"
    );

    // The reloaded scene and anything spawned after it get ids never used
    // before: nothing inherits the old parent's id.
    let fresh = api
        .spawn_actor(Command::spawn_box([0.0, 1.0, 0.0], [0.5; 3]))
        .unwrap();
    assert!(fresh > parent, "new id {fresh} after old {parent}");
    assert_eq!(u64::from(report.actor_count) + parent + 1, fresh);
    // A sensor spawned now gets a new sensor id too.
    let next = api.spawn_sensor(SensorSpec::imu([0.0; 3])).unwrap();
    assert!(next.id() > in_world.id());
}

#[test]
fn sensor_watch_and_save_give_up_after_the_timeout_when_nothing_comes() {
    let world = unique_world("silent-sensor");
    // Synchronous mode and nobody ticks: no capture will ever come.
    let _server = server(&world, &["--sync", "--delta-seconds", "0.02"]);
    let spawned = client(&world, &["sensor", "spawn", "imu", "--json"]);
    spawned.assert_success();
    let id = spawned.json()[0]["id"].as_u64().unwrap().to_string();
    let out = client(&world, &["--timeout", "1", "sensor", "watch", &id]);
    assert_eq!(out.status.code(), Some(1), "{}", out.stderr);
    assert!(
        out.stderr.contains(&format!(
            "no capture from sensor {id} of world '{world}' within 1s"
        )),
        "{}",
        out.stderr
    );
    let dir = std::env::temp_dir().join(format!("simbus-save-{}", std::process::id()));
    let out = client(
        &world,
        &[
            "--timeout",
            "1",
            "sensor",
            "save",
            &id,
            "--out",
            dir.to_str().unwrap(),
        ],
    );
    assert_eq!(out.status.code(), Some(1), "{}", out.stderr);
    assert!(
        out.stderr.contains("no capture from sensor"),
        "{}",
        out.stderr
    );
    let _ = std::fs::remove_dir_all(&dir);

    // A period longer than the run: the same clear timeout, and a readable
    // period in the list.
    let slow = client(&world, &["sensor", "spawn", "imu", "--sensor-tick", "1e9"]);
    slow.assert_success();
    let list = client(&world, &["sensor", "list"]);
    assert!(
        list.stdout.iter().any(|l| l.contains("every 1e9 s")),
        "{:?}",
        list.stdout
    );
}

#[test]
fn sensor_save_names_the_path_it_could_not_write() {
    let world = TestWorld::start("save-path", &["--delta-seconds", "0.01", "--realtime"]);
    let spawned = client(&world, &["sensor", "spawn", "imu", "--json"]);
    spawned.assert_success();
    let id = spawned.json()[0]["id"].as_u64().unwrap().to_string();
    // A regular file where the directory should be.
    let file = std::env::temp_dir().join(format!("simbus-not-a-dir-{}", std::process::id()));
    std::fs::write(&file, b"x").unwrap();
    let out = client(
        &world,
        &["sensor", "save", &id, "--out", file.to_str().unwrap()],
    );
    let _ = std::fs::remove_file(&file);
    assert_eq!(out.status.code(), Some(1), "{}", out.stderr);
    assert!(
        out.stderr.contains(file.to_str().unwrap()),
        "{}",
        out.stderr
    );
}
