//! The event sensors: a collision sensor reports one event per contact its
//! parent starts, naming the other actor, on the frame it starts, and
//! nothing while the contact rests; an obstacle detector reports the actor
//! ahead and its distance, and publishes nothing on frames with nothing
//! ahead.

use std::time::Duration;

use shared_types::{Collision, Command, Obstacle, SensorSpec};
use sim_client::{Client, Ticker};
use simbus_tests::TestWorld;

const T: Duration = Duration::from_secs(20);

fn world(tag: &str) -> (TestWorld, Client, Ticker) {
    simbus_tests::sync_world(tag, &["--scene", "flat", "--max-sensor-readers", "4"])
}

fn spawn(client: &Client, command: Command) -> u64 {
    client.apply_batch_sync(&[command], false).unwrap().results[0].actor
}

#[test]
fn a_falling_box_reports_landing_once_and_resting_never() {
    let (_server, mut client, mut ticker) = world("collision-box");
    // The flat scene's first actor is its ground.
    let ground = client.wait_for_tick(T).unwrap().actors[0].id;
    let box_id = spawn(
        &client,
        Command::spawn_box([0.0, 1.0, 0.0], [0.5, 0.5, 0.5]),
    );
    let mut sensor = client
        .spawn_sensor(SensorSpec::with_params([0.0; 3], Collision).attached_to(box_id))
        .unwrap();
    let mut events = Vec::new();
    for _ in 0..150 {
        let frame = ticker.tick(T).unwrap();
        while let Some(capture) = sensor.try_recv().unwrap() {
            assert_eq!(capture.header().frame, frame, "published with its frame");
            assert!(capture.header().count > 0, "only frames with events");
            events.extend(capture.collisions().unwrap().iter().map(|e| (frame, *e)));
        }
    }
    // Dropped from 0.5 m: it lands once (a bounce would start a second
    // contact; a box this size does not bounce), then rests.
    assert_eq!(events.len(), 1, "{events:?}");
    let (frame, landing) = events[0];
    assert_eq!(landing.other_actor, ground);
    assert!(frame < 100, "landed at frame {frame}");
    // The ground pushed the box up.
    let [x, y, z] = landing.normal_impulse;
    assert!(y > 0.1 && x.abs() < y && z.abs() < y, "{:?}", landing);
}

#[test]
fn a_vehicle_driven_into_a_box_reports_one_contact_naming_it() {
    let (_server, client, mut ticker) = world("collision-car");
    let car = spawn(&client, Command::spawn_vehicle([0.0, 1.0, 0.0]));
    // A tall, deep box 8 m ahead of the car, resting on the ground: too
    // deep for a car braking at 8 m/s² after the hit to tip it over onto
    // itself.
    let wall = spawn(
        &client,
        Command::spawn_box([9.0, 1.5, 0.0], [1.5, 1.5, 2.0]),
    );
    let mut sensor = client
        .spawn_sensor(SensorSpec::with_params([0.0; 3], Collision).attached_to(car))
        .unwrap();
    // Let both settle before driving.
    for _ in 0..50 {
        ticker.tick(T).unwrap();
    }
    while sensor.try_recv().unwrap().is_some() {}
    client
        .apply_batch_sync(
            &[Command::vehicle_control(car, 1.0, 0.0, 0.0, false)],
            false,
        )
        .unwrap();
    let mut hits = Vec::new();
    let mut braking = false;
    for _ in 0..400 {
        let frame = ticker.tick(T).unwrap();
        while let Some(capture) = sensor.try_recv().unwrap() {
            assert_eq!(capture.header().frame, frame, "published with its frame");
            let events = capture.collisions().unwrap();
            assert!(!events.is_empty(), "published only with events");
            // (Braking hard, the chassis may touch the ground: contacts
            // with it are the ground's, not the wall's.)
            hits.extend(
                events
                    .iter()
                    .filter(|e| e.other_actor == wall)
                    .map(|e| (frame, *e)),
            );
        }
        // Hit: off the throttle, brakes on; the car stops against the box
        // or just short of it, and nothing more starts.
        if !hits.is_empty() && !braking {
            let brake = Command::vehicle_control(car, 0.0, 0.0, 1.0, false);
            client.apply_batch_sync(&[brake], false).unwrap();
            braking = true;
        }
    }
    assert_eq!(hits.len(), 1, "one contact start with the wall: {hits:?}");
    let (frame, hit) = hits[0];
    // About 7 m of travel from rest under full throttle.
    assert!(frame > 60 && frame < 250, "hit at frame {frame}");
    // The box pushed back: against the car's travel (+X).
    assert!(hit.normal_impulse[0] < 0.0, "{hit:?}");
}

#[test]
fn an_obstacle_ahead_is_reported_at_its_distance_and_nothing_when_clear() {
    let (_server, client, mut ticker) = world("obstacle");
    let box_id = spawn(
        &client,
        Command::spawn_box([40.0, 5.0, 0.0], [1.0, 1.0, 1.0]),
    );
    client
        .apply_batch_sync(&[Command::set_gravity(box_id, false)], false)
        .unwrap();
    let detector = Obstacle {
        distance: 20.0,
        hit_radius: 0.05,
        only_dynamics: true,
    };
    let mut sensor = client
        .spawn_sensor(SensorSpec::with_params([0.0, 5.0, 0.0], detector))
        .unwrap();
    // 39 m away: out of its 20 m.
    let clear = ticker.tick(T).unwrap();
    // Its near face 8 m ahead.
    client
        .apply_batch_sync(
            &[Command::set_transform(box_id, [9.0, 5.0, 0.0], [0.0; 4])],
            false,
        )
        .unwrap();
    let seen = ticker.tick(T).unwrap();
    let capture = sensor.recv(T).unwrap();
    assert_eq!(capture.header().frame, seen, "nothing published at {clear}");
    assert_eq!(capture.header().sequence, 1);
    let detection = capture.obstacle().unwrap();
    assert_eq!(detection.other_actor, box_id);
    assert!(
        (detection.distance - 8.0).abs() < 0.1,
        "{}",
        detection.distance
    );
}
