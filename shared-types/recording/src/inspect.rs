//! Reading a recording without a server: CARLA's `show_recorder_file_info`,
//! `show_recorder_collisions` and `show_recorder_actors_blocked`, answered
//! as data (serialize them for JSON) instead of preformatted text.
//!
//! ```no_run
//! let info = simbus_recording::inspect::file_info("run.mcap", false)?;
//! println!("{} frames, {:.1} s", info.frames, info.duration_seconds);
//! # Ok::<(), simbus_recording::RecordingError>(())
//! ```

use std::collections::BTreeMap;

use serde::Serialize;
use shared_types::Exact;
use shared_types::{
    ActorKind, ActorState, CommandKind, CommandStatus, FrameHeader, NANOS_PER_SECOND,
};

use crate::format::{RecordedCommand, RecordedEvent, RecordingError, RecordingHeader};
use crate::read::{Entry, RecordingReader};

/// What a recording holds (`recorder info`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct FileInfo {
    /// The file.
    pub path: String,
    /// Its header: versions, world, scene, seed, settings, start.
    pub header: RecordingHeader,
    /// Frames recorded.
    pub frames: u64,
    /// The first recorded frame id (of the first episode: ids start again
    /// with each episode, see `episode_list`).
    pub first_frame: u64,
    /// The last recorded frame id (of the last episode).
    pub last_frame: u64,
    /// The frames of each episode the recording covers, in order.
    pub episode_list: Vec<EpisodeFrames>,
    /// Simulation seconds covered (summed over episodes).
    pub duration_seconds: f64,
    /// Episodes begun during the recording (loads and reloads).
    pub episodes: u64,
    /// Commands recorded.
    pub commands: u64,
    /// Actors spawned by commands.
    pub actors_spawned: u64,
    /// Actors destroyed by commands.
    pub actors_destroyed: u64,
    /// The most actors in one frame.
    pub max_actors: u64,
    /// Sensors spawned (recorded ones: see `captures`).
    pub sensors: u64,
    /// Sensor captures recorded.
    pub captures: u64,
    /// Collisions.
    pub collisions: u64,
    /// Keyframes.
    pub keyframes: u64,
    /// Settings changes.
    pub settings_changes: u64,
    /// The file's size.
    pub bytes: u64,
    /// Bytes of frames, commands and captures before compression.
    pub raw_bytes: u64,
    /// `raw_bytes / bytes`.
    pub compression_ratio: f64,
    /// The file is still being recorded, or was not closed (its server was
    /// killed): every complete chunk was read.
    pub truncated: bool,
    /// Why the recording stopped, if it was closed.
    pub stopped: Option<String>,
    /// With `show_all`: every frame (id, time, delta, actors).
    #[serde(skip_serializing_if = "Vec::is_empty")]
    pub frame_list: Vec<FrameLine>,
}

/// The frames one episode contributed to a recording.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct EpisodeFrames {
    /// The episode.
    pub episode: u64,
    /// Its frames in the recording.
    pub frames: u64,
    /// Its first recorded frame id.
    pub first_frame: u64,
    /// Its last recorded frame id.
    pub last_frame: u64,
}

/// One frame, for `recorder info --all`.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct FrameLine {
    /// Frame id.
    pub frame: u64,
    /// Its episode in the recording.
    pub episode: u64,
    /// Simulation seconds.
    pub elapsed_seconds: f64,
    /// Seconds since the previous frame.
    pub delta_seconds: f64,
    /// Physics steps.
    pub substeps: u32,
    /// Actors.
    pub actors: u32,
}

/// One collision (`recorder collisions`).
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Collision {
    /// The frame in which the contact started.
    pub frame: u64,
    /// When, in recording seconds: since the recording's start, as CARLA's
    /// recorder counts and [`Blocked::from_seconds`] does.
    pub time_seconds: f64,
    /// When, in the world's simulation time.
    pub elapsed_seconds: f64,
    /// One actor (the lower id).
    pub actor_a: u64,
    /// Its kind.
    pub kind_a: &'static str,
    /// The other.
    pub actor_b: u64,
    /// Its kind.
    pub kind_b: &'static str,
    /// The contact's normal impulse at the end of the step, N·s.
    pub impulse: f32,
}

/// An actor that stayed (nearly) still at least once (`recorder blocked`).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct BlockedActor {
    /// The actor.
    pub actor: u64,
    /// Its kind.
    pub kind: &'static str,
    /// Each stretch in which it moved less than the distance for at least
    /// the time, in order.
    pub stretches: Vec<Blocked>,
}

/// One stretch in which an actor stayed (nearly) still.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Blocked {
    /// The frame it stopped at.
    pub frame: u64,
    /// When it stopped (recording seconds).
    pub from_seconds: f64,
    /// How long it moved less than the distance.
    pub duration_seconds: f64,
    /// How far it moved meanwhile, metres.
    pub distance: f32,
}

/// Why [`actors_blocked`] gave no answer.
#[derive(Debug, thiserror::Error)]
pub enum BlockedError {
    /// `min_time` is not a finite number of seconds in the clock's range.
    #[error(
        "min_time must be a finite number of seconds in 0..={max}, got {}",
        Exact(*.0),
        max = shared_types::MAX_SENSOR_TICK_SECONDS
    )]
    MinTime(f64),
    /// `min_distance` is not a positive, finite number of metres.
    #[error(
        "min_distance must be a positive, finite number of metres, got {}",
        Exact(*.0)
    )]
    MinDistance(f64),
    /// The recording cannot be read.
    #[error(transparent)]
    File(#[from] RecordingError),
}

fn kind_name(kind: u32) -> &'static str {
    ActorKind::from_u32(kind).map_or("unknown", |k| k.name())
}

fn seconds(ns: u64) -> f64 {
    ns as f64 / NANOS_PER_SECOND as f64
}

/// Every entry of `path`, in order.
fn entries(path: &str, mut each: impl FnMut(&Entry)) -> Result<RecordingReader, RecordingError> {
    let mut reader = RecordingReader::open(path)?;
    while let Some(entry) = reader.next() {
        each(&entry?);
    }
    Ok(reader)
}

/// CARLA's `show_recorder_file_info(name, show_all)`.
///
/// # Errors
///
/// Returns the [`RecordingError`] of [`RecordingReader::open`] if `path` cannot
/// be opened as a simbus recording ([`RecordingError::Io`],
/// [`RecordingError::NotMcap`], [`RecordingError::NotSimbus`],
/// [`RecordingError::Truncated`], ...), and the first error met reading its
/// messages: [`RecordingError::Corrupt`] for a damaged chunk,
/// [`RecordingError::Malformed`] for a message that breaks its schema,
/// [`RecordingError::FutureSchema`] for a channel of a newer simbus.
pub fn file_info(path: &str, show_all: bool) -> Result<FileInfo, RecordingError> {
    let mut info = FileInfo::empty(path, RecordingReader::open(path)?.header().clone());
    let mut last_log = 0;
    let reader = entries(path, |entry| match entry {
        Entry::Frame {
            log_ns,
            header,
            actors,
        } => {
            last_log = *log_ns;
            info.count_frame(header, actors, show_all);
        }
        Entry::Command(c) => info.count_command(c),
        Entry::Event(RecordedEvent::Episode { .. }) => info.episodes += 1,
        Entry::Event(RecordedEvent::Settings { .. }) => info.settings_changes += 1,
        Entry::Event(RecordedEvent::Stopped { reason, .. }) => info.stopped = Some(reason.clone()),
        Entry::Event(RecordedEvent::SensorEnded { .. }) => {}
        Entry::Collision(_) => info.collisions += 1,
        Entry::Sensor(_) => info.sensors += 1,
        Entry::Capture { data, .. } => {
            info.captures += 1;
            info.raw_bytes += data.len() as u64;
        }
        Entry::Keyframe { .. } => info.keyframes += 1,
    })?;
    info.duration_seconds = seconds(last_log);
    info.bytes = reader.bytes();
    info.truncated = reader.truncated();
    info.compression_ratio = if info.bytes > 0 {
        info.raw_bytes as f64 / info.bytes as f64
    } else {
        0.0
    };
    Ok(info)
}

impl FileInfo {
    /// Nothing counted yet.
    fn empty(path: &str, header: RecordingHeader) -> Self {
        FileInfo {
            path: path.to_string(),
            header,
            frames: 0,
            first_frame: 0,
            last_frame: 0,
            episode_list: Vec::new(),
            duration_seconds: 0.0,
            episodes: 0,
            commands: 0,
            actors_spawned: 0,
            actors_destroyed: 0,
            max_actors: 0,
            sensors: 0,
            captures: 0,
            collisions: 0,
            keyframes: 0,
            settings_changes: 0,
            bytes: 0,
            raw_bytes: 0,
            compression_ratio: 0.0,
            truncated: false,
            stopped: None,
            frame_list: Vec::new(),
        }
    }

    /// Counts a frame (its episode, its actors and bytes; listed with `show_all`).
    fn count_frame(&mut self, header: &FrameHeader, actors: &[ActorState], show_all: bool) {
        let t = &header.timestamp;
        if self.frames == 0 {
            self.first_frame = t.frame;
        }
        self.frames += 1;
        self.last_frame = t.frame;
        match self.episode_list.last_mut() {
            Some(e) if e.episode == header.episode => {
                e.frames += 1;
                e.last_frame = t.frame;
            }
            _ => self.episode_list.push(EpisodeFrames {
                episode: header.episode,
                frames: 1,
                first_frame: t.frame,
                last_frame: t.frame,
            }),
        }
        self.max_actors = self.max_actors.max(actors.len() as u64);
        self.raw_bytes += (std::mem::size_of_val(header) + std::mem::size_of_val(actors)) as u64;
        if show_all {
            self.frame_list.push(FrameLine {
                frame: t.frame,
                episode: header.episode,
                elapsed_seconds: t.elapsed_seconds(),
                delta_seconds: t.delta_seconds(),
                substeps: header.physics_substeps,
                actors: header.actor_count,
            });
        }
    }

    /// Counts an applied command (and the actors it spawned or destroyed).
    fn count_command(&mut self, c: &RecordedCommand) {
        self.commands += 1;
        self.raw_bytes += std::mem::size_of_val(c) as u64;
        let ok = c.result.status == CommandStatus::Ok as u32;
        match CommandKind::from_u32(c.command.kind) {
            Some(kind) if ok && kind.spawns() => self.actors_spawned += 1,
            Some(CommandKind::Destroy) if ok => self.actors_destroyed += 1,
            _ => {}
        }
    }
}

/// Whether `kind` matches CARLA-style category `filter`: `a` any, `v`
/// vehicle, `w` walker, `t` traffic light, `b` box, `s` sphere, `c`
/// capsule, `x` static (and traffic signs).
pub fn kind_matches(filter: char, kind: u32) -> bool {
    matches!(
        (filter, ActorKind::from_u32(kind)),
        ('a', _)
            | ('v', Some(ActorKind::Vehicle))
            | ('w', Some(ActorKind::Walker))
            | ('t', Some(ActorKind::TrafficLight))
            | ('b', Some(ActorKind::Box))
            | ('s', Some(ActorKind::Sphere))
            | ('c', Some(ActorKind::Capsule))
            | ('x', Some(ActorKind::Static | ActorKind::TrafficSign))
    )
}

/// CARLA's `show_recorder_collisions(name, type1, type2)`: collisions
/// between an actor of category `kind1` and one of `kind2` (see
/// [`kind_matches`]), in order.
///
/// # Errors
///
/// Returns the [`RecordingError`] of [`RecordingReader::open`] if `path` cannot
/// be opened as a simbus recording, and the first error met reading its
/// messages ([`RecordingError::Corrupt`], [`RecordingError::Malformed`],
/// [`RecordingError::FutureSchema`], ...).
pub fn collisions(path: &str, kind1: char, kind2: char) -> Result<Vec<Collision>, RecordingError> {
    let mut out = Vec::new();
    // A step's collisions follow its frame in the file, at its recording
    // time (a load's new episode starts its frame ids again, never its
    // recording time).
    let mut frame_log_ns = 0;
    entries(path, |entry| match entry {
        Entry::Frame { log_ns, .. } => frame_log_ns = *log_ns,
        Entry::Collision(c) => {
            let matches = (kind_matches(kind1, c.kind_a) && kind_matches(kind2, c.kind_b))
                || (kind_matches(kind1, c.kind_b) && kind_matches(kind2, c.kind_a));
            if matches {
                out.push(Collision {
                    frame: c.frame,
                    time_seconds: seconds(frame_log_ns),
                    elapsed_seconds: seconds(c.elapsed_ns),
                    actor_a: c.actor_a,
                    kind_a: kind_name(c.kind_a),
                    actor_b: c.actor_b,
                    kind_b: kind_name(c.kind_b),
                    impulse: c.impulse,
                });
            }
        }
        _ => {}
    })?;
    Ok(out)
}

/// CARLA's `show_recorder_actors_blocked(name, min_time, min_distance)`.
///
/// Every movable actor that, at least once, moved less than `min_distance`
/// metres (positive, finite) for at least `min_time` seconds (finite, not
/// negative), with each such stretch; actors in id order.
///
/// # Errors
///
/// Returns [`BlockedError::MinTime`] if `min_time` is negative, not finite or
/// beyond the clock's range, [`BlockedError::MinDistance`] if `min_distance` is
/// not positive and finite (both checked before the file is opened), and
/// [`BlockedError::File`] with the [`RecordingError`] if the recording cannot
/// be opened or read.
pub fn actors_blocked(
    path: &str,
    min_time: f64,
    min_distance: f64,
) -> Result<Vec<BlockedActor>, BlockedError> {
    struct Still {
        kind: u32,
        since_ns: u64,
        since_frame: u64,
        at: [f32; 3],
        last_ns: u64,
        moved: f32,
    }
    if !(min_time.is_finite() && (0.0..=shared_types::MAX_SENSOR_TICK_SECONDS).contains(&min_time))
    {
        return Err(BlockedError::MinTime(min_time));
    }
    if !(min_distance.is_finite() && min_distance > 0.0) {
        return Err(BlockedError::MinDistance(min_distance));
    }
    let min_ns = (min_time * NANOS_PER_SECOND as f64) as u64;
    let min_distance = min_distance as f32;
    let mut still: BTreeMap<u64, Still> = BTreeMap::new();
    let mut out: BTreeMap<u64, BlockedActor> = BTreeMap::new();
    let close = |id: u64, s: &Still, out: &mut BTreeMap<u64, BlockedActor>| {
        if s.last_ns.saturating_sub(s.since_ns) >= min_ns {
            out.entry(id)
                .or_insert_with(|| BlockedActor {
                    actor: id,
                    kind: kind_name(s.kind),
                    stretches: Vec::new(),
                })
                .stretches
                .push(Blocked {
                    frame: s.since_frame,
                    from_seconds: seconds(s.since_ns),
                    duration_seconds: seconds(s.last_ns.saturating_sub(s.since_ns)),
                    distance: s.moved,
                });
        }
    };
    entries(path, |entry| {
        let Entry::Frame {
            log_ns,
            header,
            actors,
        } = entry
        else {
            return;
        };
        for actor in actors {
            if actor.kind == ActorKind::Static as u32 {
                continue;
            }
            let start = || Still {
                kind: actor.kind,
                since_ns: *log_ns,
                since_frame: header.timestamp.frame,
                at: actor.position,
                last_ns: *log_ns,
                moved: 0.0,
            };
            let s = still.entry(actor.id).or_insert_with(start);
            let [dx, dy, dz] = [0, 1, 2].map(|i| actor.position[i] - s.at[i]);
            let distance = (dx * dx + dy * dy + dz * dz).sqrt();
            if distance >= min_distance {
                close(actor.id, s, &mut out);
                *s = start();
            } else {
                s.last_ns = *log_ns;
                s.moved = distance;
            }
        }
    })?;
    for (id, s) in &still {
        close(*id, s, &mut out);
    }
    Ok(out.into_values().collect())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn refused_bounds_print_the_number_given_readably() {
        // Checked before the file is opened; 1e300 is not 300 digits.
        let e = actors_blocked("/nonexistent.mcap", 1e300, 1.0).unwrap_err();
        assert!(matches!(e, BlockedError::MinTime(t) if t == 1e300));
        assert_eq!(
            e.to_string(),
            "min_time must be a finite number of seconds in 0..=18446744073, got 1e300"
        );
        let e = actors_blocked("/nonexistent.mcap", 1.0, -1e300).unwrap_err();
        assert_eq!(
            e.to_string(),
            "min_distance must be a positive, finite number of metres, got -1e300"
        );
        let e = actors_blocked("/nonexistent.mcap", 1.0, 0.25).unwrap_err();
        assert!(matches!(e, BlockedError::File(_)), "{e}");
    }
}
