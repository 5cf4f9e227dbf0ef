//! The journal: the recorder's format, written continuously into a
//! directory of segments with a stated durability, so that a killed
//! server can be resumed ([`resume`]) from its last keyframe and the
//! commands after it.
//!
//! Each server run writes one segment, `journal-NNNNNN.mcap`: its header,
//! the frame it starts from, a keyframe, then every frame, applied
//! command, episode, settings change and sensor, and a keyframe every
//! `--keyframe-seconds`. A segment is complete from its first keyframe
//! on, so a resume reads only the newest one it can use.
//!
//! Durability: every `frames:N` frames the frame loop hands the writer a
//! sync (end the chunk, flush, `fdatasync`) and waits for it, before the
//! frame's tick is answered. With N = 1 no ticker is ever told of a frame
//! that a crash can take back; with N > 1 at most N frames are lost.

pub(crate) mod resume;

use std::path::{Path, PathBuf};

use shared_types::{FrameHeader, WorldSettings};
use simbus_recording::RecordingHeader;
use tracing::{info, warn};

use crate::config::JournalOptions;
use crate::recorder::{Recorder, SyncError, Synced};
use crate::sensors::SensorNote;
use crate::world::World;

/// The name of segment `index` in `dir`.
pub(crate) fn segment_path(dir: &Path, index: u32) -> PathBuf {
    dir.join(format!("journal-{index:06}.mcap"))
}

/// The segments (`journal-NNNNNN.mcap`) in `dir`, oldest first.
///
/// # Errors
///
/// Returns the [`std::io::Error`] of reading `dir` (it does not exist, is not a
/// directory, or may not be read) or one of its entries. Files that are not
/// named `journal-NNNNNN.mcap` are skipped, not errors.
pub fn segments(dir: &Path) -> std::io::Result<Vec<(u32, PathBuf)>> {
    let mut found = Vec::new();
    for entry in std::fs::read_dir(dir)? {
        let entry = entry?;
        let name = entry.file_name();
        let Some(index) = name
            .to_str()
            .and_then(|n| n.strip_prefix("journal-"))
            .and_then(|n| n.strip_suffix(".mcap"))
            .and_then(|n| n.parse::<u32>().ok())
        else {
            continue;
        };
        found.push((index, entry.path()));
    }
    found.sort();
    Ok(found)
}

/// Why a journal could not be started.
#[derive(Debug, thiserror::Error)]
pub enum JournalError {
    /// The directory could not be made or read.
    #[error("cannot use the journal directory {dir}")]
    Directory {
        /// The directory.
        dir: PathBuf,
        /// What the file system said.
        source: std::io::Error,
    },
    /// A fresh journal was asked for where one already is.
    #[error("{dir} already holds a journal ({segments} segment(s)): resume it with --resume {dir}, or journal into an empty directory")]
    NotEmpty {
        /// The directory.
        dir: PathBuf,
        /// Its segments.
        segments: usize,
    },
    /// The segment could not be created.
    #[error("cannot start the journal: {0}")]
    Start(#[from] crate::recorder::StartError),
    /// The segment's first frame could not be made durable.
    #[error("cannot start the journal: {0}")]
    Sync(#[from] SyncError),
}

/// The journal being written.
#[derive(Debug)]
pub(crate) struct Journal {
    recorder: Recorder,
    options: JournalOptions,
    segment: PathBuf,
    /// Frames recorded since the last sync was asked for.
    unsynced: u64,
    /// The sync asked for and not waited for yet, and the frame it covers.
    in_flight: Option<(Synced, (u64, u64))>,
    /// The last frame made durable: (episode, frame).
    pub(crate) durable: Option<(u64, u64)>,
    /// Why the journal stopped, if it did (the world runs on).
    pub(crate) stopped: Option<String>,
}

impl Journal {
    /// Opens the next segment of `options.dir` (`fresh`: the directory
    /// must hold none yet) and records `frame` of `world` and the living
    /// `sensors` into it, with a keyframe, durably.
    pub(crate) fn start(
        options: &JournalOptions,
        fresh: bool,
        header: RecordingHeader,
        sensors: Vec<SensorNote>,
        frame: (&FrameHeader, &World),
        scene: String,
    ) -> Result<Self, JournalError> {
        let dir = &options.dir;
        let directory = |source| JournalError::Directory {
            dir: dir.clone(),
            source,
        };
        std::fs::create_dir_all(dir).map_err(directory)?;
        let existing = segments(dir).map_err(directory)?;
        if fresh && !existing.is_empty() {
            return Err(JournalError::NotEmpty {
                dir: dir.clone(),
                segments: existing.len(),
            });
        }
        let index = existing.last().map_or(1, |(i, _)| i + 1);
        let mut header = header;
        header.journal_sync_frames = options.sync.every(&header.settings.into());
        let segment = segment_path(dir, index);
        let mut recorder = Recorder::default();
        recorder.journal = true;
        let path = segment.to_string_lossy().into_owned();
        let started = recorder
            .start(&path, header, sensors, frame, scene)
            .map_err(JournalError::from)
            .and_then(|()| recorder.sync().map_err(JournalError::from));
        if let Err(e) = started {
            // No segment is left behind that holds nothing a resume can
            // use (a full disk would leave an empty one).
            drop(recorder);
            if let Err(removed) = std::fs::remove_file(&segment) {
                if removed.kind() != std::io::ErrorKind::NotFound {
                    warn!(segment = %segment.display(), "cannot remove the unusable segment: {removed}");
                }
            }
            return Err(e);
        }
        // The directory entry of the new segment is durable too.
        if let Ok(d) = std::fs::File::open(dir) {
            let _ = d.sync_all();
        }
        info!(segment = %segment.display(), sync = %options.sync, "journal started");
        Ok(Self {
            recorder,
            options: options.clone(),
            segment,
            unsynced: 0,
            in_flight: None,
            durable: Some((frame.0.episode, frame.0.timestamp.frame)),
            stopped: None,
        })
    }

    /// The journal's directory.
    pub(crate) fn dir(&self) -> &Path {
        &self.options.dir
    }

    /// The recorder writing the segment (frames, commands, events, sensors).
    pub(crate) fn recorder(&mut self) -> &mut Recorder {
        &mut self.recorder
    }

    /// Records a published frame and, when the policy says so, waits until
    /// it (and everything before it) is on disk.
    pub(crate) fn frame(
        &mut self,
        header: &FrameHeader,
        world: &World,
        scene: &dyn std::fmt::Display,
        settings: &WorldSettings,
    ) {
        if self.stopped.is_some() {
            return;
        }
        self.recorder.frame(header, world, scene);
        if !self.recorder.is_recording() {
            let reason = self.recorder.last.error.clone();
            self.stop(reason.unwrap_or_else(|| SyncError::WriterStopped.to_string()));
            return;
        }
        self.unsynced += 1;
        let every = self.options.sync.every(settings);
        let at = (header.episode, header.timestamp.frame);
        if every == 1 {
            // The frame is durable before its tick is answered.
            self.unsynced = 0;
            match self.recorder.sync() {
                Ok(()) => self.durable = Some(at),
                Err(reason) => self.stop(crate::error::message(&reason)),
            }
            return;
        }
        // Every half period: wait for the sync asked for half a period ago
        // (done by now unless the disk is slower than the world), then ask
        // for the next, so the frame loop never waits for the writer's
        // backlog and at most `every` frames are not yet durable.
        if self.unsynced < every.div_ceil(2) {
            return;
        }
        self.unsynced = 0;
        if let Some((synced, covers)) = self.in_flight.take() {
            match self.recorder.synced(&synced) {
                Ok(()) => self.durable = Some(covers),
                Err(reason) => return self.stop(crate::error::message(&reason)),
            }
        }
        match self.recorder.request_sync() {
            Ok(synced) => self.in_flight = Some((synced, at)),
            Err(reason) => self.stop(crate::error::message(&reason)),
        }
    }

    /// The journal stops (the disk is full, the file cannot be written);
    /// the world runs on, and status and log say why.
    fn stop(&mut self, reason: String) {
        let (episode, frame) = self.durable.unwrap_or_default();
        warn!(
            segment = %self.segment.display(),
            durable_episode = episode,
            durable_frame = frame,
            "the journal stopped: {reason}; the world runs on without it, and a resume starts from frame {frame}"
        );
        self.recorder.stop("journal failed", 0);
        // Status has room for the cause, not for the path before it.
        let cause = reason.rsplit(": ").next().unwrap_or(&reason);
        self.stopped = Some(cause.to_string());
    }

    /// Closes the segment (the server stops).
    pub(crate) fn close(&mut self, reason: &str, frame: u64) {
        self.recorder.stop(reason, frame);
    }
}
