//! The sensor wire types' rules: what a spec may be, and the kinds' names.

use super::*;
use crate::sensor_check::SensorSpecError;

#[test]
fn specs_are_checked() {
    assert!(SensorSpec::depth([0.0; 3], 640, 480, 90.0, 100.0)
        .check()
        .is_ok());
    assert!(SensorSpec::depth([0.0; 3], 0, 480, 90.0, 100.0)
        .check()
        .is_err());
    assert!(SensorSpec::depth([0.0; 3], 64, 48, 180.0, 100.0)
        .check()
        .is_err());
    assert!(SensorSpec::lidar([0.0; 3], 64, 1024, 50.0, 10.0, -30.0)
        .check()
        .is_ok());
    assert!(SensorSpec::lidar([0.0; 3], 64, 1024, 50.0, -30.0, 10.0)
        .check()
        .is_err());
    assert!(SensorSpec::imu([f32::NAN, 0.0, 0.0]).check().is_err());
    assert!(SensorSpec::imu([0.0; 3]).every(-1.0).check().is_err());
    // Issue #24: sensors are kept within the world's reach, as actors are.
    assert_eq!(
        SensorSpec::imu([1e9, 0.0, 0.0]).check(),
        Err(SensorSpecError::Position)
    );
    assert!(SensorSpec::imu([0.0, -100_000.0, 100_000.0])
        .check()
        .is_ok());
    assert_eq!(SensorSpec::depth([0.0; 3], 4, 3, 60.0, 10.0).elements(), 12);
    // 2048 x 1024 x 4 B = 8 MiB is fine; 8192 x 8192 x 4 B = 256 MiB is not.
    assert!(SensorSpec::depth([0.0; 3], 2048, 1024, 90.0, 10.0)
        .check()
        .is_ok());
    assert!(SensorSpec::depth([0.0; 3], 8192, 8192, 90.0, 10.0)
        .check()
        .is_err());
    assert!(SensorSpec::lidar([0.0; 3], 256, 65536, 50.0, 10.0, -30.0)
        .check()
        .is_err());
    // One limit, stated where it is broken.
    let too_big = SensorSpec::depth([0.0; 3], 8192, 8192, 90.0, 10.0).check();
    assert!(too_big.unwrap_err().to_string().contains("8388608 pixels"));
    let forever = SensorSpec::imu([0.0; 3]).every(1e300).check();
    assert!(forever.unwrap_err().to_string().contains("18446744073"));
}

#[test]
fn the_check_and_the_flags_share_one_set_of_size_limits() {
    // Each side / count at its limit passes (with the other kept small
    // enough for the capture's byte cap), one past it does not: the
    // same constants bound `sim-client sensor --size/--channels/--points`.
    let depth = |w, h| SensorSpec::depth([0.0; 3], w, h, 90.0, 10.0).check();
    assert_eq!(depth(MAX_IMAGE_SIDE, 1), Ok(()));
    assert_eq!(depth(1, MAX_IMAGE_SIDE), Ok(()));
    assert_eq!(
        depth(MAX_IMAGE_SIDE + 1, 1),
        Err(SensorSpecError::CameraSize)
    );
    assert_eq!(
        depth(1, MAX_IMAGE_SIDE + 1),
        Err(SensorSpecError::CameraSize)
    );
    let lidar = |c, p| SensorSpec::lidar([0.0; 3], c, p, 50.0, 10.0, -30.0).check();
    assert_eq!(lidar(MAX_LIDAR_CHANNELS, 1), Ok(()));
    assert_eq!(lidar(1, MAX_LIDAR_POINTS), Ok(()));
    assert_eq!(
        lidar(MAX_LIDAR_CHANNELS + 1, 1),
        Err(SensorSpecError::LidarSize)
    );
    assert_eq!(
        lidar(1, MAX_LIDAR_POINTS + 1),
        Err(SensorSpecError::LidarSize)
    );
    let message = SensorSpecError::LidarSize.to_string();
    assert!(
        message.contains("1..=256 and points per channel in 1..=65536"),
        "{message}"
    );
}

#[test]
fn kinds_round_trip_through_their_names() {
    for k in SensorKind::ALL {
        assert_eq!(SensorKind::from_name(k.name()), Some(k));
    }
    assert_eq!(SensorKind::from_name("camera"), None);
}

#[test]
fn every_camera_kind_is_checked_as_the_depth_camera_is() {
    use crate::sensor_check::SensorSpecError as E;
    for kind in [SensorKind::Rgb, SensorKind::Semantic, SensorKind::Instance] {
        assert!(kind.is_camera());
        let camera =
            |size, fov, far| SensorSpec::camera_of(kind, [0.0; 3], size, fov, far).unwrap();
        assert_eq!(camera((800, 600), 90.0, 1000.0).check(), Ok(()));
        assert_eq!(
            camera((800, 600), 90.0, 1000.0).payload_bytes(),
            800 * 600 * 4
        );
        assert_eq!(camera((0, 600), 90.0, 1.0).check(), Err(E::CameraSize));
        assert_eq!(camera((8192, 8192), 90.0, 1.0).check(), Err(E::CameraSize));
        assert_eq!(camera((8, 6), f32::NAN, 1.0).check(), Err(E::NotFinite));
        assert_eq!(
            camera((8, 6), 180.0, 1.0).check(),
            Err(E::CameraFieldOfView)
        );
        assert_eq!(camera((8, 6), 90.0, -1.0).check(), Err(E::CameraRange));
    }
    assert!(!SensorKind::Lidar.is_camera());
    assert_eq!(
        SensorSpec::camera_of(SensorKind::Imu, [0.0; 3], (8, 6), 90.0, 1.0),
        None
    );
}

#[test]
fn a_semantic_lidar_is_a_lidar_that_stays_semantic() {
    let lidar = SensorSpec::lidar([0.0; 3], 16, 500, 40.0, 10.0, -30.0)
        .lidar_params()
        .expect("a lidar");
    let spec = SensorSpec::semantic_lidar([0.0; 3], lidar).rotating(10.0);
    assert_eq!(spec.sensor_kind(), Some(SensorKind::SemanticLidar));
    assert_eq!(spec.lidar_params().map(|l| l.rotation_hz), Some(10.0));
    assert_eq!(spec.elements(), 16 * 500);
    assert_eq!(spec.payload_bytes(), 16 * 500 * 24);
    assert!(spec.check().is_ok());
    let upside_down = SensorSpec::semantic_lidar(
        [0.0; 3],
        crate::sensor_params::Lidar {
            upper_fov: -30.0,
            lower_fov: 10.0,
            ..lidar
        },
    );
    assert_eq!(upside_down.check(), Err(SensorSpecError::LidarRange));
    assert!(SensorKind::SemanticLidar.is_lidar() && !SensorKind::Radar.is_lidar());
    assert_eq!(
        SensorKind::from_name("semantic-lidar"),
        Some(SensorKind::SemanticLidar)
    );
}

#[test]
fn radars_are_checked_as_sent() {
    let radar = crate::ranging::Radar::default();
    let spec = SensorSpec::with_params([0.0; 3], radar);
    assert_eq!(spec.params[..4], [30.0, 30.0, 100.0, 1500.0]);
    assert_eq!(spec.radar_params(), Some(radar));
    assert_eq!(spec.elements(), 1500);
    assert_eq!(spec.payload_bytes(), 1500 * 16);
    assert!(spec.check().is_ok());
    for (slot, value) in [
        (0, f32::NAN),
        (1, 180.0),
        (2, 0.0),
        (3, 0.5),
        (3, 2e6),
        (4, -1.0),
    ] {
        let mut bad = spec;
        bad.params[slot] = value;
        assert!(bad.check().is_err(), "params[{slot}] = {value}");
    }
    let mut bad = spec;
    bad.params[1] = 200.0;
    let message = bad.check().unwrap_err().to_string();
    assert!(message.contains("radar's fields of view"), "{message}");
}

#[test]
fn kinds_are_listed_as_a_sentence_lists_them() {
    use SensorKind::{Depth, Radar, Rgb, Semantic};
    assert_eq!(SensorKind::listed(&[]), "");
    assert_eq!(SensorKind::listed(&[Depth]), "depth");
    assert_eq!(SensorKind::listed(&[Depth, Radar]), "depth or radar");
    assert_eq!(
        SensorKind::listed(&[Depth, Rgb, Semantic]),
        "depth, rgb or semantic"
    );
}
