//! The recorder domain: records every frame, applied command, event,
//! collision, keyframe and (on request) sensor capture into an MCAP file.
//!
//! The frame loop only hands copies to a writer thread over a bounded
//! channel; the thread compresses and writes. (A keyframe is serialized on
//! the frame loop: the world has to be copied while it stands still.) Nothing is ever dropped: when
//! the disk cannot keep up and the channel is full, the frame loop waits
//! (and says so in the log). The file is finished (summary, footer) on
//! `stop`, when the server stops, and on a load of another scene; a
//! killed server leaves every complete chunk readable.

mod create;
mod refusal;
mod scene_update;
mod service;
mod writer;

pub use create::{CreateCause, StartError};
pub use writer::{CloseCause, WriteError};

pub(crate) use refusal::Refused;
pub(crate) use service::{RecorderCall, RecorderPort};

use std::fmt::Display;
use std::sync::mpsc::{sync_channel, Receiver, SyncSender, TrySendError};
use std::thread::JoinHandle;

use shared_types::{Command, CommandResult, FrameHeader, SensorHeader, NANOS_PER_SECOND};
use simbus_recording::{RecordedCollision, RecordedCommand, RecordedEvent, RecordingHeader};
use tracing::{info, warn};

use crate::keyframe::Keyframe;
use crate::sensors::SensorNote;
use crate::world::World;
use writer::{Item, Written};

/// The answer to a [`Recorder::request_sync`].
pub(crate) type Synced = Receiver<Result<(), WriteError>>;

/// Why what was recorded could not be made durable.
#[derive(Debug, thiserror::Error)]
pub enum SyncError {
    /// No recording runs.
    #[error("nothing is being recorded")]
    NotRecording,
    /// The writer could not write or sync the file.
    #[error(transparent)]
    Write(#[from] WriteError),
    /// The writer thread ended before it answered.
    #[error("the recorder's writer stopped")]
    WriterStopped,
}

/// Items in flight to the writer before the frame loop waits for it.
const QUEUE: usize = 256;
/// A journal's items gathered before they are handed over without a sync.
const BATCH: usize = 256;

/// The running recording.
#[derive(Debug)]
struct Active {
    items: SyncSender<Item>,
    thread: JoinHandle<Result<Written, WriteError>>,
    path: String,
    sensors: bool,
    frames: u64,
    /// Recording time of the last frame (never goes back).
    log_ns: u64,
    keyframe_every_ns: u64,
    next_keyframe_ns: u64,
    /// Times the frame loop waited for the disk.
    stalls: u64,
    /// The settings of the last recorded frame.
    settings: Option<shared_types::WireSettings>,
    /// The id of the last recorded frame.
    last_frame: u64,
}

/// What the last recording wrote.
#[derive(Debug, Clone, Default)]
pub(crate) struct LastRecording {
    pub(crate) path: String,
    pub(crate) frames: u64,
    /// The file's size: once closed, or as the error left it.
    pub(crate) bytes: u64,
    /// Why it stopped by itself, if it did.
    pub(crate) error: Option<String>,
    /// The last frame it recorded, when it stopped by itself.
    pub(crate) stopped_at: Option<u64>,
}

impl LastRecording {
    /// What a client is told about a recording that stopped by itself:
    /// where, why, and what the file holds.
    pub(crate) fn failure(&self) -> Option<String> {
        let error = self.error.as_ref()?;
        let at = self
            .stopped_at
            .map_or(String::new(), |frame| format!(" at frame {frame}"));
        Some(format!(
            "the recording to {} stopped by itself{at}: {error}; the file holds {} bytes, \
             readable up to its last complete chunk (`sim-client recorder info` says up to \
             which frame)",
            self.path, self.bytes
        ))
    }
}

/// The recorder's state. Dropped with a recording running (the server
/// failed), it closes the file first.
#[derive(Debug, Default)]
pub(crate) struct Recorder {
    active: Option<Active>,
    pub(crate) last: LastRecording,
    collisions: Vec<RecordedCollision>,
    captures: Vec<(SensorHeader, Vec<u8>)>,
    /// The debug shapes the next frame shows.
    shapes: Vec<shared_types::DebugShape>,
    /// The header of the last frame published: a recording starts with
    /// that frame as it was sent (its substeps, flags and time).
    published: Option<FrameHeader>,
    /// This recorder writes a journal: no Foxglove scene, uncompressed
    /// chunks, items handed over in batches.
    pub(crate) journal: bool,
    /// A journal's items not handed over yet.
    batch: Vec<Item>,
    /// Why the last recording's writer failed, until a sync that found it
    /// stopped takes it.
    failed: Option<WriteError>,
}

impl Drop for Recorder {
    fn drop(&mut self) {
        self.stop("server error", 0);
    }
}

impl Recorder {
    /// Whether a recording runs.
    pub(crate) fn is_recording(&self) -> bool {
        self.active.is_some()
    }

    /// Notes the header of a frame just published (a copy, no allocation).
    pub(crate) fn published(&mut self, header: &FrameHeader) {
        self.published = Some(*header);
    }

    /// The header of the last frame published, if it is `frame` of
    /// `episode`.
    pub(crate) fn last_published(&self, frame: u64, episode: u64) -> Option<FrameHeader> {
        self.published
            .filter(|h| h.timestamp.frame == frame && h.episode == episode)
    }

    /// The running recording's path and frames so far.
    pub(crate) fn progress(&self) -> Option<(&str, u64)> {
        self.active.as_ref().map(|a| (a.path.as_str(), a.frames))
    }

    /// Starts recording to `path`: writes the header, the current frame and
    /// a keyframe. The file is created here, so a path the server cannot
    /// write is refused at once.
    pub(crate) fn start(
        &mut self,
        path: &str,
        header: RecordingHeader,
        sensors: Vec<SensorNote>,
        frame: (&FrameHeader, &World),
        scene: String,
    ) -> Result<(), StartError> {
        let handle = writer::create(path, &header, self.journal)?;
        let (items, receiver) = sync_channel(QUEUE);
        let thread_path = path.to_string();
        let thread = std::thread::Builder::new()
            .name("simbus-recorder".into())
            .spawn(move || writer::run(handle, receiver, thread_path))
            .map_err(StartError::Thread)?;
        let every = (header.keyframe_seconds * NANOS_PER_SECOND as f64) as u64;
        self.active = Some(Active {
            items,
            thread,
            path: path.to_string(),
            sensors: header.sensors,
            frames: 0,
            log_ns: 0,
            keyframe_every_ns: every.max(1),
            next_keyframe_ns: 0,
            stalls: 0,
            settings: None,
            last_frame: frame.0.timestamp.frame,
        });
        info!(
            path,
            sensors = header.sensors,
            frame = frame.0.timestamp.frame,
            "recording started"
        );
        self.collisions.clear();
        self.captures.clear();
        self.failed = None;
        self.sensor_notes(sensors);
        self.record_frame(frame.0, frame.1, &scene, true);
        Ok(())
    }

    /// Stops the recording (if one runs), finishing the file; `reason` and
    /// `frame` go into its last event.
    pub(crate) fn stop(&mut self, reason: &str, frame: u64) -> Option<&LastRecording> {
        if !self.batch.is_empty() {
            let batch = std::mem::take(&mut self.batch);
            self.hand_over(Item::Batch(batch));
        }
        let active = self.active.take()?;
        let log_ns = active.log_ns;
        let _ = active.items.send(Item::Event {
            log_ns,
            event: RecordedEvent::Stopped {
                frame,
                reason: reason.to_string(),
            },
        });
        drop(active.items);
        let result = active
            .thread
            .join()
            .unwrap_or_else(|_| Err(WriteError::Panicked));
        self.last = match result {
            Ok(written) => LastRecording {
                path: active.path,
                frames: written.frames,
                bytes: written.bytes,
                error: None,
                stopped_at: None,
            },
            Err(error) => {
                // What is on disk: every complete chunk reads.
                let bytes = std::fs::metadata(&active.path).map_or(0, |m| m.len());
                let text = error.to_string();
                self.failed = Some(error);
                LastRecording {
                    error: Some(text),
                    stopped_at: Some(active.last_frame),
                    path: active.path,
                    frames: active.frames,
                    bytes,
                }
            }
        };
        info!(
            path = self.last.path,
            frames = self.last.frames,
            bytes = self.last.bytes,
            stalls = active.stalls,
            reason,
            "recording stopped"
        );
        Some(&self.last)
    }

    /// Hands `item` to the writer; waits when its queue is full (never drops).
    fn send(&mut self, item: Item) {
        if self.journal && !matches!(item, Item::Sync { .. }) {
            // A journal hands its items over in batches, at each sync (or
            // every BATCH items): one wake-up of the writer per batch, not
            // several per frame on a machine whose CPUs the ticker and the
            // server already keep busy.
            self.batch.push(item);
            if self.batch.len() < BATCH {
                return;
            }
            let batch = std::mem::take(&mut self.batch);
            return self.hand_over(Item::Batch(batch));
        }
        if self.journal && !self.batch.is_empty() {
            let batch = std::mem::take(&mut self.batch);
            self.hand_over(Item::Batch(batch));
        }
        self.hand_over(item);
    }

    /// Hands `item` to the writer; waits when its queue is full (never drops).
    fn hand_over(&mut self, item: Item) {
        let Some(active) = &mut self.active else {
            return;
        };
        let item = match active.items.try_send(item) {
            Ok(()) => return,
            Err(TrySendError::Full(item)) => item,
            Err(TrySendError::Disconnected(_)) => {
                warn!(
                    path = active.path,
                    "the recorder's writer stopped; recording ends"
                );
                self.stop("writer failed", 0);
                return;
            }
        };
        active.stalls += 1;
        if active.stalls.is_power_of_two() {
            warn!(
                path = active.path,
                stalls = active.stalls,
                "the disk cannot keep up with the recording: the frame loop waits for it (no frame is dropped)"
            );
        }
        if active.items.send(item).is_err() {
            warn!(
                path = active.path,
                "the recorder's writer stopped; recording ends"
            );
            self.stop("writer failed", 0);
        }
    }

    /// Makes everything recorded so far durable, waiting for the disk (the
    /// writer ends its chunk, flushes and syncs the file). A failure ends
    /// the recording, and says why.
    pub(crate) fn sync(&mut self) -> Result<(), SyncError> {
        let synced = self.request_sync()?;
        self.synced(&synced)
    }

    /// Asks the writer to make everything recorded so far durable, without
    /// waiting: [`Recorder::synced`] waits for the answer.
    pub(crate) fn request_sync(&mut self) -> Result<Synced, SyncError> {
        if self.active.is_none() {
            return Err(SyncError::NotRecording);
        }
        let (done, synced) = sync_channel(1);
        self.send(Item::Sync { done });
        Ok(synced)
    }

    /// Waits for the answer to a [`Recorder::request_sync`].
    pub(crate) fn synced(&mut self, synced: &Synced) -> Result<(), SyncError> {
        let failed = match synced.recv() {
            Ok(Ok(())) => return Ok(()),
            Ok(Err(error)) => Some(SyncError::Write(error)),
            Err(_) => None,
        };
        self.stop("sync failed", 0);
        // A writer that stopped without answering failed before: its error.
        let failed = failed.or_else(|| self.failed.take().map(SyncError::Write));
        Err(failed.unwrap_or(SyncError::WriterStopped))
    }

    /// Makes the next recorded frame carry a keyframe.
    pub(crate) fn keyframe_next(&mut self) {
        if let Some(active) = &mut self.active {
            active.next_keyframe_ns = 0;
        }
    }

    /// Where the world's step puts the contacts that start (only while recording).
    pub(crate) fn collisions(&mut self) -> Option<&mut Vec<RecordedCollision>> {
        self.active.as_ref()?;
        Some(&mut self.collisions)
    }

    /// Where the sensors put copies of their captures (only while
    /// recording with sensors).
    pub(crate) fn captures(&mut self) -> Option<&mut Vec<(SensorHeader, Vec<u8>)>> {
        self.active.as_ref().filter(|a| a.sensors)?;
        Some(&mut self.captures)
    }

    /// Records a published frame, the collisions and captures of its step,
    /// and a keyframe when one is due.
    /// `scene` is named in a keyframe only (formatted when one is due).
    /// The debug shapes the next recorded frame shows (its scene draws
    /// them).
    pub(crate) fn draw(&mut self, shapes: &[shared_types::DebugShape]) {
        self.shapes.clear();
        self.shapes.extend_from_slice(shapes);
    }

    pub(crate) fn frame(&mut self, header: &FrameHeader, world: &World, scene: &dyn Display) {
        if self.active.is_some() {
            self.record_frame(header, world, scene, false);
        }
    }

    fn record_frame(
        &mut self,
        header: &FrameHeader,
        world: &World,
        scene: &dyn Display,
        first: bool,
    ) {
        let Some(active) = &mut self.active else {
            return;
        };
        if !first {
            active.log_ns = active.log_ns.saturating_add(header.timestamp.delta_ns);
        }
        active.frames += 1;
        active.last_frame = header.timestamp.frame;
        let log_ns = active.log_ns;
        let settings_changed = active.settings.is_some_and(|s| s != header.settings);
        active.settings = Some(header.settings);
        if settings_changed {
            self.send(Item::Event {
                log_ns,
                event: RecordedEvent::Settings {
                    frame: header.timestamp.frame,
                    settings: header.settings.into(),
                },
            });
        }
        let Some(active) = &mut self.active else {
            return;
        };
        let keyframe_due = log_ns >= active.next_keyframe_ns;
        if keyframe_due {
            active.next_keyframe_ns = log_ns.saturating_add(active.keyframe_every_ns);
        }
        let actors = world.states();
        let shapes = self.shapes.clone();
        self.send(Item::Frame {
            log_ns,
            header: *header,
            actors,
            shapes,
        });
        for mut collision in std::mem::take(&mut self.collisions) {
            collision.frame = header.timestamp.frame;
            collision.elapsed_ns = header.timestamp.elapsed_ns;
            self.send(Item::Collision { log_ns, collision });
        }
        for (header, data) in std::mem::take(&mut self.captures) {
            self.send(Item::Capture {
                log_ns,
                header,
                data,
            });
        }
        if keyframe_due {
            let data = Keyframe::of(world, header, scene.to_string()).encode();
            self.send(Item::Keyframe {
                log_ns,
                frame: header.timestamp.frame,
                data,
            });
        }
    }

    /// Records a command applied before `frame` of `episode`.
    pub(crate) fn command(
        &mut self,
        frame: u64,
        episode: u64,
        command: &Command,
        result: &CommandResult,
    ) {
        let Some(active) = &self.active else {
            return;
        };
        let log_ns = active.log_ns;
        self.send(Item::Command {
            log_ns,
            command: RecordedCommand {
                frame,
                episode,
                command: *command,
                result: *result,
            },
        });
    }

    /// Records an event.
    pub(crate) fn event(&mut self, event: RecordedEvent) {
        let Some(active) = &self.active else {
            return;
        };
        let log_ns = active.log_ns;
        self.send(Item::Event { log_ns, event });
    }

    /// Records what the sensors domain noted.
    pub(crate) fn sensor_notes(&mut self, notes: impl IntoIterator<Item = SensorNote>) {
        for note in notes {
            let Some(active) = &self.active else {
                continue;
            };
            let log_ns = active.log_ns;
            match note {
                SensorNote::Spawned(sensor) => self.send(Item::Sensor { log_ns, sensor }),
                SensorNote::Ended { frame, id } => self.send(Item::Event {
                    log_ns,
                    event: RecordedEvent::SensorEnded { frame, id },
                }),
            }
        }
    }
}
