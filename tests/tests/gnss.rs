//! The GNSS receiver: a receiver on a box moved 100 m reads the latitude
//! the map's projection gives for each place, frame by frame; its noise
//! repeats with its seed; bad noise values are refused before anything is
//! spawned.

use std::time::Duration;

use shared_types::gnss::geolocation;
use shared_types::{Command, Gnss, SensorSpec};

const T: Duration = Duration::from_secs(20);

#[test]
fn a_receiver_on_a_box_moved_100_m_reads_the_projections_latitude() {
    let (_server, client, mut ticker) =
        simbus_tests::sync_world("gnss-move", &["--scene", "empty"]);
    let spawned = client
        .apply_batch_sync(&[Command::spawn_box([0.0, 5.0, 0.0], [0.5; 3])], false)
        .unwrap();
    let id = spawned.results[0].actor;
    client
        .apply_batch_sync(&[Command::set_gravity(id, false)], false)
        .unwrap();
    let mut gnss = client
        .spawn_sensor(SensorSpec::gnss([0.0, 1.0, 0.0]).attached_to(id))
        .unwrap();
    let frame = ticker.tick(T).unwrap();
    let here = gnss.recv(T).unwrap();
    assert_eq!(here.header().frame, frame);
    let reading = *here.gnss().unwrap();
    assert_eq!((reading.latitude, reading.longitude), (0.0, 0.0));
    assert!((reading.altitude - 6.0).abs() < 1e-4, "{reading:?}");
    drop(here);

    // 100 m along +Z (CARLA's y) and 30 m along +X (CARLA's x).
    client
        .apply_batch_sync(
            &[Command::set_transform(
                id,
                [30.0, 5.0, 100.0],
                [0.0, 0.0, 0.0, 1.0],
            )],
            false,
        )
        .unwrap();
    let frame = ticker.tick(T).unwrap();
    let there = gnss.recv(T).unwrap();
    assert_eq!(there.header().frame, frame);
    let reading = *there.gnss().unwrap();
    let expected = geolocation([30.0, 6.0, 100.0]);
    assert!(
        (reading.latitude - expected.latitude).abs() < 1e-9,
        "{reading:?} vs {expected:?}"
    );
    assert!(
        (reading.longitude - expected.longitude).abs() < 1e-9,
        "{reading:?} vs {expected:?}"
    );
    // Near the origin a degree is 0.9996 x 6 378 137 m x pi / 180 either way.
    assert!(
        (reading.latitude - 100.0 / 111_274.955).abs() < 1e-7,
        "{reading:?}"
    );
    assert!(
        (reading.longitude - 30.0 / 111_274.955).abs() < 1e-7,
        "{reading:?}"
    );
}

#[test]
fn the_same_seed_gives_the_same_errors_another_seed_others() {
    let (_server, client, mut ticker) =
        simbus_tests::sync_world("gnss-noise", &["--scene", "empty"]);
    let noisy = |seed| {
        let params = Gnss {
            lat_stddev: 1e-5,
            lon_stddev: 1e-5,
            alt_stddev: 0.5,
            alt_bias: 10.0,
            seed,
            ..Gnss::default()
        };
        client
            .spawn_sensor(SensorSpec::with_params([0.0, 2.0, 0.0], params))
            .unwrap()
    };
    let mut sensors = [noisy(7), noisy(7), noisy(8)];
    let mut readings = [Vec::new(), Vec::new(), Vec::new()];
    for _ in 0..20 {
        let frame = ticker.tick(T).unwrap();
        for (sensor, got) in sensors.iter_mut().zip(&mut readings) {
            let capture = sensor.recv(T).unwrap();
            assert_eq!(capture.header().frame, frame);
            got.push(*capture.gnss().unwrap());
        }
    }
    assert_eq!(readings[0], readings[1], "the same seed, the same errors");
    assert_ne!(readings[0], readings[2], "another seed, other errors");
    let altitudes: Vec<f64> = readings[0].iter().map(|r| r.altitude).collect();
    let mean = altitudes.iter().sum::<f64>() / altitudes.len() as f64;
    assert!(
        (mean - 12.0).abs() < 0.5,
        "biased by 10 m above 2 m: {altitudes:?}"
    );
    assert!(altitudes.windows(2).any(|w| w[0] != w[1]), "noisy");
}

#[test]
fn bad_noise_is_refused_before_anything_is_spawned() {
    let world = simbus_tests::TestWorld::start("gnss-bad", &[]);
    let client = world.connect();
    let negative = Gnss {
        alt_stddev: -1.0,
        ..Gnss::default()
    };
    let error = client
        .spawn_sensor(SensorSpec::with_params([0.0; 3], negative))
        .expect_err("a negative deviation is refused");
    assert!(
        error.to_string().contains("GNSS biases must be finite"),
        "{error}"
    );
    let out = world.cli(&["sensor", "spawn", "gnss", "--noise-stddev", "0,-1,0"]);
    out.assert_code(2);
    assert!(
        out.stderr
            .contains("--noise-stddev takes standard deviations >= 0"),
        "{out}"
    );
    let out = world.cli(&["sensor", "spawn", "depth", "--noise-seed", "3"]);
    out.assert_code(2);
    assert!(
        out.stderr
            .contains("--noise-seed applies to gnss, lidar or radar sensors"),
        "{out}"
    );
    assert!(client.list_sensors().unwrap().is_empty(), "nothing spawned");
}
