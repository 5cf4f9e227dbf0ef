//! The semantic lidar and the radar: a semantic lidar's points on a box
//! carry the box's actor id and CARLA's tag for it, frame-exact; a radar
//! sees a box driven towards it at 5 m/s closing at -5 m/s (CARLA's sign),
//! each detection where a ray meets it, and casts `points_per_second × dt`
//! rays a frame; hostile parameters are refused and spawn nothing.

use std::time::Duration;

use shared_types::{Command, Lidar, LidarNoise, Radar, SemanticTag, SensorSpec, SensorSpecError};
use sim_client::{Client, SensorError, Ticker};
use simbus_tests::TestWorld;

const T: Duration = Duration::from_secs(20);

fn world(tag: &str) -> (TestWorld, Client, Ticker) {
    // 0.05 s frames: a 1500-point radar casts 75 rays a frame.
    simbus_tests::sync_world_at(tag, "0.05", &["--scene", "flat"])
}

fn spawn(client: &Client, command: Command) -> u64 {
    client.apply_batch_sync(&[command], false).unwrap().results[0].actor
}

/// A box of half size 1 m floating with its centre at (`x`, 3, 0), gravity off.
fn floating_box(client: &Client, x: f32) -> u64 {
    let id = spawn(client, Command::spawn_box([x, 3.0, 0.0], [1.0, 1.0, 1.0]));
    client
        .apply_batch_sync(&[Command::set_gravity(id, false)], false)
        .unwrap();
    id
}

#[test]
fn semantic_lidar_points_on_a_box_name_the_box_and_its_tag() {
    let (_server, mut client, mut ticker) = world("semantic-lidar");
    let ground = client.wait_for_tick(T).unwrap().actors[0].id;
    let box_id = floating_box(&client, 10.0);
    let lidar = Lidar {
        channels: 16,
        points: 360,
        range: 40.0,
        upper_fov: 10.0,
        lower_fov: -30.0,
        rotation_hz: 0.0,
        noise: Default::default(),
    };
    let mut sensor = client
        .spawn_sensor(SensorSpec::semantic_lidar([0.0, 3.0, 0.0], lidar))
        .unwrap();
    let frame = ticker.tick(T).unwrap();
    let capture = sensor.recv(T).unwrap();
    assert_eq!(capture.header().frame, frame);
    let points = capture.semantic_points().expect("a semantic lidar capture");
    let on_box: Vec<_> = points
        .iter()
        .filter(|p| p.object_idx as u64 == box_id)
        .collect();
    let on_ground = points
        .iter()
        .filter(|p| p.object_idx as u64 == ground)
        .count();
    assert!(on_box.len() > 10, "{} points on the box", on_box.len());
    assert!(on_ground > 100, "{on_ground} points on the ground");
    for p in &on_box {
        assert_eq!(p.object_tag, SemanticTag::Dynamic as u32, "{p:?}");
        // The box's near face is 9 m ahead; every point is on the box.
        assert!(p.x >= 9.0 - 1e-3 && p.x <= 11.0 + 1e-3, "{p:?}");
        assert!(p.cos_inc_angle > 0.0 && p.cos_inc_angle <= 1.0, "{p:?}");
    }
    // Straight ahead the ray meets the near face head on.
    let head_on = on_box
        .iter()
        .filter(|p| p.z.abs() < 0.2 && p.y.abs() < 0.2)
        .map(|p| p.cos_inc_angle)
        .fold(0.0_f32, f32::max);
    assert!(head_on > 0.99, "{head_on}");
    // Nothing beyond the ground and the box.
    assert!(points
        .iter()
        .all(|p| p.object_idx as u64 == box_id || p.object_idx as u64 == ground));
}

#[test]
fn a_radar_sees_a_box_coming_at_five_metres_a_second_closing_at_minus_five() {
    let (_server, client, mut ticker) = world("radar");
    let box_id = floating_box(&client, 20.0);
    client
        .apply_batch_sync(
            &[Command::constant_velocity(box_id, Some([-5.0, 0.0, 0.0]))],
            false,
        )
        .unwrap();
    let radar = Radar {
        horizontal_fov: 20.0,
        vertical_fov: 10.0,
        // Short of the ground: every ray ends 2.6 m or less below the
        // sensor, 3 m up.
        range: 30.0,
        points_per_second: 1500,
        seed: 0,
    };
    let mut sensor = client
        .spawn_sensor(SensorSpec::with_params([0.0, 3.0, 0.0], radar))
        .unwrap();
    let mut seen = 0;
    for _ in 0..10 {
        let frame = ticker.tick(T).unwrap();
        let capture = sensor.recv(T).unwrap();
        assert_eq!(capture.header().frame, frame);
        let detections = capture.detections().expect("a radar capture");
        assert!(detections.len() <= 75, "{} of 75 rays", detections.len());
        for d in detections {
            assert!((d.velocity + 5.0).abs() < 0.1, "{d:?}");
            assert!(d.azimuth.abs() <= 10f32.to_radians() + 1e-4, "{d:?}");
            assert!(d.altitude.abs() <= 5f32.to_radians() + 1e-4, "{d:?}");
            // The near face is 19 m ahead at the start, closing 0.25 m a frame.
            let ahead = d.depth * d.altitude.cos() * d.azimuth.cos();
            assert!((14.0..=19.1).contains(&ahead), "{d:?}");
        }
        seen += detections.len();
    }
    // The box fills about half the field of view (rays gather at its
    // centre, as CARLA's do).
    assert!(seen > 300, "{seen} detections in 750 rays");
}

#[test]
fn the_same_radar_seed_casts_the_same_rays_in_a_new_world() {
    let run = |seed| {
        let (_server, client, mut ticker) = world("radar-seed");
        floating_box(&client, 15.0);
        let radar = Radar {
            seed,
            ..Radar::default()
        };
        let mut sensor = client
            .spawn_sensor(SensorSpec::with_params([0.0, 3.0, 0.0], radar))
            .unwrap();
        ticker.tick(T).unwrap();
        let capture = sensor.recv(T).unwrap();
        capture.bytes().to_vec()
    };
    let first = run(7);
    assert!(!first.is_empty());
    assert_eq!(first, run(7));
    assert_ne!(first, run(8));
}

#[test]
fn hostile_radar_and_lidar_parameters_are_refused_and_spawn_nothing() {
    let (_server, client, _ticker) = world("ranging-hostile");
    let radar = SensorSpec::with_params([0.0; 3], Radar::default());
    let lidar = SensorSpec::semantic_lidar(
        [0.0; 3],
        Lidar {
            channels: 8,
            points: 64,
            range: 10.0,
            upper_fov: 10.0,
            lower_fov: -10.0,
            rotation_hz: 0.0,
            noise: Default::default(),
        },
    );
    let mut cases = Vec::new();
    for (slot, value) in [
        (0, f32::NAN),
        (0, 0.0),
        (1, 180.0),
        (2, -5.0),
        (3, 0.0),
        (3, 1e9),
    ] {
        let mut spec = radar;
        spec.params[slot] = value;
        cases.push(spec);
    }
    // Sizes, range, field of view; noise (a semantic lidar has none), a
    // drop-off share above 1, a fractional seed.
    for (slot, value) in [
        (0, 0.0),
        (1, 1e9),
        (2, -1.0),
        (3, f32::INFINITY),
        (6, 0.1),
        (7, 1.5),
        (11, 0.5),
    ] {
        let mut spec = lidar;
        spec.params[slot] = value;
        cases.push(spec);
    }
    for spec in cases {
        match client.spawn_sensor(spec) {
            Err(SensorError::InvalidSpec(
                SensorSpecError::Radar
                | SensorSpecError::NotFinite
                | SensorSpecError::LidarSize
                | SensorSpecError::LidarRange
                | SensorSpecError::LidarNoise,
            )) => {}
            other => panic!("{:?}: {other:?}", spec.params),
        }
    }
    assert!(client.list_sensors().unwrap().is_empty());
}

/// One capture of a lidar with `noise` 3 m up in a flat world with a
/// box ahead: its points.
fn lidar_points(tag: &str, noise: LidarNoise) -> Vec<shared_types::LidarPoint> {
    let (_server, client, mut ticker) = world(tag);
    floating_box(&client, 10.0);
    let lidar = Lidar {
        channels: 16,
        points: 512,
        range: 40.0,
        upper_fov: 10.0,
        lower_fov: -30.0,
        rotation_hz: 0.0,
        noise,
    };
    let mut sensor = client
        .spawn_sensor(SensorSpec::with_params([0.0, 3.0, 0.0], lidar))
        .unwrap();
    ticker.tick(T).unwrap();
    let capture = sensor.recv(T).unwrap();
    capture.points().expect("a lidar capture").to_vec()
}

#[test]
fn a_lidar_drops_and_spreads_its_points_as_carla_the_same_way_for_the_same_seed() {
    let exact = lidar_points("lidar-exact", LidarNoise::default());
    // CARLA's defaults: 45 % dropped at random, then some of the faint
    // returns; intensity exp(-0.004 d).
    let carla = LidarNoise {
        dropoff_general_rate: 0.45,
        dropoff_intensity_limit: 0.8,
        dropoff_zero_intensity: 0.4,
        atmosphere_attenuation_rate: 0.004,
        seed: 11,
        ..LidarNoise::default()
    };
    let dropped = lidar_points("lidar-dropoff", carla);
    let share = dropped.len() as f32 / exact.len() as f32;
    assert!(
        (0.45..0.6).contains(&share),
        "{share}: {} of {}",
        dropped.len(),
        exact.len()
    );
    for p in &dropped {
        let d = (p.x * p.x + p.y * p.y + p.z * p.z).sqrt();
        assert!((p.intensity - (-0.004 * d).exp()).abs() < 1e-5, "{p:?}");
        // Every kept point is one the exact lidar has.
        assert!(exact.contains(p) || exact.iter().any(|e| e.x == p.x && e.y == p.y && e.z == p.z));
    }
    assert_eq!(dropped, lidar_points("lidar-dropoff-again", carla));
    let other_seed = LidarNoise { seed: 12, ..carla };
    assert_ne!(dropped, lidar_points("lidar-dropoff-other", other_seed));
    // A normal error along each ray: the same directions, other distances.
    let noisy = LidarNoise {
        noise_stddev: 0.1,
        seed: 5,
        ..LidarNoise::default()
    };
    let spread = lidar_points("lidar-noise", noisy);
    assert_eq!(spread.len(), exact.len());
    let errors: Vec<f32> = spread
        .iter()
        .zip(&exact)
        .map(|(n, e)| {
            let (dn, de) = (n.x.hypot(n.y).hypot(n.z), e.x.hypot(e.y).hypot(e.z));
            // Along the ray: the same direction.
            assert!((n.x / dn - e.x / de).abs() < 1e-4, "{n:?} {e:?}");
            dn - de
        })
        .collect();
    let deviation = (errors.iter().map(|e| e * e).sum::<f32>() / errors.len() as f32).sqrt();
    assert!((deviation - 0.1).abs() < 0.01, "{deviation}");
}
