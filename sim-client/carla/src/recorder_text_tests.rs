//! CARLA's `show_recorder_file_info` layout from a small recording: the
//! heading, a frame's title only when it has events (every frame with
//! `show_all`), `Create` in CARLA's axes and centimetres, `Destroy`,
//! `Collision`, `Positions:`, and `Frames:` / `Duration:` as C++ writes
//! numbers.

use shared_types::{FrameHeader, WorldSettings};
use simbus_recording::{RecordedSettings, RECORDING_VERSION};

use super::*;

fn header() -> RecordingHeader {
    RecordingHeader {
        recording_version: RECORDING_VERSION,
        simbus_version: "test".into(),
        protocol_version: shared_types::PROTOCOL_VERSION,
        world: "w".into(),
        scene: "town".into(),
        seed: 1,
        settings: RecordedSettings::from(WorldSettings::default()),
        start_frame: 40,
        start_elapsed_ns: 2_000_000_000,
        episode: 1,
        start_platform_timestamp: 1_700_000_000.0,
        sensors: false,
        keyframe_seconds: 10.0,
        journal_sync_frames: 0,
        run_pid: 0,
    }
}

fn actor(id: u64, kind: ActorKind, position: [f32; 3]) -> ActorState {
    ActorState {
        id,
        kind: kind as u32,
        position,
        rotation: [0.0, 0.0, 0.0, 1.0],
        ..ActorState::default()
    }
}

fn frame(frame: u64, log_ms: u64, actors: Vec<ActorState>) -> Entry {
    let mut header = FrameHeader::default();
    header.timestamp.frame = frame;
    header.actor_count = actors.len() as u32;
    Entry::Frame {
        log_ns: log_ms * 1_000_000,
        header,
        actors,
    }
}

/// Three frames 0.05 s apart: the ground, a vehicle (simbus x 1, y 0.5,
/// z 3 m) and a box; the box hits the vehicle in the second frame and is
/// gone in the third.
fn recording() -> Vec<Entry> {
    let ground = actor(1, ActorKind::Static, [0.0; 3]);
    let car = actor(2, ActorKind::Vehicle, [1.0, 0.5, 3.0]);
    let boxed = actor(3, ActorKind::Box, [-2.25, 1.0, 0.0]);
    let hit = RecordedCollision {
        frame: 41,
        actor_a: 2,
        actor_b: 3,
        kind_a: ActorKind::Vehicle as u32,
        kind_b: ActorKind::Box as u32,
        elapsed_ns: 2_050_000_000,
        impulse: 1.0,
        reserved: 0,
    };
    vec![
        frame(40, 0, vec![ground, car, boxed]),
        frame(41, 50, vec![ground, car, boxed]),
        Entry::Collision(hit),
        frame(42, 100, vec![ground, car]),
    ]
}

fn text(show_all: bool) -> String {
    let names = Names::new();
    let mut text = InfoText::new(&header(), show_all, &names);
    for entry in recording() {
        text.entry(&entry);
    }
    text.finish()
}

/// The text after its `Date:` line (which depends on the time zone).
fn after_date(text: &str) -> &str {
    let start = text.find("Date: ").unwrap();
    &text[start + text[start..].find('\n').unwrap() + 1..]
}

#[test]
fn file_info_is_in_carlas_layout() {
    let text = text(false);
    assert!(text.starts_with("Version: 1\nMap: town\nDate: "), "{text}");
    let date = text.lines().nth(2).unwrap().strip_prefix("Date: ").unwrap();
    let shape: String = date
        .chars()
        .map(|c| if c.is_ascii_digit() { '9' } else { c })
        .collect();
    assert_eq!(shape, "99/99/99 99:99:99", "{text}");
    assert_eq!(
        after_date(&text),
        "\n\
         Frame 1 at 0 seconds\n \
         Create 1: static.prop.fixed (0) at (0, 0, 0)\n \
         Create 2: vehicle.simbus.car (1) at (100, 300, 50)\n \
         Create 3: static.prop.box (0) at (-225, 0, 100)\n\
         Frame 2 at 0.05 seconds\n \
         Collision id 0 between 2 with 3\n\
         Frame 3 at 0.1 seconds\n \
         Destroy 3\n\
         \n\
         Frames: 3\n\
         Duration: 0.1 seconds\n"
    );
}

#[test]
fn show_all_lists_every_frame_and_its_positions() {
    let text = text(true);
    let frame_titles: Vec<&str> = text.lines().filter(|l| l.starts_with("Frame ")).collect();
    assert_eq!(
        frame_titles,
        [
            "Frame 1 at 0 seconds",
            "Frame 2 at 0.05 seconds",
            "Frame 3 at 0.1 seconds"
        ]
    );
    assert!(
        text.contains(
            "Frame 3 at 0.1 seconds\n Destroy 3\n Positions: 2\n  \
             Id: 1 Location: (0, 0, 0) Rotation: (0, 0, 0)\n  \
             Id: 2 Location: (100, 300, 50) Rotation: (0, 0, 0)\n"
        ),
        "{text}"
    );
    assert!(
        text.ends_with("\nFrames: 3\nDuration: 0.1 seconds\n"),
        "{text}"
    );
}

#[test]
fn a_collision_read_before_its_frame_goes_with_that_frame() {
    let mut entries = recording();
    entries.swap(1, 2); // the collision before frame 41
    let names = Names::new();
    let mut text = InfoText::new(&header(), false, &names);
    for entry in entries {
        text.entry(&entry);
    }
    let text = text.finish();
    assert!(
        text.contains("Frame 2 at 0.05 seconds\n Collision id 0 between 2 with 3\n"),
        "{text}"
    );
}

#[test]
fn an_empty_recording_has_zero_frames() {
    let text = InfoText::new(&header(), true, &Names::new()).finish();
    assert!(
        text.ends_with("\n\nFrames: 0\nDuration: 0 seconds\n"),
        "{text}"
    );
}

#[test]
fn numbers_read_as_cpp_streams_write_them() {
    for (x, written) in [
        (0.0, "0"),
        (1.0, "1"),
        (0.05, "0.05"),
        (0.1 + 0.2, "0.3"),
        (-2.5, "-2.5"),
        (100.5, "100.5"),
        (123456.0, "123456"),
        (1234567.0, "1.23457e+06"),
        (999999.5, "1e+06"),
        (123456789.0, "1.23457e+08"),
        (0.0001, "0.0001"),
        (0.00001, "1e-05"),
        (2.0 / 3.0, "0.666667"),
        (f64::INFINITY, "inf"),
        (f64::NAN, "nan"),
    ] {
        assert_eq!(cpp_number(x), written, "{x}");
    }
}
