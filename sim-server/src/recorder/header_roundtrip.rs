//! A recording the writer closed reads back, whatever the recorder's
//! options were: every header the writer writes is one the reader takes.
//! (Issue #24: `--keyframe-seconds NaN` wrote `"keyframe_seconds":null`,
//! and the reader called the cleanly stopped file "not a simbus recording".)

use std::sync::mpsc::sync_channel;

use proptest::prelude::*;
use simbus_recording::{
    Entry, RecordedEvent, RecordedSettings, RecordingHeader, RecordingReader, RECORDING_VERSION,
};

use super::{create, run, Item};

/// Any `f64`, the non-finite ones and the boundaries made likely.
fn any_seconds() -> impl Strategy<Value = f64> {
    prop_oneof![
        Just(f64::NAN),
        Just(f64::INFINITY),
        Just(f64::NEG_INFINITY),
        Just(0.0),
        Just(-0.0),
        Just(f64::MAX),
        Just(f64::MIN_POSITIVE),
        any::<f64>(),
        0.0..1e4f64,
    ]
}

fn any_settings() -> impl Strategy<Value = RecordedSettings> {
    (
        any::<bool>(),
        proptest::option::of(any_seconds()),
        any::<bool>(),
        any_seconds(),
        any::<u32>(),
        proptest::sample::select(shared_types::SubstepRule::ALL.to_vec()),
    )
        .prop_map(
            |(
                synchronous_mode,
                fixed_delta_seconds,
                substepping,
                max_substep_delta_time,
                max_substeps,
                substep_rule,
            )| {
                RecordedSettings {
                    synchronous_mode,
                    fixed_delta_seconds,
                    substepping,
                    max_substep_delta_time,
                    max_substeps,
                    substep_rule,
                }
            },
        )
}

fn any_header() -> impl Strategy<Value = RecordingHeader> {
    (
        ("[a-z0-9_-]{1,20}", "\\PC{0,24}", any::<u64>()),
        any_settings(),
        (any::<u64>(), any::<u64>(), any::<u64>()),
        (any_seconds(), any::<bool>(), any_seconds()),
    )
        .prop_map(
            |(
                (world, scene, seed),
                settings,
                (start_frame, start_elapsed_ns, episode),
                (start_platform_timestamp, sensors, keyframe_seconds),
            )| RecordingHeader {
                recording_version: RECORDING_VERSION,
                simbus_version: env!("CARGO_PKG_VERSION").to_string(),
                protocol_version: shared_types::PROTOCOL_VERSION,
                world,
                scene,
                seed,
                settings,
                start_frame,
                start_elapsed_ns,
                episode,
                start_platform_timestamp,
                sensors,
                keyframe_seconds,
                journal_sync_frames: 0,
                run_pid: 0,
            },
        )
}

/// The same number: equal, both NaN, or (JSON's float parsing is not
/// bit-exact for every value) within one unit in the last place.
fn same(a: f64, b: f64) -> bool {
    a == b
        || (a.is_nan() && b.is_nan())
        || (a.is_finite() && b.is_finite() && (a - b).abs() <= f64::EPSILON * a.abs().max(b.abs()))
}

fn same_settings(a: &RecordedSettings, b: &RecordedSettings) -> bool {
    a.synchronous_mode == b.synchronous_mode
        && a.substepping == b.substepping
        && a.max_substeps == b.max_substeps
        && a.substep_rule == b.substep_rule
        && same(a.max_substep_delta_time, b.max_substep_delta_time)
        && match (a.fixed_delta_seconds, b.fixed_delta_seconds) {
            (None, None) => true,
            (Some(x), Some(y)) => same(x, y),
            _ => false,
        }
}

/// Writes a recording with `header`, a settings event and the stop event,
/// closes it, and reads it back: the header and both events.
fn write_and_read(header: &RecordingHeader, case: u32) -> Result<(), TestCaseError> {
    let path = std::env::temp_dir().join(format!(
        "simbus-header-roundtrip-{}-{case}.mcap",
        std::process::id()
    ));
    let path_text = path.to_string_lossy().into_owned();
    let handle =
        create(&path_text, header, false).map_err(|e| TestCaseError::fail(e.to_string()))?;
    let (items, receiver) = sync_channel(4);
    let events = [
        RecordedEvent::Settings {
            frame: header.start_frame,
            settings: header.settings,
        },
        RecordedEvent::Stopped {
            frame: header.start_frame,
            reason: "stop".to_string(),
        },
    ];
    for event in events.clone() {
        items
            .send(Item::Event { log_ns: 0, event })
            .map_err(|e| TestCaseError::fail(e.to_string()))?;
    }
    drop(items);
    let written = run(handle, receiver, path_text.clone());
    let read = RecordingReader::open(&path_text);
    let entries: Vec<Entry> = match &read {
        Ok(_) => {
            let mut reader = RecordingReader::open(&path_text).expect("opened once already");
            std::iter::from_fn(|| reader.next())
                .collect::<Result<_, _>>()
                .map_err(|e| TestCaseError::fail(e.to_string()))?
        }
        Err(_) => Vec::new(),
    };
    let _ = std::fs::remove_file(&path);
    prop_assert!(written.is_ok(), "the writer closed the file: {:?}", written);
    let reader = read.map_err(|e| TestCaseError::fail(format!("a closed recording reads: {e}")))?;
    let back = reader.header();
    prop_assert_eq!(&back.world, &header.world);
    prop_assert_eq!(&back.scene, &header.scene);
    prop_assert_eq!(back.seed, header.seed);
    prop_assert_eq!(back.sensors, header.sensors);
    prop_assert_eq!(back.start_frame, header.start_frame);
    prop_assert_eq!(back.start_elapsed_ns, header.start_elapsed_ns);
    prop_assert_eq!(back.episode, header.episode);
    prop_assert!(same(back.keyframe_seconds, header.keyframe_seconds));
    prop_assert!(same(
        back.start_platform_timestamp,
        header.start_platform_timestamp
    ));
    prop_assert!(same_settings(&back.settings, &header.settings));
    let recorded: Vec<&RecordedEvent> = entries
        .iter()
        .filter_map(|e| match e {
            Entry::Event(event) => Some(event),
            _ => None,
        })
        .collect();
    prop_assert_eq!(recorded.len(), 2, "both events read back: {:?}", entries);
    match recorded[0] {
        RecordedEvent::Settings { settings, .. } => {
            prop_assert!(same_settings(settings, &header.settings))
        }
        other => prop_assert!(false, "the settings event first, got {:?}", other),
    }
    prop_assert_eq!(recorded[1], &events[1]);
    Ok(())
}

#[test]
fn every_header_the_writer_writes_reads_back() {
    let case = std::cell::Cell::new(0);
    let mut runner = proptest::test_runner::TestRunner::new(ProptestConfig {
        cases: 64,
        failure_persistence: None,
        ..ProptestConfig::default()
    });
    runner
        .run(&any_header(), |header| {
            case.set(case.get() + 1);
            write_and_read(&header, case.get())
        })
        .unwrap();
}

#[test]
fn the_issue_24_header_reads_back() {
    // `--keyframe-seconds NaN`, exactly as issue #24 reported it.
    let header = RecordingHeader {
        recording_version: RECORDING_VERSION,
        simbus_version: env!("CARGO_PKG_VERSION").to_string(),
        protocol_version: shared_types::PROTOCOL_VERSION,
        world: "default".into(),
        scene: "default".into(),
        seed: 0,
        settings: shared_types::WorldSettings::default().into(),
        start_frame: 7,
        start_elapsed_ns: 0,
        episode: 1,
        start_platform_timestamp: 1.7e9,
        sensors: false,
        keyframe_seconds: f64::NAN,
        journal_sync_frames: 0,
        run_pid: 0,
    };
    write_and_read(&header, 0).unwrap();
}
