//! A sync that cannot reach the disk says why as a typed error: the frame
//! loop that asked gets the MCAP writer's I/O error (its kind intact, here
//! "no space left"), and the writer thread ends with that kind. (Issue 44,
//! item 5: the cause was flattened to a string.)

use shared_types::FrameHeader;
use simbus_recording::{RecordedSettings, RecordingHeader, RECORDING_VERSION};
use std::io::ErrorKind;

use super::{io_kind, WriteError};
use crate::recorder::{Recorder, SyncError};
use crate::world::World;

fn header() -> RecordingHeader {
    RecordingHeader {
        recording_version: RECORDING_VERSION,
        simbus_version: env!("CARGO_PKG_VERSION").to_string(),
        protocol_version: shared_types::PROTOCOL_VERSION,
        world: "sync-errors".to_string(),
        scene: "empty".to_string(),
        seed: 0,
        settings: RecordedSettings::from(shared_types::WorldSettings::default()),
        start_frame: 0,
        start_elapsed_ns: 0,
        episode: 1,
        start_platform_timestamp: 0.0,
        sensors: false,
        keyframe_seconds: 1.0,
        journal_sync_frames: 1,
        run_pid: 0,
    }
}

/// Points every descriptor this process holds on `path` at `/dev/full`,
/// where every write fails with ENOSPC: the disk under the recording
/// fills.
fn fill_the_disk_under(path: &std::path::Path) {
    let full = std::fs::OpenOptions::new()
        .write(true)
        .open("/dev/full")
        .expect("Linux's /dev/full");
    let mut moved = 0;
    for entry in std::fs::read_dir("/proc/self/fd").unwrap().flatten() {
        let Ok(target) = std::fs::read_link(entry.path()) else {
            continue;
        };
        let Some(fd) = entry.file_name().to_str().and_then(|n| n.parse().ok()) else {
            continue;
        };
        if target == path {
            // SAFETY: both descriptors are open; `fd` is replaced in place
            // (the File that owns it closes /dev/full's copy later).
            let replaced = unsafe { libc::dup2(std::os::fd::AsRawFd::as_raw_fd(&full), fd) };
            assert_eq!(replaced, fd);
            moved += 1;
        }
    }
    assert!(moved > 0, "no descriptor on {}", path.display());
}

#[test]
fn a_sync_on_a_full_disk_answers_the_io_error_typed() {
    let file = std::env::temp_dir().join(format!("simbus-sync-full-{}.mcap", std::process::id()));
    let path = file.to_string_lossy().into_owned();
    let mut recorder = Recorder::default();
    recorder.journal = true;
    let world = World::new(&[], 1);
    let frame: FrameHeader = bytemuck::Zeroable::zeroed();
    recorder
        .start(
            &path,
            header(),
            Vec::new(),
            (&frame, &world),
            "empty".to_string(),
        )
        .expect("a temporary file");
    fill_the_disk_under(&file);
    match recorder.sync() {
        Err(SyncError::Write(WriteError::Write {
            path: failed,
            error,
        })) => {
            assert_eq!(failed, path);
            assert_eq!(io_kind(&error), Some(ErrorKind::StorageFull), "{error}");
        }
        other => panic!("{other:?}"),
    }
    assert!(!recorder.is_recording(), "a failed sync ends the recording");
    let _ = std::fs::remove_file(&file);
}

#[test]
fn a_sync_with_nothing_recording_is_refused_as_such() {
    let mut recorder = Recorder::default();
    assert!(matches!(recorder.sync(), Err(SyncError::NotRecording)));
}
