//! Reading a journal back: the world after its last complete frame (a
//! resume), or after any journaled frame (a fork), rebuilt from the
//! nearest keyframe before it and the commands journaled since, every
//! re-simulated frame checked against the journal's.
//!
//! What was journaled after the last complete frame (commands for a frame
//! that never came, a sensor spawned after it) is left out: the resumed
//! world is the one that frame's readers saw, and a ticker that sends
//! those commands again gets the frame they were for.

use std::path::{Path, PathBuf};
use std::time::Instant;

use shared_types::{ActorState, FrameHeader, SensorSpec, WorldSettings};
use simbus_recording::{Entry, RecordedEvent, RecordingError, RecordingHeader, RecordingReader};
use tracing::{info, warn};

use super::segments;
use crate::clock::Clock;
use crate::keyframe::Keyframe;
use crate::replayer::{episode_world, recorded_plan};
use crate::scene::Scene;
use crate::world::World;

/// Where a server resumes from.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ResumeOptions {
    /// The journal's directory.
    pub dir: PathBuf,
    /// Fork: the journaled frame to start from (`None`: the last complete
    /// frame).
    pub at: Option<u64>,
}

/// Why a journal cannot be resumed. Nothing was started.
#[derive(Debug, thiserror::Error)]
pub enum ResumeError {
    /// The directory cannot be read.
    #[error("cannot read the journal directory {dir}")]
    Directory {
        /// The directory.
        dir: PathBuf,
        /// What the file system said.
        source: std::io::Error,
    },
    /// It holds no segment.
    #[error("{dir} holds no journal (no journal-NNNNNN.mcap)")]
    Empty {
        /// The directory.
        dir: PathBuf,
    },
    /// No segment can be used; the newest one's reason is given.
    #[error("no segment of {dir} can be resumed: {reason}")]
    Unusable {
        /// The directory.
        dir: PathBuf,
        /// Why the newest segment could not be used.
        reason: String,
    },
    /// A fork asked for a frame the journal does not hold.
    #[error("the journal in {dir} holds no frame {frame} after a keyframe")]
    NoSuchFrame {
        /// The directory.
        dir: PathBuf,
        /// The frame asked for.
        frame: u64,
    },
    /// A re-simulated frame differs from the journal's.
    #[error("re-simulating {segment} differs from the journal at frame {frame}, actor {actor}: the journal is damaged or was written by a different build; refusing to resume")]
    Mismatch {
        /// The segment.
        segment: PathBuf,
        /// The frame.
        frame: u64,
        /// The first actor that differs.
        actor: u64,
    },
}

/// A world rebuilt from a journal.
#[derive(Debug)]
pub(crate) struct Resumed {
    /// The journal's header (world, seed, the run's start).
    pub(crate) header: RecordingHeader,
    /// The world after the frame (taken by the server that resumes).
    pub(crate) world: Option<World>,
    pub(crate) clock: Clock,
    pub(crate) scene: Scene,
    pub(crate) episode: u64,
    /// The settings the last frame was computed with.
    pub(crate) settings: WorldSettings,
    /// The last frame as it was published.
    pub(crate) frame: FrameHeader,
    /// The sensors alive at that frame, with their ids.
    pub(crate) sensors: Vec<(u64, SensorSpec)>,
    /// The highest sensor id the journal gave out.
    pub(crate) last_sensor_id: u64,
    /// The segment read.
    pub(crate) segment: PathBuf,
    /// The frame of the keyframe it started from.
    pub(crate) keyframe_frame: u64,
    /// Frames re-simulated (and checked) after the keyframe.
    pub(crate) resimulated: u64,
    /// What was damaged or left out, said in the log.
    pub(crate) notes: Vec<String>,
}

/// A keyframe or a frame, in the order a segment holds them.
#[derive(Debug, Clone, Copy)]
enum Mark {
    Keyframe,
    Frame { frame: u64, replay: bool },
}

/// The first pass over a segment: its marks and why reading stopped
/// early, if it did.
struct Scan {
    marks: Vec<Mark>,
    damage: Option<String>,
}

fn scan(path: &Path) -> Result<Scan, RecordingError> {
    let mut reader = RecordingReader::open(&path.to_string_lossy())?;
    let mut marks = Vec::new();
    let mut damage = None;
    for entry in std::iter::from_fn(|| reader.next()) {
        match entry {
            Ok(Entry::Keyframe { .. }) => marks.push(Mark::Keyframe),
            Ok(Entry::Frame { header, .. }) => marks.push(Mark::Frame {
                frame: header.timestamp.frame,
                replay: header.flags & FrameHeader::REPLAY != 0,
            }),
            Ok(_) => {}
            Err(e) => {
                damage = Some(e.to_string());
                break;
            }
        }
    }
    if damage.is_none() && reader.truncated() {
        damage = Some(
            "it ends in the middle of a chunk (its server was killed, or its disk filled)".into(),
        );
    }
    Ok(Scan { marks, damage })
}

/// The index (among frames) of the frame to resume at, and the indexes
/// (among keyframes) of the keyframes before it, latest first.
fn choose(marks: &[Mark], at: Option<u64>) -> Option<(usize, Vec<usize>)> {
    let mut frames = 0;
    let mut keyframes = 0;
    // (frame index, keyframes up to it, its mark's position)
    let mut target = None;
    let mut replay_seen = false;
    for (position, mark) in marks.iter().enumerate() {
        match *mark {
            Mark::Keyframe => {
                keyframes += 1;
                replay_seen = false;
            }
            Mark::Frame { frame, replay, .. } => {
                replay_seen |= replay;
                let wanted = !replay_seen && at.is_none_or(|at| frame == at);
                // A keyframe is written right after its own frame.
                let own = matches!(marks.get(position + 1), Some(Mark::Keyframe));
                let usable = keyframes + usize::from(own);
                if wanted && usable > 0 {
                    target = Some((frames, usable));
                }
                frames += 1;
            }
        }
    }
    let (frame, usable) = target?;
    Some((frame, (0..usable).rev().collect()))
}

/// Rebuilds the world of the journal in `options.dir`: its newest usable
/// segment's last complete frame, or `options.at`'s frame in the newest
/// segment that holds it after a keyframe.
pub(crate) fn resume(options: &ResumeOptions) -> Result<Resumed, ResumeError> {
    let dir = &options.dir;
    let found = segments(dir).map_err(|source| ResumeError::Directory {
        dir: dir.clone(),
        source,
    })?;
    if found.is_empty() {
        return Err(ResumeError::Empty { dir: dir.clone() });
    }
    let mut newest_reason = None;
    for (_, path) in found.iter().rev() {
        let scanned = match scan(path) {
            Ok(scanned) => scanned,
            Err(reason) => {
                warn!(segment = %path.display(), "journal segment unreadable: {reason}");
                newest_reason.get_or_insert(format!("{}: {reason}", path.display()));
                continue;
            }
        };
        let Some((target, keyframes)) = choose(&scanned.marks, options.at) else {
            if options.at.is_none() {
                newest_reason.get_or_insert(format!(
                    "{}: no complete keyframe{}",
                    path.display(),
                    scanned
                        .damage
                        .as_deref()
                        .map(|d| format!(" ({d})"))
                        .unwrap_or_default()
                ));
            }
            continue;
        };
        for keyframe in keyframes {
            match roll(path, keyframe, target) {
                Ok(Rolled::Done(mut resumed)) => {
                    if let Some(damage) = scanned.damage.clone() {
                        resumed.notes.push(format!(
                            "{} is damaged or unfinished after frame {}: {damage}",
                            path.display(),
                            resumed.frame.timestamp.frame
                        ));
                    }
                    let every = resumed.header.journal_sync_frames;
                    if every > 1 {
                        resumed.notes.push(format!(
                            "the journal was made durable every {every} frames: up to {every} frame(s) published after frame {} before the crash may be lost, and are computed again from here",
                            resumed.frame.timestamp.frame
                        ));
                    }
                    for note in &resumed.notes {
                        warn!("{note}");
                    }
                    info!(
                        segment = %path.display(),
                        keyframe = resumed.keyframe_frame,
                        frame = resumed.frame.timestamp.frame,
                        episode = resumed.episode,
                        resimulated = resumed.resimulated,
                        "journal read: resuming after frame {}", resumed.frame.timestamp.frame
                    );
                    return Ok(*resumed);
                }
                Ok(Rolled::BadKeyframe(reason)) => {
                    warn!(segment = %path.display(), keyframe, "keyframe unusable ({reason}); trying the one before");
                }
                Err(e) => return Err(e),
            }
        }
    }
    match options.at {
        Some(frame) => Err(ResumeError::NoSuchFrame {
            dir: dir.clone(),
            frame,
        }),
        None => Err(ResumeError::Unusable {
            dir: dir.clone(),
            reason: newest_reason.unwrap_or_else(|| "no keyframe".into()),
        }),
    }
}

enum Rolled {
    Done(Box<Resumed>),
    BadKeyframe(String),
}

/// What waits for the next frame: applied only when that frame is in
/// the journal.
enum Pending {
    Command(shared_types::Command),
    Episode { scene: String, first_id: u64 },
    Spawned(u64, SensorSpec),
    Ended(u64),
}

/// Restores keyframe number `keyframe` of `path` and rolls forward to
/// frame number `target`, checking each frame.
fn roll(path: &Path, keyframe: usize, target: usize) -> Result<Rolled, ResumeError> {
    let mut reader =
        RecordingReader::open(&path.to_string_lossy()).map_err(|e| ResumeError::Unusable {
            dir: path.to_path_buf(),
            reason: e.to_string(),
        })?;
    let header = reader.header().clone();
    let mut sensors: Vec<(u64, SensorSpec)> = Vec::new();
    let mut last_sensor_id = 0u64;
    let mut keyframes = 0usize;
    let mut frames = 0usize;
    let mut last: Option<FrameHeader> = None;
    let mut restored: Option<(World, Scene, u64, u64)> = None;
    let mut pending: Vec<Pending> = Vec::new();
    let mut resimulated = 0u64;
    let mut notes = Vec::new();
    let apply_sensor = |sensors: &mut Vec<(u64, SensorSpec)>, change: &Pending| match *change {
        Pending::Spawned(id, spec) => sensors.push((id, spec)),
        Pending::Ended(id) => sensors.retain(|(alive, _)| *alive != id),
        _ => {}
    };
    while let Some(entry) = reader.next() {
        let Ok(entry) = entry else { break };
        match entry {
            Entry::Sensor(sensor) => {
                last_sensor_id = last_sensor_id.max(sensor.id);
                let change = Pending::Spawned(sensor.id, sensor.spec);
                if restored.is_some() {
                    pending.push(change);
                } else {
                    apply_sensor(&mut sensors, &change);
                }
            }
            Entry::Event(RecordedEvent::SensorEnded { id, .. }) => {
                let change = Pending::Ended(id);
                if restored.is_some() {
                    pending.push(change);
                } else {
                    apply_sensor(&mut sensors, &change);
                }
            }
            Entry::Keyframe { data } => {
                if keyframes == keyframe {
                    let keyframe = match Keyframe::decode(&data) {
                        Ok(k) => k,
                        Err(e) => return Ok(Rolled::BadKeyframe(e.to_string())),
                    };
                    if let Err(e) = keyframe.world.check() {
                        return Ok(Rolled::BadKeyframe(e.to_string()));
                    }
                    let scene: Scene = match keyframe.scene.parse() {
                        Ok(scene) => scene,
                        Err(e) => return Ok(Rolled::BadKeyframe(e.to_string())),
                    };
                    restored = Some((keyframe.world, scene, keyframe.episode, keyframe.frame));
                    if frames > target {
                        break;
                    }
                }
                keyframes += 1;
            }
            Entry::Command(recorded) if restored.is_some() => {
                pending.push(Pending::Command(recorded.command));
            }
            Entry::Event(RecordedEvent::Episode {
                scene,
                first_actor_id,
                ..
            }) if restored.is_some() => pending.push(Pending::Episode {
                scene,
                first_id: first_actor_id,
            }),
            Entry::Frame {
                header: h, actors, ..
            } => {
                let index = frames;
                frames += 1;
                let Some((world, scene, episode, _)) = &mut restored else {
                    last = Some(h);
                    continue;
                };
                for change in pending.drain(..) {
                    match change {
                        Pending::Command(command) => {
                            world.apply(&command);
                        }
                        Pending::Episode { scene: s, first_id } => {
                            match episode_world(&s, header.seed, first_id) {
                                Ok((w, sc)) => {
                                    *world = w;
                                    *scene = sc;
                                }
                                Err(e) => {
                                    return Err(ResumeError::Unusable {
                                        dir: path.to_path_buf(),
                                        reason: crate::error::message(&e),
                                    })
                                }
                            }
                        }
                        change => apply_sensor(&mut sensors, &change),
                    }
                }
                *episode = h.episode;
                if h.physics_substeps > 0 {
                    let plan = recorded_plan(&h);
                    let stepped = std::panic::catch_unwind(std::panic::AssertUnwindSafe(|| {
                        world.step(&plan)
                    }));
                    if stepped.is_err() {
                        return Err(mismatch(path, &h, 0));
                    }
                    resimulated += 1;
                }
                if let Some(actor) = first_difference(&world.states(), &actors) {
                    return Err(mismatch(path, &h, actor));
                }
                last = Some(h);
                if index >= target {
                    break;
                }
            }
            _ => {}
        }
    }
    let (Some((world, scene, episode, keyframe_frame)), Some(frame)) = (restored, last) else {
        return Ok(Rolled::BadKeyframe("the segment ended before it".into()));
    };
    if !pending.is_empty() {
        notes.push(format!(
            "{} journaled request(s) after frame {} belong to a frame that was never completed; they are left out",
            pending.len(),
            frame.timestamp.frame
        ));
    }
    let clock = Clock::at_timestamp(&frame.timestamp, Instant::now());
    Ok(Rolled::Done(Box::new(Resumed {
        header,
        world: Some(world),
        clock,
        scene,
        episode,
        settings: WorldSettings::from(frame.settings),
        frame,
        sensors,
        last_sensor_id,
        segment: path.to_path_buf(),
        keyframe_frame,
        resimulated,
        notes,
    })))
}

fn mismatch(path: &Path, header: &FrameHeader, actor: u64) -> ResumeError {
    ResumeError::Mismatch {
        segment: path.to_path_buf(),
        frame: header.timestamp.frame,
        actor,
    }
}

/// The id of the first actor whose state differs, bit for bit (an actor
/// only one side has counts).
fn first_difference(simulated: &[ActorState], journaled: &[ActorState]) -> Option<u64> {
    for (a, b) in simulated.iter().zip(journaled) {
        if bytemuck::bytes_of(a) != bytemuck::bytes_of(b) {
            return Some(a.id.min(b.id));
        }
    }
    match simulated.len().cmp(&journaled.len()) {
        std::cmp::Ordering::Equal => None,
        std::cmp::Ordering::Greater => Some(simulated[journaled.len()].id),
        std::cmp::Ordering::Less => Some(journaled[simulated.len()].id),
    }
}
