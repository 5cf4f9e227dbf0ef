//! The client library against a real server: `wait_for_tick` blocking and
//! spinning, `on_tick` / `remove_on_tick`, every frame's packed poses, and a
//! clear error when the server dies while a client waits.

use std::sync::atomic::{AtomicU64, Ordering};
use std::sync::{Arc, Mutex};
use std::time::Duration;

use shared_types::{ActorPose, Command};
use sim_client::{Client, RequestError, Status, WaitError, WaitMode};
use simbus_tests::{server, unique_world, TestWorld};

#[test]
fn wait_for_tick_blocks_or_spins_and_returns_newer_frames() {
    let world = TestWorld::start("wait", &["--fixed-delta-seconds", "0.01", "--realtime"]);
    let mut client = Client::connect(&world, Duration::from_secs(10)).unwrap();
    for mode in [WaitMode::Block, WaitMode::Spin, WaitMode::Hybrid] {
        client.set_wait_mode(mode);
        let mut last = client.wait_for_tick(Duration::from_secs(5)).unwrap();
        for _ in 0..20 {
            let next = client.wait_for_tick(Duration::from_secs(5)).unwrap();
            assert_eq!(next.frame(), last.frame() + 1 + next.missed, "{mode:?}");
            assert_eq!(next.actors.len(), 17, "the default scene");
            last = next;
        }
    }
}

/// Every frame carries its actors' poses, packed after them in the same
/// sample: each one the pose of the actor at its index, for an odd and an
/// even number of actors, and for frames of a body in motion.
#[test]
fn every_frame_holds_each_actors_pose_packed_after_the_actors() {
    let world = TestWorld::start("poses", &["--fixed-delta-seconds", "0.01", "--realtime"]);
    let mut client = Client::connect(&world, Duration::from_secs(10)).unwrap();
    let check = |client: &mut Client, actors: usize| -> Vec<f32> {
        (0..20)
            .map(|_| {
                let view = client.wait_for_frame(Duration::from_secs(5)).unwrap();
                assert_eq!(view.actors().len(), actors);
                let expected: Vec<ActorPose> = view.actors().iter().map(ActorPose::from).collect();
                assert_eq!(view.poses(), expected.as_slice(), "frame {}", view.frame());
                assert!(view.payload_bytes().len() >= actors * (96 + 48));
                view.poses().last().map_or(0.0, |p| p.position[1])
            })
            .collect()
    };
    check(&mut client, 17);
    let spawned = client
        .spawn_actor(Command::spawn_box([3.0, 8.0, 3.0], [0.5; 3]))
        .unwrap();
    // Frames until the spawned box (the newest id: the last actor) is in one.
    while client
        .wait_for_frame(Duration::from_secs(5))
        .unwrap()
        .actors()
        .len()
        != 18
    {}
    let heights = check(&mut client, 18);
    assert!(
        heights.windows(2).all(|h| h[1] <= h[0]) && heights[19] < heights[0],
        "actor {spawned}'s poses fall frame by frame: {heights:?}"
    );
}

#[test]
fn on_tick_callbacks_see_every_frame_until_removed() {
    let world = TestWorld::start("on-tick", &["--fixed-delta-seconds", "0.01", "--realtime"]);
    let mut client = Client::connect(&world, Duration::from_secs(10)).unwrap();
    let frames = Arc::new(Mutex::new(Vec::new()));
    let calls = Arc::new(AtomicU64::new(0));
    let seen = frames.clone();
    let id = client
        .on_tick(move |s| seen.lock().unwrap().push(s.frame()))
        .unwrap();
    let counter = calls.clone();
    let other = client
        .on_tick(move |_| {
            counter.fetch_add(1, Ordering::Relaxed);
        })
        .unwrap();
    while frames.lock().unwrap().len() < 30 {
        client.wait_for_tick(Duration::from_secs(5)).unwrap();
    }
    assert!(client.remove_on_tick(id));
    assert!(!client.remove_on_tick(id), "removing twice says so");
    let count = frames.lock().unwrap().len();
    for _ in 0..10 {
        client.wait_for_tick(Duration::from_secs(5)).unwrap();
    }
    let frames = frames.lock().unwrap().clone();
    assert!(frames.len() <= count + 1, "no calls after removal");
    assert!(
        frames.windows(2).all(|w| w[1] > w[0]),
        "in order: {frames:?}"
    );
    assert!(
        calls.load(Ordering::Relaxed) >= 30,
        "the other callback still runs"
    );
    assert!(client.remove_on_tick(other));
}

#[test]
fn a_server_that_dies_ends_the_wait_with_a_clear_error() {
    let world = unique_world("dies");
    let mut server = server(&world, &["--fixed-delta-seconds", "0.01", "--realtime"]);
    let mut client = Client::connect(&world, Duration::from_secs(10)).unwrap();
    client.wait_for_tick(Duration::from_secs(5)).unwrap();
    server.guard.kill().unwrap();
    match client.wait_for_tick(Duration::from_secs(30)) {
        Err(WaitError::ServerGone { pid, .. }) => assert_eq!(pid, server.pid()),
        // Frames published just before the kill may still be queued.
        Ok(_) => assert!(matches!(
            (0..100).find_map(|_| client.wait_for_tick(Duration::from_secs(30)).err()),
            Some(WaitError::ServerGone { .. })
        )),
        Err(e) => panic!("expected ServerGone, got {e}"),
    }
    match client.status() {
        Err(RequestError::ServerGone { pid, .. }) => assert_eq!(pid, server.pid()),
        other => panic!("expected ServerGone, got {other:?}"),
    }
}

/// `Client` is not `Send`: a program with several threads connects one
/// client in each, as the CARLA gateway does per connection. Each thread's
/// client reads frames, asks for the status and applies settings on its
/// own ports, all at once, built with `Client::builder`.
#[test]
fn a_client_per_thread_each_with_its_own_ports() {
    let world = TestWorld::start(
        "per-thread",
        &["--fixed-delta-seconds", "0.01", "--realtime"],
    );
    let name = world.name().to_owned();
    let threads: Vec<_> = (0..4)
        .map(|i| {
            let name = name.clone();
            std::thread::spawn(move || {
                let mut client = Client::builder(name.as_str())
                    .timeout(Duration::from_secs(20))
                    .request_timeout(Duration::from_secs(10))
                    .wait_mode(if i % 2 == 0 {
                        WaitMode::Block
                    } else {
                        WaitMode::Spin
                    })
                    .connect()
                    .unwrap_or_else(|e| panic!("thread {i}: {e}"));
                let first = client.wait_for_tick(Duration::from_secs(10)).unwrap();
                let next = client.wait_for_tick(Duration::from_secs(10)).unwrap();
                assert!(next.frame() > first.frame(), "thread {i}");
                let status: Status = client.status().unwrap();
                assert!(status.frame >= first.frame(), "thread {i}");
                assert_eq!(status.settings.fixed_delta_seconds, Some(0.01));
                let settings = client.get_settings().unwrap();
                client.apply_settings(settings).unwrap();
                status.server_pid
            })
        })
        .collect();
    for thread in threads {
        assert_eq!(thread.join().expect("a client thread"), world.server.pid());
    }
}
