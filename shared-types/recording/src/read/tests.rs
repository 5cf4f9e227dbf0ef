//! How a file is classified before and while it is read: empty, text and
//! other bytes are "not an MCAP file"; a recording still being written is
//! "still being recorded" until its first chunk is complete, then reads up
//! to its last complete chunk; a missing file's error says its cause once.

use std::fs::File;
use std::path::PathBuf;

use super::*;
use bytemuck::Zeroable;

/// A file in a directory of its own, removed on drop.
struct Temp(PathBuf);

impl Temp {
    fn new(tag: &str) -> Self {
        let dir = std::env::temp_dir().join(format!("simbus-read-{tag}-{}", std::process::id()));
        std::fs::create_dir_all(&dir).unwrap();
        Self(dir)
    }

    fn file(&self, name: &str) -> String {
        self.0.join(name).to_string_lossy().into_owned()
    }
}

impl Drop for Temp {
    fn drop(&mut self) {
        let _ = std::fs::remove_dir_all(&self.0);
    }
}

fn open_error(path: &str) -> RecordingError {
    match RecordingReader::open(path) {
        Ok(_) => panic!("{path} was read"),
        Err(e) => e,
    }
}

#[test]
fn first_bytes_say_whether_a_file_is_mcap() {
    assert_eq!(not_mcap(b""), Some(NotMcap::Empty));
    assert_eq!(
        not_mcap(b"these are not the bytes you are looking for\n"),
        Some(NotMcap::Text)
    );
    assert_eq!(
        not_mcap("héllo, wörld\r\n\t".as_bytes()),
        Some(NotMcap::Text)
    );
    // Cut in the middle of a character: still text.
    assert_eq!(not_mcap(&"ab€".as_bytes()[..3]), Some(NotMcap::Text));
    assert_eq!(not_mcap(&[0, 1, 2, 0xff]), Some(NotMcap::OtherBytes));
    assert_eq!(not_mcap(b"\x1b[31mred"), Some(NotMcap::OtherBytes));
    assert_eq!(not_mcap(mcap::MAGIC), None);
    assert_eq!(not_mcap(&mcap::MAGIC[..3]), None, "a file being created");
    let mut more = mcap::MAGIC.to_vec();
    more.extend_from_slice(b"anything");
    assert_eq!(not_mcap(&more), None);
}

#[test]
fn empty_text_and_other_files_are_not_mcap_by_name() {
    let temp = Temp::new("kinds");
    for (name, bytes, says) in [
        ("empty.mcap", &b""[..], "is not an MCAP file: it is empty"),
        (
            "notes.mcap",
            &b"recorded on Tuesday\n"[..],
            "is not an MCAP file: it holds text",
        ),
        (
            "short.mcap",
            &b"hi"[..],
            "is not an MCAP file: it holds text",
        ),
        (
            "image.mcap",
            &[0x89, b'P', b'N', b'G', 0, 0, 0, 0x0d][..],
            "is not an MCAP file: it does not begin with MCAP's magic bytes",
        ),
    ] {
        let path = temp.file(name);
        std::fs::write(&path, bytes).unwrap();
        let error = open_error(&path);
        assert!(
            matches!(error, RecordingError::NotMcap { .. }),
            "{name}: {error}"
        );
        assert_eq!(error.code(), "not_mcap");
        assert_eq!(error.to_string(), format!("{path} {says}"));
    }
}

#[test]
fn a_missing_file_names_its_cause_once() {
    let temp = Temp::new("missing");
    let path = temp.file("missing.mcap");
    let error = open_error(&path);
    let text = error.to_string();
    assert!(text.starts_with(&format!("cannot read {path}: ")), "{text}");
    assert_eq!(text.matches("os error 2").count(), 1, "{text}");
    // The cause is in the message, not repeated as a source a chain
    // printer would append.
    assert!(std::error::Error::source(&error).is_none());
}

/// A recording being written the way the server writes one (chunked, zstd,
/// straight to the file), with `frames` frames so far and chunks of
/// `chunk_bytes`; the writer is returned unfinished.
fn recording_in_progress(path: &str, frames: u64, chunk_bytes: u64) -> mcap::Writer<File> {
    let mut mcap = mcap::WriteOptions::new()
        .profile(PROFILE)
        .compression(Some(mcap::Compression::Zstd))
        .chunk_size(Some(chunk_bytes))
        .create(File::create(path).unwrap())
        .unwrap();
    let header = RecordingHeader {
        recording_version: RECORDING_VERSION,
        simbus_version: "test".into(),
        protocol_version: shared_types::PROTOCOL_VERSION,
        world: "w".into(),
        scene: "default".into(),
        seed: 1,
        keyframe_seconds: DEFAULT_KEYFRAME_SECONDS,
        ..RecordingHeader::unread()
    };
    let schema = mcap.add_schema(HEADER_SCHEMA, "jsonschema", b"{}").unwrap();
    let header_channel = mcap
        .add_channel(schema, HEADER_TOPIC, "json", &Default::default())
        .unwrap();
    let schema = mcap.add_schema(FRAME_SCHEMA, WIRE_ENCODING, b"").unwrap();
    let frames_channel = mcap
        .add_channel(schema, FRAMES_TOPIC, WIRE_ENCODING, &Default::default())
        .unwrap();
    let message = |channel_id, sequence: u64| mcap::records::MessageHeader {
        channel_id,
        sequence: sequence as u32,
        log_time: sequence,
        publish_time: sequence,
    };
    mcap.write_to_known_channel(
        &message(header_channel, 0),
        &serde_json::to_vec(&header).unwrap(),
    )
    .unwrap();
    for frame in 0..frames {
        let mut header = FrameHeader::zeroed();
        header.timestamp.frame = frame;
        // Different bytes per frame, so that chunks fill despite zstd.
        header.timestamp.platform_timestamp = (frame as f64).sqrt();
        header.server_pid = frame.wrapping_mul(2_654_435_761) as u32;
        mcap.write_to_known_channel(&message(frames_channel, frame), bytemuck::bytes_of(&header))
            .unwrap();
    }
    mcap
}

fn frames_in(path: &str) -> (u64, bool) {
    let mut reader = RecordingReader::open(path).unwrap();
    let mut frames = 0;
    while let Some(entry) = reader.next() {
        match entry.unwrap() {
            Entry::Frame { header, .. } => {
                assert_eq!(header.timestamp.frame, frames);
                frames += 1;
            }
            other => panic!("unexpected {other:?}"),
        }
    }
    (frames, reader.truncated())
}

#[test]
fn a_recording_being_written_says_so_then_reads_its_complete_chunks() {
    let temp = Temp::new("live");
    // Its first chunk is still being gathered: nothing to read yet.
    let path = temp.file("young.mcap");
    let writer = recording_in_progress(&path, 10, 1 << 20);
    let error = open_error(&path);
    assert!(matches!(error, RecordingError::Truncated { .. }), "{error}");
    assert!(
        error
            .to_string()
            .contains("is still being recorded, or was not closed"),
        "{error}"
    );
    assert!(!error.to_string().contains("damaged"), "{error}");
    drop(writer);

    // Several chunks are complete, one is being gathered: the complete
    // ones are read, no error, and the file says it was not closed.
    let path = temp.file("older.mcap");
    let mut writer = recording_in_progress(&path, 2000, 4096);
    let (frames, truncated) = frames_in(&path);
    assert!(truncated, "an unfinished file is flagged");
    assert!(
        frames > 0 && frames < 2000,
        "{frames} frames read from complete chunks"
    );
    // Once closed, every frame reads and nothing is flagged.
    writer.finish().unwrap();
    drop(writer);
    assert_eq!(frames_in(&path), (2000, false));
}
