//! Reading a recording: one pass through the file in the order it was
//! written, each message checked against its schema and bounds before use.

use std::collections::HashMap;
use std::fs::File;
use std::io::{BufReader, Read, Seek};
use std::sync::Arc;

use mcap::sans_io::linear_reader::LinearReaderOptions;

use bytemuck::Pod;
use shared_types::WorldSettings;

use crate::format::*;
use shared_types::{ActorState, FrameHeader, SensorHeader};

/// The longest record the reader accepts (a chunk, decompressed): bounds
/// what a damaged length field can make it allocate.
const RECORD_LENGTH_LIMIT: usize = 1 << 30;

/// One message of a recording, decoded.
#[derive(Debug, Clone, PartialEq)]
pub enum Entry {
    /// A frame as published.
    Frame {
        /// The recording time (see the module docs), nanoseconds.
        log_ns: u64,
        /// The frame header.
        header: FrameHeader,
        /// Every actor.
        actors: Vec<ActorState>,
    },
    /// An applied command.
    Command(RecordedCommand),
    /// An event.
    Event(RecordedEvent),
    /// A collision.
    Collision(RecordedCollision),
    /// A sensor's spawn.
    Sensor(RecordedSensor),
    /// A sensor capture.
    Capture {
        /// Its header.
        header: SensorHeader,
        /// Its payload bytes.
        data: Vec<u8>,
    },
    /// A keyframe: the server's serialized world after the frame before it.
    Keyframe {
        /// The serialized state.
        data: Vec<u8>,
    },
}

/// Which channel a message came from, as this build knows them.
#[derive(Debug, Clone, Copy, PartialEq)]
enum Channel {
    Header,
    Frames,
    /// Frames of [`super::LEGACY_FRAME_SCHEMA`]: a shorter header.
    LegacyFrames,
    Commands,
    Events,
    Collisions,
    Sensors,
    /// Sensors of [`super::LEGACY_SENSOR_SPAWN_SCHEMA`]: fewer parameters.
    LegacySensors,
    Capture,
    Keyframes,
    Skipped,
}

/// Reads a recording message by message.
pub struct RecordingReader {
    path: String,
    messages: mcap::io::MessageReader<BufReader<File>>,
    channels: HashMap<u16, Channel>,
    header: RecordingHeader,
    /// Set when the file ended in the middle of a chunk (a server that was
    /// killed): every complete chunk before it was read.
    truncated: bool,
    /// The recording time of the last frame read (frames never go back).
    last_log_ns: u64,
    /// The file ends with MCAP's closing magic (it was finished).
    closed: bool,
    bytes: u64,
}

impl RecordingHeader {
    /// The header of a recording not yet read: every number zero, every
    /// name empty, the default settings.
    pub(crate) fn unread() -> Self {
        Self {
            recording_version: 0,
            simbus_version: String::new(),
            protocol_version: 0,
            world: String::new(),
            scene: String::new(),
            seed: 0,
            settings: WorldSettings::default().into(),
            start_frame: 0,
            start_elapsed_ns: 0,
            episode: 0,
            start_platform_timestamp: 0.0,
            sensors: false,
            keyframe_seconds: 0.0,
            journal_sync_frames: 0,
            run_pid: 0,
        }
    }
}

impl std::fmt::Debug for RecordingReader {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RecordingReader")
            .field("path", &self.path)
            .field("header", &self.header)
            .field("truncated", &self.truncated)
            .finish()
    }
}

impl RecordingReader {
    /// Opens `path` and reads its header.
    ///
    /// # Errors
    ///
    /// Returns [`RecordingError::Io`] if `path` cannot be read,
    /// [`RecordingError::Directory`] if it is a directory,
    /// [`RecordingError::NotMcap`] if it does not begin with MCAP's magic
    /// (empty, text, other bytes), [`RecordingError::Truncated`] if it ends
    /// before its first complete chunk (still being recorded, or never closed),
    /// [`RecordingError::Corrupt`] if its first chunk is damaged,
    /// [`RecordingError::NotSimbus`] if its first message is not a simbus
    /// header, [`RecordingError::Malformed`] if that header does not read, and
    /// [`RecordingError::FutureSchema`] if it was written by a newer simbus (a
    /// recording version or a header schema this build does not read).
    pub fn open(path: &str) -> Result<Self, RecordingError> {
        let io = |error| RecordingError::Io {
            path: path.to_string(),
            error,
        };
        let metadata = std::fs::metadata(path).map_err(io)?;
        if metadata.is_dir() {
            return Err(RecordingError::Directory {
                path: path.to_string(),
            });
        }
        let mut file = File::open(path).map_err(io)?;
        let mut head = Vec::with_capacity(HEAD_BYTES);
        (&mut file)
            .take(HEAD_BYTES as u64)
            .read_to_end(&mut head)
            .map_err(io)?;
        file.rewind().map_err(io)?;
        if let Some(found) = not_mcap(&head) {
            return Err(RecordingError::NotMcap {
                path: path.to_string(),
                found,
            });
        }
        let options = LinearReaderOptions::default()
            .with_prevalidate_chunk_crcs(true)
            .with_validate_data_section_crc(true)
            .with_record_length_limit(RECORD_LENGTH_LIMIT);
        let mut reader = Self {
            path: path.to_string(),
            messages: mcap::io::MessageReader::new_with_options(BufReader::new(file), options),
            channels: HashMap::new(),
            header: RecordingHeader::unread(),
            truncated: false,
            last_log_ns: 0,
            closed: ends_with_magic(path),
            bytes: metadata.len(),
        };
        let not_simbus = || RecordingError::NotSimbus {
            path: path.to_string(),
        };
        let first = match reader.messages.next() {
            Some(Ok(message)) => message,
            // Still being written (the chunk in progress has a placeholder
            // header), or never closed: nothing complete yet.
            Some(Err(mcap::McapError::UnexpectedEof | mcap::McapError::UnexpectedEoc))
                if !reader.closed =>
            {
                return Err(RecordingError::Truncated {
                    path: path.to_string(),
                })
            }
            Some(Err(e)) => return Err(reader.mcap_error(e)),
            None => return Err(not_simbus()),
        };
        if reader.channel_of(&first.channel)? != Channel::Header {
            return Err(not_simbus());
        }
        // The header channel is simbus's: a header it cannot read is a
        // damaged one, said as such (not "not a simbus recording").
        let header: RecordingHeader =
            serde_json::from_slice(&first.data).map_err(|e| RecordingError::Malformed {
                path: path.to_string(),
                topic: HEADER_TOPIC.to_string(),
                reason: e.to_string(),
            })?;
        if header.recording_version > RECORDING_VERSION {
            return Err(RecordingError::FutureSchema {
                path: path.to_string(),
                found: format!("recording version {}", header.recording_version),
                known: HEADER_SCHEMA,
            });
        }
        reader.header = header;
        Ok(reader)
    }

    /// The recording's header.
    pub fn header(&self) -> &RecordingHeader {
        &self.header
    }

    /// The file's size in bytes.
    pub fn bytes(&self) -> u64 {
        self.bytes
    }

    /// Whether the file ended in the middle of a chunk: it is still being
    /// recorded, or was not closed (its server was killed), and holds what
    /// was written up to then.
    pub fn truncated(&self) -> bool {
        self.truncated
    }

    fn mcap_error(&self, source: mcap::McapError) -> RecordingError {
        use mcap::McapError as E;
        let path = self.path.clone();
        match source {
            E::BadMagic => RecordingError::NotMcap {
                path,
                found: NotMcap::OtherBytes,
            },
            E::Io(error) => RecordingError::Io { path, error },
            error => RecordingError::Corrupt { path, error },
        }
    }

    fn channel_of(&mut self, channel: &Arc<mcap::Channel<'_>>) -> Result<Channel, RecordingError> {
        if let Some(known) = self.channels.get(&channel.id) {
            return Ok(*known);
        }
        let schema = channel.schema.as_ref().map_or("", |s| s.name.as_str());
        let kind = match check_schema(schema) {
            Ok(true) => match (channel.topic.as_str(), schema) {
                (HEADER_TOPIC, HEADER_SCHEMA) => Channel::Header,
                (FRAMES_TOPIC, FRAME_SCHEMA) => Channel::Frames,
                (FRAMES_TOPIC, LEGACY_FRAME_SCHEMA) => Channel::LegacyFrames,
                (COMMANDS_TOPIC, COMMAND_SCHEMA) => Channel::Commands,
                (EVENTS_TOPIC, EVENT_SCHEMA) => Channel::Events,
                (COLLISIONS_TOPIC, COLLISION_SCHEMA) => Channel::Collisions,
                (SENSORS_TOPIC, SENSOR_SPAWN_SCHEMA) => Channel::Sensors,
                (SENSORS_TOPIC, LEGACY_SENSOR_SPAWN_SCHEMA) => Channel::LegacySensors,
                (topic, CAPTURE_SCHEMA) if topic.starts_with(SENSOR_TOPIC_PREFIX) => {
                    Channel::Capture
                }
                (KEYFRAMES_TOPIC, KEYFRAME_SCHEMA | LEGACY_KEYFRAME_SCHEMA) => Channel::Keyframes,
                _ => Channel::Skipped,
            },
            Ok(false) => Channel::Skipped,
            Err(known) => {
                return Err(RecordingError::FutureSchema {
                    path: self.path.clone(),
                    found: schema.to_string(),
                    known,
                })
            }
        };
        self.channels.insert(channel.id, kind);
        Ok(kind)
    }

    /// The next message this build knows, decoded; `None` at the end (or
    /// at the end of the last complete chunk of a truncated file).
    #[allow(clippy::should_implement_trait)]
    pub fn next(&mut self) -> Option<Result<Entry, RecordingError>> {
        loop {
            let message = match self.messages.next()? {
                Ok(message) => message,
                // An unfinished file ends mid-chunk: what came before is good.
                Err(mcap::McapError::UnexpectedEof | mcap::McapError::UnexpectedEoc)
                    if !self.closed =>
                {
                    self.truncated = true;
                    return None;
                }
                Err(e) => return Some(Err(self.mcap_error(e))),
            };
            let channel = match self.channel_of(&message.channel) {
                Ok(channel) => channel,
                Err(e) => return Some(Err(e)),
            };
            match self.decode(channel, &message) {
                Ok(None) => {}
                Ok(Some(entry)) => return Some(Ok(entry)),
                Err(e) => return Some(Err(e)),
            }
        }
    }

    /// `message`'s entry (`None` for a message not read as one).
    fn decode(
        &mut self,
        channel: Channel,
        message: &mcap::Message<'_>,
    ) -> Result<Option<Entry>, RecordingError> {
        let data = &message.data[..];
        let malformed = |reason: &str| Err(self.malformed(message, reason));
        let entry = match channel {
            Channel::Skipped | Channel::Header => return Ok(None),
            Channel::Frames | Channel::LegacyFrames => self.decode_frame(channel, message)?,
            Channel::Commands => match exact_pod(data) {
                Some(command) => Entry::Command(command),
                None => return malformed("not one recorded command"),
            },
            Channel::Collisions => match exact_pod(data) {
                Some(collision) => Entry::Collision(collision),
                None => return malformed("not one recorded collision"),
            },
            Channel::Sensors => match exact_pod(data) {
                Some(sensor) => Entry::Sensor(sensor),
                None => return malformed("not one recorded sensor"),
            },
            Channel::LegacySensors => match padded_pod(data, LEGACY_SENSOR_SPAWN_BYTES) {
                Some(sensor) => Entry::Sensor(sensor),
                None => return malformed("not one recorded sensor of protocol 3"),
            },
            Channel::Events => match serde_json::from_slice(data) {
                Ok(event) => Entry::Event(event),
                Err(e) => return malformed(&e.to_string()),
            },
            Channel::Capture => {
                let Some((header, rest)) = split_pod::<SensorHeader>(data) else {
                    return malformed("shorter than a capture header");
                };
                Entry::Capture {
                    header,
                    data: rest.to_vec(),
                }
            }
            Channel::Keyframes => Entry::Keyframe {
                data: data.to_vec(),
            },
        };
        Ok(Some(entry))
    }

    /// A frame (of the current or the legacy layout), checked: its actors
    /// as many as it says and finite, its time not going back.
    fn decode_frame(
        &mut self,
        channel: Channel,
        message: &mcap::Message<'_>,
    ) -> Result<Entry, RecordingError> {
        let data = &message.data[..];
        let split = if channel == Channel::Frames {
            split_pod::<FrameHeader>(data)
        } else {
            split_legacy_header(data)
        };
        let Some((header, rest)) = split else {
            return Err(self.malformed(message, "shorter than a frame header"));
        };
        let actors: Option<Vec<ActorState>> = pods(rest);
        let Some(actors) = actors.filter(|a| a.len() == header.actor_count as usize) else {
            return Err(self.malformed(message, "actor count does not match the bytes"));
        };
        if message.log_time < self.last_log_ns {
            return Err(self.malformed(message, "a frame's time goes back"));
        }
        if !actors.iter().all(finite) {
            return Err(self.malformed(message, "an actor's state is not finite"));
        }
        self.last_log_ns = message.log_time;
        Ok(Entry::Frame {
            log_ns: message.log_time,
            header,
            actors,
        })
    }

    /// A message that is not what its channel holds.
    fn malformed(&self, message: &mcap::Message<'_>, reason: &str) -> RecordingError {
        RecordingError::Malformed {
            path: self.path.clone(),
            topic: message.channel.topic.clone(),
            reason: reason.to_string(),
        }
    }
}

/// Bytes from a file's start that [`not_mcap`] looks at.
const HEAD_BYTES: usize = 512;

/// What a file starting with `head` holds, if it is not MCAP: empty, text
/// or other bytes. A file that begins with MCAP's magic (or a piece of it:
/// one still being created) is MCAP as far as its first bytes go.
pub(super) fn not_mcap(head: &[u8]) -> Option<NotMcap> {
    if head.is_empty() {
        return Some(NotMcap::Empty);
    }
    let magic = &mcap::MAGIC[..head.len().min(mcap::MAGIC.len())];
    if head.starts_with(magic) {
        return None;
    }
    let text = match std::str::from_utf8(head) {
        Ok(text) => text,
        // Cut in the middle of a character by `HEAD_BYTES`.
        Err(e) if e.error_len().is_none() => {
            std::str::from_utf8(&head[..e.valid_up_to()]).unwrap_or_default()
        }
        Err(_) => "",
    };
    let printable = |c: char| !c.is_control() || c.is_whitespace();
    Some(if !text.is_empty() && text.chars().all(printable) {
        NotMcap::Text
    } else {
        NotMcap::OtherBytes
    })
}

/// Whether the file at `path` ends with MCAP's magic, as a finished file does.
fn ends_with_magic(path: &str) -> bool {
    use std::io::SeekFrom;
    let mut tail = [0u8; 8];
    File::open(path)
        .and_then(|mut f| {
            f.seek(SeekFrom::End(-8))?;
            f.read_exact(&mut tail)
        })
        .is_ok()
        && tail == *mcap::MAGIC
}

/// Whether every number of an actor's state is finite.
fn finite(actor: &ActorState) -> bool {
    let vectors = [
        &actor.position[..],
        &actor.rotation[..],
        &actor.linear_velocity[..],
        &actor.angular_velocity[..],
        &actor.acceleration[..],
        &actor.extent[..],
    ];
    vectors.iter().all(|v| v.iter().all(|x| x.is_finite()))
}

/// A `T` read from the front of `data`, and the rest.
fn split_pod<T: Pod>(data: &[u8]) -> Option<(T, &[u8])> {
    let size = std::mem::size_of::<T>();
    let head = data.get(..size)?;
    Some((bytemuck::pod_read_unaligned(head), &data[size..]))
}

/// A [`super::LEGACY_FRAME_SCHEMA`] header at the start of `data`, its
/// later fields zero, and the rest.
fn split_legacy_header(data: &[u8]) -> Option<(FrameHeader, &[u8])> {
    let head = data.get(..LEGACY_FRAME_HEADER_BYTES)?;
    let mut bytes = [0u8; std::mem::size_of::<FrameHeader>()];
    bytes[..LEGACY_FRAME_HEADER_BYTES].copy_from_slice(head);
    Some((
        bytemuck::pod_read_unaligned(&bytes),
        &data[LEGACY_FRAME_HEADER_BYTES..],
    ))
}

/// `data`, exactly `len` bytes, as a `T` whose later bytes are zero (an
/// older, shorter layout of it).
fn padded_pod<T: Pod>(data: &[u8], len: usize) -> Option<T> {
    if data.len() != len || len > std::mem::size_of::<T>() {
        return None;
    }
    let mut value = T::zeroed();
    bytemuck::bytes_of_mut(&mut value)[..len].copy_from_slice(data);
    Some(value)
}

/// `data` as exactly one `T`.
fn exact_pod<T: Pod>(data: &[u8]) -> Option<T> {
    (data.len() == std::mem::size_of::<T>()).then(|| bytemuck::pod_read_unaligned(data))
}

/// `data` as a whole number of `T`s.
fn pods<T: Pod>(data: &[u8]) -> Option<Vec<T>> {
    let size = std::mem::size_of::<T>();
    if !data.len().is_multiple_of(size) {
        return None;
    }
    Some(
        data.chunks_exact(size)
            .map(bytemuck::pod_read_unaligned)
            .collect(),
    )
}

#[cfg(test)]
mod tests;
