//! The recording's writer thread: it owns the MCAP file, takes what the
//! frame loop hands it over a bounded channel and writes it, so the frame
//! loop never waits for the disk unless the channel is full.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufWriter, Write};
use std::sync::mpsc::Receiver;

use mcap::records::MessageHeader;
use serde_json::json;
use shared_types::{ActorState, FrameHeader, SensorHeader};
use simbus_recording::*;
use tracing::{info, warn};

use super::create::{create_file, describe, StartError};
use super::scene_update::{scene_update, scene_update_schema};

/// Bytes of messages gathered before a chunk is compressed and written: a
/// killed server loses at most the chunk being gathered.
const CHUNK_BYTES: u64 = 1 << 20;

/// What the frame loop hands the writer.
#[derive(Debug)]
pub(crate) enum Item {
    /// A published frame.
    Frame {
        log_ns: u64,
        header: FrameHeader,
        actors: Vec<ActorState>,
        /// The debug shapes it shows.
        shapes: Vec<shared_types::DebugShape>,
    },
    /// An applied command.
    Command {
        log_ns: u64,
        command: RecordedCommand,
    },
    /// An event.
    Event { log_ns: u64, event: RecordedEvent },
    /// A collision.
    Collision {
        log_ns: u64,
        collision: RecordedCollision,
    },
    /// A sensor's spawn.
    Sensor { log_ns: u64, sensor: RecordedSensor },
    /// A capture.
    Capture {
        log_ns: u64,
        header: SensorHeader,
        data: Vec<u8>,
    },
    /// A keyframe after `frame`.
    Keyframe {
        log_ns: u64,
        frame: u64,
        data: Vec<u8>,
    },
    /// A journal's items, in order.
    Batch(Vec<Item>),
    /// Make everything handed over so far durable (end the chunk, flush,
    /// `fdatasync`), then say so on `done`: how a journal keeps its promise.
    Sync {
        done: std::sync::mpsc::SyncSender<Result<(), WriteError>>,
    },
}

/// The kind of the I/O error under an MCAP writer's error, its binrw
/// layer included (a full disk while a record is written arrives as a
/// parse error holding the I/O error).
pub(crate) fn io_kind(error: &mcap::McapError) -> Option<std::io::ErrorKind> {
    match error {
        mcap::McapError::Io(e) | mcap::McapError::Parse(binrw::Error::Io(e)) => Some(e.kind()),
        _ => None,
    }
}

/// What a finished recording holds.
#[derive(Debug, Clone, Copy, Default)]
pub(crate) struct Written {
    pub(crate) frames: u64,
    pub(crate) bytes: u64,
}

/// The open file and its channel ids.
struct Writer {
    mcap: McapFile,
    frames: u16,
    commands: u16,
    events: u16,
    collisions: u16,
    sensors: u16,
    keyframes: u16,
    scene: u16,
    capture_schema: u16,
    captures: HashMap<u64, u16>,
    written: Written,
    scratch: Vec<u8>,
    /// The file again, to sync it (the MCAP writer owns the other handle).
    file: File,
    /// Write each frame as a Foxglove scene too (a recording: yes; a
    /// journal, which only a resume reads: no).
    pub(crate) scene_updates: bool,
}

type McapResult<T> = Result<T, mcap::McapError>;
type McapFile = mcap::Writer<BufWriter<File>>;

/// Creates `path` and writes the header; the file is ready for [`run`].
/// A path that cannot be created is refused with the file system's reason.
pub(crate) fn create(
    path: &str,
    header: &RecordingHeader,
    journal: bool,
) -> Result<WriterHandle, StartError> {
    let file = create_file(path)?;
    let sync_handle = file.try_clone().map_err(|error| StartError::Header {
        path: path.to_string(),
        error: mcap::McapError::Io(error),
    })?;
    begin(file, sync_handle, header, journal).map_err(|error| StartError::Header {
        path: path.to_string(),
        error,
    })
}

/// Writes the header into the created `file`.
fn begin(
    file: File,
    sync_handle: File,
    header: &RecordingHeader,
    journal: bool,
) -> McapResult<WriterHandle> {
    let mut mcap = mcap::WriteOptions::new()
        .profile(PROFILE)
        .library(format!("simbus {}", env!("CARGO_PKG_VERSION")))
        // A journal's chunks go uncompressed: each sync ends a chunk of a
        // few frames, and compressing them cost the frame loop more than
        // the disk saves (`simbus-bench recorder`'s journal rows).
        .compression((!journal).then_some(mcap::Compression::Zstd))
        .chunk_size(Some(CHUNK_BYTES))
        .create(BufWriter::new(file))?;
    let header_json = serde_json::to_vec(header).unwrap_or_default();
    let mut metadata = std::collections::BTreeMap::new();
    metadata.insert(
        "header".to_string(),
        String::from_utf8_lossy(&header_json).into_owned(),
    );
    mcap.write_metadata(&mcap::records::Metadata {
        name: "simbus".to_string(),
        metadata,
    })?;
    let channels = add_channels(&mut mcap)?;
    mcap.write_to_known_channel(
        &MessageHeader {
            channel_id: channels.header,
            sequence: 0,
            log_time: 0,
            publish_time: header.start_elapsed_ns,
        },
        &header_json,
    )?;
    // The header in a chunk of its own, on disk now: a recording still
    // being written reads as one (its header, then every complete chunk),
    // not as an empty or damaged file.
    mcap.flush()?;
    Ok(WriterHandle(Writer {
        mcap,
        frames: channels.frames,
        commands: channels.commands,
        events: channels.events,
        collisions: channels.collisions,
        sensors: channels.sensors,
        keyframes: channels.keyframes,
        scene: channels.scene,
        capture_schema: channels.capture_schema,
        captures: HashMap::new(),
        written: Written::default(),
        scratch: Vec::new(),
        file: sync_handle,
        // A journal is read by a resume, not by Foxglove.
        scene_updates: !journal,
    }))
}

/// The ids of a recording's channels (and of the schema its sensors'
/// channels share).
struct Channels {
    header: u16,
    frames: u16,
    commands: u16,
    collisions: u16,
    sensors: u16,
    events: u16,
    keyframes: u16,
    scene: u16,
    capture_schema: u16,
}

/// A schema in JSON Schema named `name`.
fn json_schema(mcap: &mut McapFile, name: &str, schema: serde_json::Value) -> McapResult<u16> {
    mcap.add_schema(name, "jsonschema", schema.to_string().as_bytes())
}

/// A channel on `topic` of `#[repr(C)]` records laid out as `layout` says.
fn wire_channel(mcap: &mut McapFile, schema: &str, layout: &str, topic: &str) -> McapResult<u16> {
    let id = mcap.add_schema(schema, WIRE_ENCODING, layout.as_bytes())?;
    mcap.add_channel(id, topic, WIRE_ENCODING, &Default::default())
}

/// Adds every channel of a recording (and the captures' schema), in the
/// order their ids are given out.
fn add_channels(mcap: &mut McapFile) -> McapResult<Channels> {
    let header_schema = json_schema(mcap, HEADER_SCHEMA, json!({"type": "object"}))?;
    let header = mcap.add_channel(header_schema, HEADER_TOPIC, "json", &Default::default())?;
    let frames = wire_channel(
        mcap,
        FRAME_SCHEMA,
        "#[repr(C)] simbus::FrameHeader/3 (112 bytes, little-endian) followed by actor_count simbus::ActorState/1 (96 bytes each); see shared-types/src/frame.rs",
        FRAMES_TOPIC,
    )?;
    let commands = wire_channel(
        mcap,
        COMMAND_SCHEMA,
        "#[repr(C)] simbus::RecordedCommand/1: frame u64, episode u64, simbus::Command, simbus::CommandResult; see shared-types/recording/src/lib.rs",
        COMMANDS_TOPIC,
    )?;
    let collisions = wire_channel(
        mcap,
        COLLISION_SCHEMA,
        "#[repr(C)] simbus::RecordedCollision/1 (48 bytes); see shared-types/recording/src/lib.rs",
        COLLISIONS_TOPIC,
    )?;
    let sensors = wire_channel(
        mcap,
        SENSOR_SPAWN_SCHEMA,
        "#[repr(C)] simbus::RecordedSensor/2: frame u64, id u64, simbus::SensorSpec/2",
        SENSORS_TOPIC,
    )?;
    let event_schema = json_schema(
        mcap,
        EVENT_SCHEMA,
        json!({"type": "object", "required": ["event"]}),
    )?;
    let events = mcap.add_channel(event_schema, EVENTS_TOPIC, "json", &Default::default())?;
    let keyframe_schema = mcap.add_schema(
        KEYFRAME_SCHEMA,
        "postcard",
        b"simbus server world: rapier3d 0.36 PhysicsWorld (serde) and simbus actors, postcard",
    )?;
    let keyframes = mcap.add_channel(
        keyframe_schema,
        KEYFRAMES_TOPIC,
        "postcard",
        &Default::default(),
    )?;
    let scene_schema = json_schema(mcap, SCENE_SCHEMA, scene_update_schema())?;
    let scene = mcap.add_channel(scene_schema, SCENE_TOPIC, "json", &Default::default())?;
    let capture_schema = mcap.add_schema(
        CAPTURE_SCHEMA,
        WIRE_ENCODING,
        b"#[repr(C)] simbus::SensorHeader/2 followed by the capture's elements (f32 depth; simbus::Bgra for rgb, semantic and instance; simbus::LidarPoint/1, simbus::SemanticLidarPoint/1, simbus::RadarDetection/1, simbus::ImuMeasurement/1, simbus::GnssMeasurement/1, simbus::CollisionEvent/1 or simbus::ObstacleDetection/1)",
    )?;
    Ok(Channels {
        header,
        frames,
        commands,
        collisions,
        sensors,
        events,
        keyframes,
        scene,
        capture_schema,
    })
}

/// A created recording, to be moved to its thread.
pub(crate) struct WriterHandle(Writer);

impl std::fmt::Debug for WriterHandle {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str("WriterHandle")
    }
}

/// Writes every item until the channel closes, then finishes the file
/// (summary, indexes, footer). Returns what was written.
pub(crate) fn run(
    handle: WriterHandle,
    items: Receiver<Item>,
    path: String,
) -> Result<Written, WriteError> {
    let mut writer = handle.0;
    while let Ok(item) = items.recv() {
        if let Item::Sync { done } = item {
            let Err(error) = writer.sync() else {
                let _ = done.send(Ok(()));
                continue;
            };
            warn!(path, "journal sync failed: {}", describe(&error));
            // The frame loop waiting on `done` gets the error; the thread
            // ends with its kind, which the recorder's status shows.
            let kind = io_kind(&error).unwrap_or(std::io::ErrorKind::Other);
            let _ = done.send(Err(WriteError::Write {
                path: path.clone(),
                error,
            }));
            return Err(WriteError::Sync { path, kind });
        }
        if let Err(e) = writer.write(item) {
            warn!(path, "recording failed: {e}");
            // Dropping the receiver tells the frame loop at its next send.
            return Err(WriteError::Write { path, error: e });
        }
    }
    let mut written = writer.written;
    if let Err(cause) = finish(writer) {
        return Err(WriteError::Close { path, cause });
    }
    written.bytes = std::fs::metadata(&path).map(|m| m.len()).unwrap_or(0);
    info!(
        path,
        frames = written.frames,
        bytes = written.bytes,
        "recording closed"
    );
    Ok(written)
}

/// Writes the summary and footer, flushes and syncs the file: a recording
/// that could not be closed is an error, not a silent loss.
fn finish(mut writer: Writer) -> Result<(), CloseCause> {
    writer.mcap.finish().map_err(CloseCause::Mcap)?;
    let mut file = writer.mcap.into_inner();
    file.flush().map_err(CloseCause::Io)?;
    file.into_inner()
        .map_err(|e| e.into_error())
        .and_then(|file| file.sync_all())
        .map_err(CloseCause::Io)
}

/// Why a recording's file could not be written to its end. The lower
/// error is in the message (spelled out as the recorder's status shows
/// it), and kept typed.
#[derive(Debug, thiserror::Error)]
pub enum WriteError {
    /// Writing a frame, an event or a capture failed.
    #[error("writing {path} failed: {}", describe(error))]
    Write {
        /// The file.
        path: String,
        /// What the MCAP writer said.
        error: mcap::McapError,
    },
    /// Making the file durable failed (what failed went to the frame
    /// loop that asked; this is its kind).
    #[error("syncing {path} failed: {}", std::io::Error::from(*kind))]
    Sync {
        /// The file.
        path: String,
        /// What kind of I/O error it was.
        kind: std::io::ErrorKind,
    },
    /// Finishing the file (summary, indexes, footer, sync) failed.
    #[error("closing {path} failed: {cause}")]
    Close {
        /// The file.
        path: String,
        /// Why.
        cause: CloseCause,
    },
    /// The writer thread panicked.
    #[error("the recorder thread panicked")]
    Panicked,
}

/// Why a recording's file could not be closed.
#[derive(Debug)]
pub enum CloseCause {
    /// The MCAP writer could not write the summary or the footer.
    Mcap(mcap::McapError),
    /// The file could not be flushed or synced.
    Io(std::io::Error),
}

impl std::fmt::Display for CloseCause {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Mcap(e) => f.write_str(&describe(e)),
            Self::Io(e) => e.fmt(f),
        }
    }
}

impl Writer {
    /// Ends the chunk being gathered and makes the file durable.
    fn sync(&mut self) -> McapResult<()> {
        self.mcap.flush()?;
        self.file.sync_data().map_err(mcap::McapError::Io)
    }

    fn message(
        &mut self,
        channel_id: u16,
        sequence: u64,
        log_ns: u64,
        publish_ns: u64,
        data: &[u8],
    ) -> McapResult<()> {
        self.mcap.write_to_known_channel(
            &MessageHeader {
                channel_id,
                sequence: sequence as u32,
                log_time: log_ns,
                publish_time: publish_ns,
            },
            data,
        )
    }

    fn write(&mut self, item: Item) -> McapResult<()> {
        match item {
            Item::Frame {
                log_ns,
                header,
                actors,
                shapes,
            } => self.write_frame(log_ns, &header, &actors, &shapes)?,
            Item::Command { log_ns, command } => {
                self.message(
                    self.commands,
                    command.frame,
                    log_ns,
                    log_ns,
                    bytemuck::bytes_of(&command),
                )?;
            }
            Item::Event { log_ns, event } => {
                let json = serde_json::to_vec(&event).unwrap_or_default();
                self.message(self.events, 0, log_ns, log_ns, &json)?;
            }
            Item::Collision { log_ns, collision } => {
                self.message(
                    self.collisions,
                    collision.frame,
                    log_ns,
                    collision.elapsed_ns,
                    bytemuck::bytes_of(&collision),
                )?;
            }
            Item::Sensor { log_ns, sensor } => {
                self.message(
                    self.sensors,
                    sensor.frame,
                    log_ns,
                    log_ns,
                    bytemuck::bytes_of(&sensor),
                )?;
            }
            Item::Capture {
                log_ns,
                header,
                data,
            } => self.write_capture(log_ns, &header, &data)?,
            Item::Keyframe {
                log_ns,
                frame,
                data,
            } => {
                self.message(self.keyframes, frame, log_ns, log_ns, &data)?;
            }
            Item::Sync { .. } => self.sync()?,
            Item::Batch(items) => {
                for item in items {
                    self.write(item)?;
                }
            }
        }
        Ok(())
    }

    /// A frame, on the frames channel (its header and actors as on the
    /// wire) and on the scene channel (for Foxglove).
    fn write_frame(
        &mut self,
        log_ns: u64,
        header: &FrameHeader,
        actors: &[ActorState],
        shapes: &[shared_types::DebugShape],
    ) -> McapResult<()> {
        let mut bytes = std::mem::take(&mut self.scratch);
        bytes.clear();
        bytes.extend_from_slice(bytemuck::bytes_of(header));
        bytes.extend_from_slice(bytemuck::cast_slice(actors));
        let t = &header.timestamp;
        self.message(self.frames, t.frame, log_ns, t.elapsed_ns, &bytes)?;
        self.scratch = bytes;
        self.written.frames += 1;
        if !self.scene_updates {
            return Ok(());
        }
        let mut scene = std::mem::take(&mut self.scratch);
        scene.clear();
        scene_update(&mut scene, header, (actors, shapes), log_ns);
        self.message(self.scene, t.frame, log_ns, t.elapsed_ns, &scene)?;
        self.scratch = scene;
        Ok(())
    }

    /// A capture, on its sensor's channel (added with the sensor's first).
    fn write_capture(&mut self, log_ns: u64, header: &SensorHeader, data: &[u8]) -> McapResult<()> {
        let channel = match self.captures.get(&header.sensor_id) {
            Some(id) => *id,
            None => {
                let topic = format!("{SENSOR_TOPIC_PREFIX}{}", header.sensor_id);
                let id = self.mcap.add_channel(
                    self.capture_schema,
                    &topic,
                    WIRE_ENCODING,
                    &Default::default(),
                )?;
                self.captures.insert(header.sensor_id, id);
                id
            }
        };
        let mut bytes = std::mem::take(&mut self.scratch);
        bytes.clear();
        bytes.extend_from_slice(bytemuck::bytes_of(header));
        bytes.extend_from_slice(data);
        self.message(channel, header.frame, log_ns, header.elapsed_ns, &bytes)?;
        self.scratch = bytes;
        Ok(())
    }
}

#[cfg(test)]
#[path = "header_roundtrip.rs"]
mod header_roundtrip;

#[cfg(test)]
#[path = "sync_errors.rs"]
mod sync_errors;
