//! The image cameras: a red box 10 m ahead appears where the depth camera
//! says it is, in the box's colour, with its CARLA tag and with its actor id
//! in green and blue; four cameras at one pose cost one ray cast (the
//! frame's `sensor_rays`); the weather's sun changes the shading and a
//! sun at NaN degrees changes nothing; `sim-client sensor save --raw` writes
//! the bytes the Rust client reads in place.

use std::collections::HashMap;
use std::time::{Duration, Instant};

use shared_types::{Command, CommandStatus, SemanticTag, SensorKind, SensorSpec, Sun};
use sim_client::{Client, Sensor, Ticker};
use simbus_tests::{Scratch, TestWorld};

const T: Duration = Duration::from_secs(20);
const W: usize = 64;
const H: usize = 48;

/// A synchronous empty world with a floating box of half extent 1 m whose
/// near face is 9 m ahead of (0, 5, 0) along +X; its id.
fn world_with_a_box(tag: &str) -> (TestWorld, Client, Ticker, u64) {
    let (world, client, ticker) =
        simbus_tests::sync_world(tag, &["--scene", "empty", "--max-sensor-readers", "4"]);
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
    (world, client, ticker, id)
}

fn camera(client: &Client, kind: SensorKind, at: [f32; 3]) -> Sensor {
    let spec = SensorSpec::camera_of(kind, at, (W as u32, H as u32), 60.0, 100.0).unwrap();
    client.spawn_sensor(spec).unwrap()
}

/// The frame header's ray count of frame `frame`.
fn rays_of(client: &mut Client, frame: u64) -> u32 {
    loop {
        let view = client.wait_for_frame(T).unwrap();
        if view.header().timestamp.frame >= frame {
            assert_eq!(view.header().timestamp.frame, frame, "the frame ticked");
            return view.header().sensor_rays;
        }
    }
}

#[test]
fn a_red_box_appears_where_the_depth_camera_sees_it_with_its_tag_and_id() {
    let (_server, client, mut ticker, id) = world_with_a_box("camera-box");
    let at = [0.0, 5.0, 0.0];
    let mut depth = camera(&client, SensorKind::Depth, at);
    let mut rgb = camera(&client, SensorKind::Rgb, at);
    let mut semantic = camera(&client, SensorKind::Semantic, at);
    let mut instance = camera(&client, SensorKind::Instance, at);
    let frame = ticker.tick(T).unwrap();
    let captures = [&mut depth, &mut rgb, &mut semantic, &mut instance].map(|s| s.recv(T).unwrap());
    for c in &captures {
        assert_eq!(c.header().frame, frame);
        assert_eq!(c.header().size, [W as u32, H as u32]);
    }
    let [depth, rgb, semantic, instance] = &captures;
    let depth = depth.depth().unwrap();
    let (rgb, semantic, instance) = (
        rgb.image().unwrap(),
        semantic.image().unwrap(),
        instance.image().unwrap(),
    );
    let mut on_box = 0;
    for i in 0..W * H {
        let (c, s, n) = (rgb[i], semantic[i], instance[i]);
        if depth[i] < 100.0 {
            on_box += 1;
            assert!((depth[i] - 9.0).abs() < 1e-3, "pixel {i}: {}", depth[i]);
            assert!(
                c.r > 2 * c.g.max(c.b) && c.r > 40,
                "pixel {i}: the box is red: {c:?}"
            );
            assert_eq!(s.r, SemanticTag::Dynamic as u8, "pixel {i}");
            assert_eq!((s.g, s.b, s.a), (0, 0, 255));
            assert_eq!(n.r, SemanticTag::Dynamic as u8, "pixel {i}");
            assert_eq!(u64::from(n.g) | u64::from(n.b) << 8, id & 0xffff);
        } else {
            // Nothing else in an empty world: sky everywhere else.
            assert_eq!(s.r, SemanticTag::Sky as u8, "pixel {i}");
            assert_eq!((n.r, n.g, n.b), (SemanticTag::Sky as u8, 0, 0));
            assert!(c.b > c.r, "pixel {i}: the sky is blue: {c:?}");
        }
    }
    // A 2 m face at 9 m in a 60° camera: a sizeable patch, not all the image.
    assert!(
        on_box > 50 && on_box < W * H / 2,
        "{on_box} pixels on the box"
    );
}

#[test]
fn four_cameras_at_one_pose_cost_one_cast() {
    let (_server, mut client, mut ticker, _) = world_with_a_box("camera-rays");
    let at = [0.0, 5.0, 0.0];
    let mut sensors: Vec<Sensor> = [
        SensorKind::Depth,
        SensorKind::Rgb,
        SensorKind::Semantic,
        SensorKind::Instance,
    ]
    .into_iter()
    .map(|kind| camera(&client, kind, at))
    .collect();
    let frame = ticker.tick(T).unwrap();
    assert_eq!(rays_of(&mut client, frame) as usize, W * H, "one cast");
    for s in &mut sensors {
        assert_eq!(s.recv(T).unwrap().header().frame, frame);
    }
    // A camera a metre higher casts its own.
    let _apart = camera(&client, SensorKind::Rgb, [0.0, 6.0, 0.0]);
    let frame = ticker.tick(T).unwrap();
    assert_eq!(rays_of(&mut client, frame) as usize, 2 * W * H, "two casts");
}

#[test]
fn the_weather_s_sun_changes_the_shading_and_a_nan_one_changes_nothing() {
    let (_server, client, mut ticker, _) = world_with_a_box("camera-sun");
    let mut rgb = camera(&client, SensorKind::Rgb, [0.0, 5.0, 0.0]);
    let centre = (H / 2) * W + W / 2;
    let mut shade = |sun: Sun| {
        let result = client
            .apply_batch_sync(&[Command::set_sun(sun)], false)
            .unwrap();
        let frame = ticker.tick(T).unwrap();
        let capture = rgb.recv(T).unwrap();
        assert_eq!(capture.header().frame, frame);
        (result.results[0].status, capture.image().unwrap()[centre])
    };
    // The box's near face looks at the camera (−X): lit by a sun low behind
    // the camera, in shadow with the sun low behind the box.
    let (ok, lit) = shade(Sun {
        azimuth: 180.0,
        altitude: 5.0,
    });
    assert_eq!(ok, CommandStatus::Ok as u32);
    let (_, shadowed) = shade(Sun {
        azimuth: 0.0,
        altitude: 5.0,
    });
    assert!(
        lit.r > shadowed.r + 60,
        "lit {lit:?} against shadowed {shadowed:?}"
    );
    let (refused, unchanged) = shade(Sun {
        azimuth: 0.0,
        altitude: f32::NAN,
    });
    assert_eq!(refused, CommandStatus::InvalidArgument as u32);
    assert_eq!(unchanged, shadowed, "the sun did not move");
}

#[test]
fn sensor_save_raw_writes_the_bytes_the_client_reads_in_place() {
    let (world, client, mut ticker, _) = world_with_a_box("camera-raw");
    let mut rgb = camera(&client, SensorKind::Rgb, [0.0, 5.0, 0.0]);
    let dir = Scratch::new("camera-raw");
    let out = dir.path().to_str().unwrap().to_owned();
    let id = rgb.id().to_string();
    let saver = world.spawn_cli(&["sensor", "save", &id, "--raw", "--out", &out]);
    // Tick until the saver has written a capture: it subscribes on its own
    // time, so the frame it saves is whichever came first after that.
    let mut read = HashMap::new();
    let deadline = Instant::now() + T;
    let written = loop {
        assert!(Instant::now() < deadline, "no capture saved");
        let frame = ticker.tick(T).unwrap();
        let capture = rgb.recv(T).unwrap();
        assert_eq!(capture.header().frame, frame);
        read.insert(frame, capture.bytes().to_vec());
        if let Some(line) = saver.line(Duration::from_millis(20)) {
            if line.contains(".raw") {
                break line;
            }
        }
    };
    let saved = saver.finish(T);
    saved.assert_success();
    let frame: u64 = written
        .split("-frame")
        .nth(1)
        .and_then(|rest| rest.split('.').next())
        .and_then(|n| n.parse().ok())
        .unwrap_or_else(|| panic!("a frame in {written:?}"));
    let raw = std::fs::read(dir.path().join(format!("sensor{id}-frame{frame}.raw"))).unwrap();
    assert_eq!(raw.len(), W * H * 4);
    assert_eq!(
        Some(&raw),
        read.get(&frame),
        "frame {frame}: the same bytes"
    );
    assert!(dir
        .path()
        .join(format!("sensor{id}-frame{frame}.png"))
        .exists());
}
