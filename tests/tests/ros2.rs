//! `sim-client ros2` read and driven by a DDS node of the test's own (the
//! adapter's message layouts, over RustDDS): `/tf` holds every moving actor
//! of a frame with its pose in ROS's axes, a vehicle takes CARLA's control
//! message, and bad input is refused with the reason (a domain out of
//! range, a namespace ROS cannot have, a second ticker naming the first).
//! A stock rclpy reads and drives the adapter in `tests/python/test_ros2.py`.

use std::time::{Duration, Instant};

use simbus_ros2::dds::{Dds, Qos};
use simbus_ros2::msg::{CarlaEgoVehicleControl, TfMessage, Time};
use simbus_tests::{sync_world, Proc};

/// A DDS domain of this test's own (215..=232: above Linux's ephemeral
/// ports; the Python tests take 1..=101).
fn domain(offset: u16) -> u16 {
    215 + (std::process::id() as u16 + offset) % 18
}

/// `sim-client ros2 --json` on `world`, once it says it is ready.
fn adapter(world: &str, domain: u16, args: &[&str]) -> Proc {
    let domain = domain.to_string();
    let mut all = vec![
        "--world",
        world,
        "ros2",
        "--json",
        "--domain-id",
        domain.as_str(),
    ];
    all.extend_from_slice(args);
    let proc = Proc::spawn("sim-client", &all);
    proc.wait_line("\"ready\"", Duration::from_secs(30));
    proc
}

#[test]
fn tf_holds_every_moving_actor_in_ros_axes_and_carla_control_drives_a_vehicle() {
    let (world, mut client, mut ticker) = sync_world("ros2-tf", &[]);
    let car = client
        .spawn_actor(shared_types::Command::spawn_vehicle([0.0, 0.6, 20.0]))
        .expect("a vehicle");
    // The spawn shows from the next frame on (the adapter drives vehicles
    // the world has).
    ticker.tick(Duration::from_secs(10)).expect("a tick");
    let domain = domain(0);
    let _adapter = adapter(&world, domain, &["--vehicles", &car.to_string()]);
    let mut dds = Dds::join(domain, "simbus_test", false).expect("a DDS node");
    let tf = dds.subscription::<TfMessage>("/tf").expect("/tf");
    let control = dds
        .publisher::<CarlaEgoVehicleControl>(
            &format!("/simbus/vehicle_{car}/vehicle_control_cmd"),
            Qos::Command,
        )
        .expect("the control topic");
    // Full throttle in CARLA's message, until the vehicle moves (the
    // adapter's reader and this writer match in their own time).
    let deadline = Instant::now() + Duration::from_secs(30);
    let (frame, states) = loop {
        control
            .publish(CarlaEgoVehicleControl {
                throttle: 1.0,
                ..CarlaEgoVehicleControl::default()
            })
            .expect("published");
        let id = ticker.tick(Duration::from_secs(10)).expect("a tick");
        let frame = loop {
            let frame = client
                .wait_for_frame(Duration::from_secs(10))
                .expect("its frame");
            if frame.frame() >= id {
                break frame;
            }
        };
        assert_eq!(frame.frame(), id);
        let states = frame.actors().to_vec();
        let moving = states
            .iter()
            .find(|a| a.id == car)
            // Along the ground (it lands first: that speed is not its own).
            .is_some_and(|a| a.linear_velocity[0].hypot(a.linear_velocity[2]) > 1.0);
        if moving {
            break (frame.timestamp().elapsed_ns, states);
        }
        assert!(Instant::now() < deadline, "the vehicle never moved");
        std::thread::sleep(Duration::from_millis(5));
    };
    // That frame's /tf.
    let deadline = Instant::now() + Duration::from_secs(20);
    let mut seen = Vec::new();
    let message = loop {
        if let Ok(Some((message, _))) = tf.take() {
            seen.push(message.transforms.first().map(|t| t.header.stamp));
            let stamp = message.transforms.first().map(|t| t.header.stamp);
            if stamp == Some(Time::from_ns(frame)) {
                break message;
            }
        } else {
            assert!(
                Instant::now() < deadline,
                "no /tf of frame time {frame} ns: {seen:?}"
            );
            std::thread::sleep(Duration::from_millis(2));
        }
    };
    let moving: Vec<_> = states
        .iter()
        .filter(|a| a.actor_kind() != Some(shared_types::ActorKind::Static))
        .collect();
    assert_eq!(message.transforms.len(), moving.len(), "{message:?}");
    for actor in moving {
        let kind = actor.actor_kind().expect("a known kind").name();
        let child = format!("{kind}_{}", actor.id);
        let t = message
            .transforms
            .iter()
            .find(|t| t.child_frame_id == child)
            .unwrap_or_else(|| panic!("{child} is not on /tf"));
        assert_eq!(t.header.frame_id, "map");
        let [x, y, z] = actor.position.map(f64::from);
        let p = t.transform.translation;
        assert_eq!((p.x, p.y, p.z), (x, -z, y), "{child}");
        let [qx, qy, qz, qw] = actor.rotation.map(f64::from);
        let q = t.transform.rotation;
        assert_eq!((q.x, q.y, q.z, q.w), (qx, -qz, qy, qw), "{child}");
    }
}

#[test]
fn bad_input_is_refused_with_the_reason_and_a_second_ticker_names_the_first() {
    let world = simbus_tests::TestWorld::start("ros2-bad", &[]);
    let out_of_range = world.cli(&["ros2", "--domain-id", "233"]);
    out_of_range.assert_code(2);
    assert!(out_of_range.stderr.contains("233"), "{out_of_range}");
    let namespace = world.cli(&["ros2", "--namespace", "9lives"]);
    namespace.assert_code(2);
    assert!(
        namespace.stderr.contains("not a ROS namespace"),
        "{namespace}"
    );

    let unknown = world.cli(&["ros2", "--domain-id", "231", "--vehicles", "999"]);
    unknown.assert_code(1);
    assert!(
        unknown.stderr.contains("vehicle 999 is not in world"),
        "{unknown}"
    );

    let domain = domain(7);
    let _first = adapter(&world, domain, &["--tick-from-ros"]);
    let second = world.cli(&[
        "ros2",
        "--domain-id",
        &domain.to_string(),
        "--tick-from-ros",
    ]);
    second.assert_code(1);
    let owner = format!("ros2-simbus_{}", world.name().replace('-', "_"));
    assert!(second.stderr.contains(&owner), "{second}");

    simbus_tests::assert_fails_without_server(
        &simbus_tests::unique_world("ros2-none"),
        &["ros2", "--domain-id", &domain.to_string()],
    );
}
