//! The `sensor` commands say what they mean: `sensor save --range` that is
//! not a positive number of metres is refused (exit 2) before anything is
//! waited for; an IMU is watched with its readings and saved as JSON (not
//! Rust debug output); an unknown sensor is named by its id; counts read
//! `1 value`, `1 capture`.

use std::time::Duration;

use shared_types::SensorSpec;
use simbus_tests::{unique_world, Scratch, TestWorld};

const T: Duration = Duration::from_secs(20);

#[test]
fn save_refuses_a_range_that_is_not_a_positive_number_before_asking_anyone() {
    // No server runs on this world: the flag is checked first, or the
    // command would fail to connect (exit 1) instead.
    let world = unique_world("save-range");
    let dir = Scratch::new("save-range");
    let out_dir = dir.path().to_str().expect("path");
    for range in ["0", "NaN", "-5", "inf"] {
        let out = simbus_tests::client(
            &world,
            &[
                "--timeout",
                "1",
                "sensor",
                "save",
                "1",
                "--out",
                out_dir,
                "--range",
                range,
            ],
        );
        out.assert_code(2);
        assert!(out.stderr.contains("--range"), "{out}");
        assert!(
            out.stderr
                .contains("must be a positive, finite number of metres"),
            "{out}"
        );
    }
}

/// A 3-vector of finite numbers in `json[key]`.
fn vector(json: &serde_json::Value, key: &str) -> [f64; 3] {
    let values: Vec<f64> = json[key]
        .as_array()
        .unwrap_or_else(|| panic!("{key} in {json}"))
        .iter()
        .map(|v| v.as_f64().expect("a number"))
        .collect();
    assert!(values.iter().all(|v| v.is_finite()), "{json}");
    values
        .try_into()
        .unwrap_or_else(|_| panic!("{key}: 3 numbers in {json}"))
}

/// Checks an IMU capture's JSON: the readings of an IMU at rest in the
/// world (it reads gravity, +9.81 m/s² up) and its compass.
fn assert_imu_readings(json: &serde_json::Value) {
    let [ax, ay, az] = vector(json, "accelerometer");
    assert!(
        (ay - 9.81).abs() < 0.05 && ax.abs() < 0.05 && az.abs() < 0.05,
        "{json}"
    );
    assert_eq!(vector(json, "gyroscope"), [0.0; 3], "{json}");
    let compass = json["compass"].as_f64().expect("compass");
    assert!((0.0..std::f64::consts::TAU).contains(&compass), "{json}");
}

#[test]
fn an_imu_is_watched_with_its_readings_and_saved_as_json() {
    let world = TestWorld::start("imu-cli", &["--scene", "empty"]);
    let spawned = world.cli(&["sensor", "spawn", "imu", "--json"]);
    spawned.assert_success();
    let id = spawned.json()[0]["id"].as_u64().expect("id").to_string();

    let watched = world.cli(&["sensor", "watch", &id, "--captures", "1", "--json"]);
    watched.assert_success();
    assert_imu_readings(&watched.json()[0]);

    let watched = world.cli(&["sensor", "watch", &id, "--captures", "1"]);
    watched.assert_success();
    let line = &watched.stdout[0];
    assert!(line.contains("  1 value  accelerometer ("), "{line}");
    assert!(line.contains(" m/s²  gyroscope ("), "{line}");
    assert!(line.contains(" rad/s  compass "), "{line}");

    let dir = Scratch::new("imu-save");
    let saved = world.cli(&[
        "sensor",
        "save",
        &id,
        "--captures",
        "2",
        "--out",
        dir.path().to_str().expect("path"),
    ]);
    saved.assert_success();
    assert_eq!(saved.stdout.len(), 2, "{saved}");
    for line in &saved.stdout {
        assert!(!line.contains("ImuMeasurement"), "no debug output: {saved}");
        let path = line
            .strip_prefix("wrote ")
            .and_then(|l| l.split_once(" (imu: accelerometer ("))
            .unwrap_or_else(|| panic!("{saved}"))
            .0;
        assert!(path.ends_with(".json"), "{path}");
        let json: serde_json::Value =
            serde_json::from_str(&std::fs::read_to_string(path).expect("the saved file"))
                .expect("JSON");
        assert_eq!(
            json["sensor"].as_u64().map(|s| s.to_string()),
            Some(id.clone())
        );
        assert_eq!(json["kind"], "imu");
        let frame = json["frame"].as_u64().expect("frame");
        assert!(
            path.ends_with(&format!("sensor{id}-frame{frame}.json")),
            "{path}"
        );
        assert_imu_readings(&json);
    }
}

#[test]
fn an_unknown_sensor_is_named_by_its_id() {
    let world = TestWorld::start("unknown-sensor", &["--scene", "empty"]);
    let dir = Scratch::new("unknown-sensor");
    let out_dir = dir.path().to_str().expect("path");
    for args in [
        &["sensor", "watch", "77", "--captures", "1"][..],
        &["sensor", "save", "77", "--out", out_dir][..],
        &["sensor", "destroy", "77"][..],
    ] {
        let out = world.cli(args);
        out.assert_code(2);
        assert!(
            out.stderr.contains(&format!(
                "unknown sensor 77 in world '{}' (never spawned, or it has ended)",
                world.name()
            )),
            "{args:?}: {out}"
        );
    }
}

#[test]
fn sensor_list_counts_one_capture_in_the_singular() {
    let (world, client, mut ticker) = simbus_tests::sync_world("list-one", &["--scene", "empty"]);
    let sensor = client
        .spawn_sensor(SensorSpec::imu([0.0, 1.0, 0.0]))
        .expect("an IMU");
    let frame = ticker.tick(T).expect("tick");
    let mut sensor = sensor;
    assert_eq!(sensor.recv(T).expect("its capture").header().frame, frame);
    let listed = world.cli(&["sensor", "list"]);
    listed.assert_success();
    let line = listed
        .stdout
        .iter()
        .find(|l| l.contains(&format!("sensor {:>3}  imu", sensor.id())))
        .unwrap_or_else(|| panic!("{listed}"));
    assert!(line.ends_with("every frame  1 capture"), "{line}");
    ticker.tick(T).expect("tick");
    sensor.recv(T).expect("its capture");
    let listed = world.cli(&["sensor", "list"]);
    assert!(
        listed
            .stdout
            .iter()
            .any(|l| l.ends_with("every frame  2 captures")),
        "{listed}"
    );
}

/// Issue 44, item 8: Ctrl-C on `sensor save` before its captures came is
/// an interruption (exit 130, saying how many were saved), not a success
/// that wrote nothing.
#[test]
fn an_interrupted_save_exits_130_saying_what_it_saved() {
    let world = TestWorld::start(
        "save-interrupted",
        &["--scene", "empty", "--sync", "--delta-seconds", "0.05"],
    );
    let spawned = world.cli(&["sensor", "spawn", "imu", "--json"]);
    spawned.assert_success();
    let id = spawned.json()[0]["id"].as_u64().expect("id").to_string();
    let dir = Scratch::new("save-interrupted");
    let out = dir.path().to_str().expect("path");
    // Nobody ticks: no capture comes.
    let save = world.spawn_cli(&["sensor", "save", &id, "--out", out, "--captures", "3"]);
    save.wait_stderr("waiting for captures", T);
    simbus_process::send_signal(save.pid(), libc::SIGINT).expect("SIGINT");
    let ended = save.finish(T);
    ended.assert_code(130);
    assert!(
        ended.stderr.contains(&format!(
            "interrupted: sensor save: 0 captures of 3 saved in {out}"
        )),
        "{ended}"
    );
}
