//! The blueprints' tests.
use super::library::definitions;
use super::*;
use shared_types::LidarNoise;

fn description(id: &str, attributes: &[(&str, &str)]) -> Value {
    Value::Array(vec![
        Value::from(0u32),
        Value::from(id),
        Value::Array(
            attributes
                .iter()
                .map(|(k, v)| {
                    Value::Array(vec![Value::from(*k), Value::from(3u8), Value::from(*v)])
                })
                .collect(),
        ),
    ])
}

#[test]
fn every_blueprint_spawns_with_its_defaults() {
    for bp in LIBRARY {
        let d = Description::parse(&description(bp.id, &[])).expect(bp.id);
        d.spawn(&CarlaTransform::default()).expect(bp.id);
    }
}

#[test]
fn every_catalog_vehicle_has_carlas_attributes_and_spawns_at_its_size() {
    let ids: std::collections::HashSet<&str> =
        definitions().iter().map(|d| d.id.as_str()).collect();
    assert_eq!(ids.len(), definitions().len(), "ids are unique");
    for v in catalog::VEHICLES {
        let d = definition(v.id).expect(v.id);
        for name in [
            "base_type",
            "number_of_wheels",
            "generation",
            "object_type",
            "special_type",
            "has_dynamic_doors",
            "has_lights",
            "role_name",
            "sticky_control",
            "terramechanics",
        ] {
            assert!(d.attributes.iter().any(|a| a.id == name), "{} {name}", v.id);
        }
        let parsed = Description::parse(&description(v.id, &[])).unwrap();
        let Spawn::Body(command) = parsed.spawn(&CarlaTransform::default()).unwrap() else {
            panic!("{} is not a body", v.id);
        };
        let spec = shared_types::VehicleSpec::from_params(command.params).expect(v.id);
        assert_eq!(spec.half_extents, convert::vector(v.extent), "{}", v.id);
        assert_eq!(spec.mass, v.mass);
        // Lifted so it stands on the ground below the location.
        assert_eq!(command.vector[1], spec.half_extents[1]);
    }
}

#[test]
fn walkers_spawn_with_their_size_and_the_controller_as_one_on_its_walker() {
    for (id, half_height) in [
        ("walker.pedestrian.0001", 0.9375),
        ("walker.pedestrian.0010", 0.6),
        ("walker.pedestrian.0051", 0.9375),
    ] {
        let d = Description::parse(&description(id, &[])).expect(id);
        let Spawn::Body(command) = d.spawn(&CarlaTransform::default()).unwrap() else {
            panic!("{id} spawns no body");
        };
        assert_eq!(
            command.kind,
            shared_types::CommandKind::SpawnWalker as u32,
            "{id}"
        );
        assert_eq!(command.params[..2], [0.1875, half_height], "{id}");
    }
    let controller = Description::parse(&description("controller.ai.walker", &[])).unwrap();
    assert_eq!(
        controller.spawn(&CarlaTransform::default()).unwrap(),
        Spawn::Controller
    );
    for id in [
        "walker.pedestrian.0000",
        "walker.pedestrian.0052",
        "walker.pedestrian.1",
    ] {
        let d = Description::parse(&description(id, &[]));
        assert!(
            d.is_err() || d.unwrap().spawn(&CarlaTransform::default()).is_err(),
            "{id}"
        );
    }
    let generation = |id: &str| {
        let d = definition(id).unwrap();
        d.attributes
            .iter()
            .find(|a| a.id == "generation")
            .unwrap()
            .value
            .clone()
    };
    assert_eq!(generation("walker.pedestrian.0030"), "2");
}

#[test]
fn scene_actors_report_an_empty_role_name_and_fixed_attributes() {
    let d = scene_description(5, "vehicle.simbus.car");
    let attributes = d.as_array().unwrap()[2].as_array().unwrap().clone();
    let get = |name: &str| {
        attributes
            .iter()
            .find(|a| a.as_array().unwrap()[0].as_str() == Some(name))
            .map(|a| a.as_array().unwrap()[2].as_str().unwrap().to_string())
    };
    assert_eq!(get("role_name").as_deref(), Some(""));
    assert_eq!(get("number_of_wheels").as_deref(), Some("4"));
    let ground = scene_description(1, "static.prop.fixed");
    assert_eq!(ground.as_array().unwrap()[2].as_array().unwrap().len(), 1);
}

#[test]
fn a_lidar_takes_carlas_noise_and_drop_off_with_carlas_defaults() {
    let lidar = |attributes: &[(&str, &str)]| {
        let spawned = Description::parse(&description("sensor.lidar.ray_cast", attributes))
            .unwrap()
            .spawn(&CarlaTransform::default());
        spawned.map(|spawn| match spawn {
            Spawn::Sensor(spec) => spec.lidar_params().expect("a lidar").noise,
            _ => panic!("not a sensor"),
        })
    };
    // CARLA 0.9.16's defaults.
    let defaults = LidarNoise {
        noise_stddev: 0.0,
        dropoff_general_rate: 0.45,
        dropoff_intensity_limit: 0.8,
        dropoff_zero_intensity: 0.4,
        atmosphere_attenuation_rate: 0.004,
        seed: 0,
    };
    assert_eq!(lidar(&[]).unwrap(), defaults);
    // CARLA's "no drop-off" recipe: nothing dropped.
    let recipe = lidar(&[
        ("dropoff_general_rate", "0.0"),
        ("dropoff_intensity_limit", "1.0"),
        ("dropoff_zero_intensity", "0.0"),
        ("noise_stddev", "0.1"),
        ("noise_seed", "249013"),
    ])
    .unwrap();
    assert!(recipe.dropoff_general_rate == 0.0 && recipe.dropoff_zero_intensity == 0.0);
    assert_eq!((recipe.noise_stddev, recipe.seed), (0.1, 249013));
    for bad in [
        ("dropoff_general_rate", "1.5"),
        ("noise_stddev", "-1"),
        ("atmosphere_attenuation_rate", "-0.1"),
        ("noise_seed", "0.5"),
    ] {
        let e = lidar(&[bad]).unwrap_err().to_string();
        assert!(e.contains("dropoff_general_rate"), "{bad:?}: {e}");
    }
    // The semantic lidar has none of them.
    let d = Description::parse(&description("sensor.lidar.ray_cast_semantic", &[])).unwrap();
    let Spawn::Sensor(spec) = d.spawn(&CarlaTransform::default()).unwrap() else {
        panic!("not a sensor");
    };
    assert_eq!(spec.lidar_params().unwrap().noise, LidarNoise::default());
}

#[test]
fn a_lidar_gets_carlas_points_per_turn_and_spin() {
    let d = Description::parse(&description(
        "sensor.lidar.ray_cast",
        &[
            ("channels", "16"),
            ("points_per_second", "160000"),
            ("rotation_frequency", "20"),
        ],
    ))
    .unwrap();
    let Spawn::Sensor(spec) = d.spawn(&CarlaTransform::default()).unwrap() else {
        panic!("not a sensor");
    };
    let lidar = spec.lidar_params().expect("a lidar");
    assert_eq!(lidar.channels, 16);
    assert_eq!(lidar.points, 500);
    assert_eq!(lidar.rotation_hz, 20.0);
}

#[test]
fn unknown_blueprints_bad_numbers_and_noise_are_refused_by_name() {
    let e = Description::parse(&description("vehicle.tesla.roadster", &[]))
        .unwrap_err()
        .to_string();
    assert!(
        e.contains("vehicle.tesla.roadster") && e.contains("static.prop.box"),
        "{e}"
    );
    let d = Description::parse(&description("static.prop.sphere", &[("radius", "big")])).unwrap();
    let e = d.spawn(&CarlaTransform::default()).unwrap_err().to_string();
    assert!(e.contains("radius"), "{e}");
    let d = Description::parse(&description(
        "sensor.other.imu",
        &[("noise_accel_stddev_x", "0.1")],
    ))
    .unwrap();
    let e = d.spawn(&CarlaTransform::default()).unwrap_err().to_string();
    assert!(e.contains("noise_accel_stddev_x"), "{e}");
    let d = Description::parse(&description(
        "sensor.camera.depth",
        &[("image_size_x", "100000")],
    ))
    .unwrap();
    assert!(d.spawn(&CarlaTransform::default()).is_err());
}
