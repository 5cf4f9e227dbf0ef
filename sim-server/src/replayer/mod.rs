//! The replayer domain: turns a recording back into frames, in one of
//! three modes (see [`ReplayMode`]).
//!
//! A replay is checked whole before it starts (a damaged file is refused
//! and the world is unchanged), restores the world from the keyframe
//! nearest before `start`, rolls forward to `start`, then produces one
//! recorded frame per tick (synchronous mode) or at the recording's pace
//! times the time factor (asynchronous mode). Every replayed frame is an
//! ordinary frame of a new episode, flagged [`FrameHeader::REPLAY`].

mod cursor;
mod error;
mod refused;
mod selection;

use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use shared_types::{ActorState, FrameHeader, ReplayMode, ReplayState, WorldSettings};
use simbus_recording::{Entry, RecordedEvent, RecordingReader};
use tracing::{info, warn};

use crate::clock::{Clock, SubstepPlan};
use crate::keyframe::Keyframe;
use crate::scene::Scene;
use crate::world::World;
use cursor::Cursor;
pub(crate) use cursor::SensorChange;
pub(crate) use error::{KeyframeFault, ReplayError};
pub(crate) use refused::ReplayRefused;
use selection::Selection;

/// A replay request, checked.
#[derive(Debug, Clone)]
pub(crate) struct ReplayRequest {
    pub(crate) path: String,
    pub(crate) start_seconds: f64,
    pub(crate) duration_seconds: f64,
    pub(crate) follow_id: u64,
    pub(crate) replay_sensors: bool,
    /// At the end, keep the replayed world (else the one from before comes back).
    pub(crate) keep_actors: bool,
    pub(crate) time_factor: f64,
    /// `None`: exact for a fixed-step recording, interpolate otherwise.
    pub(crate) mode: Option<ReplayMode>,
}

/// How the last (or current) replay went, as the recorder service reports it.
#[derive(Debug, Clone)]
pub(crate) struct ReplayReport {
    pub(crate) state: ReplayState,
    pub(crate) mode: ReplayMode,
    pub(crate) path: String,
    pub(crate) frames: u64,
    /// Frames published (for interpolate, more or fewer than recorded).
    pub(crate) produced: u64,
    pub(crate) total: u64,
    pub(crate) verified: u64,
    pub(crate) mismatch: Option<(u64, u64)>,
    pub(crate) time_factor: f64,
    pub(crate) message: String,
}

impl Default for ReplayReport {
    fn default() -> Self {
        Self {
            state: ReplayState::Idle,
            mode: ReplayMode::Exact,
            path: String::new(),
            frames: 0,
            produced: 0,
            total: 0,
            verified: 0,
            mismatch: None,
            time_factor: 1.0,
            message: String::new(),
        }
    }
}

/// The world a replay put aside, restored when it stops without keeping
/// the replayed actors.
#[derive(Debug)]
pub(crate) struct SavedWorld {
    pub(crate) world: World,
    pub(crate) scene: Scene,
}

/// A running replay.
#[derive(Debug)]
struct Replay {
    cursor: Cursor,
    selection: Selection,
    /// When the first replayed frame was (to be) published, and its recording time.
    anchor: Option<(Instant, u64)>,
    /// Interpolate: the recording time of the last produced frame.
    replay_ns: u64,
    follow_id: u64,
    replay_sensors: bool,
    /// The recorded episode of the last replayed frame.
    episode: Option<u64>,
}

/// What the next replayed frame is: its header (as recorded, or made up
/// for interpolation), the actors to publish, and whether the world was
/// replaced by a new recorded episode since the previous one.
#[derive(Debug)]
pub(crate) struct ReplayFrame {
    pub(crate) header: FrameHeader,
    pub(crate) actors: Vec<ActorState>,
    pub(crate) last: bool,
    /// The recording began a new episode with this frame.
    pub(crate) new_episode: bool,
}

/// The replayer's state.
#[derive(Debug, Default)]
pub(crate) struct Replayer {
    active: Option<Replay>,
    pub(crate) report: ReplayReport,
    pub(crate) saved: Option<SavedWorld>,
    /// Replayed sensors: (recorded id, id in this server).
    pub(crate) sensor_ids: Vec<(u64, u64)>,
    /// Whether the current replay keeps its world when it ends.
    pub(crate) keep_actors: bool,
    /// The replay being prepared, if one is.
    preparing: Option<Preparing>,
}

/// A replay being prepared: its recording, and the thread reading it.
#[derive(Debug)]
struct Preparing {
    path: String,
    job: JoinHandle<Result<Prepared, ReplayRefused>>,
}

impl Replayer {
    /// Whether a replay runs.
    pub(crate) fn is_running(&self) -> bool {
        self.active.is_some()
    }

    /// The recording of the replay being prepared, if one is.
    pub(crate) fn preparing(&self) -> Option<&str> {
        self.preparing.as_ref().map(|p| p.path.as_str())
    }

    /// Reads and checks `request`'s recording on a thread of its own, so
    /// that a large file never stalls the frame loop (see [`prepare`]).
    pub(crate) fn prepare_in_background(
        &mut self,
        request: ReplayRequest,
    ) -> Result<(), ReplayRefused> {
        if let Some(path) = self.preparing() {
            return Err(ReplayRefused::AlreadyPreparing(path.to_string()));
        }
        let path = request.path.clone();
        let job = std::thread::Builder::new()
            .name("simbus-replay-prepare".into())
            .spawn(move || prepare(&request))
            .map_err(ReplayRefused::ReaderThread)?;
        self.preparing = Some(Preparing { path, job });
        Ok(())
    }

    /// The replay whose preparation finished since last asked (or why it
    /// is refused), if one did.
    pub(crate) fn prepared(&mut self) -> Option<Result<Prepared, ReplayRefused>> {
        if !self.preparing.as_ref()?.job.is_finished() {
            return None;
        }
        let preparing = self.preparing.take()?;
        Some(
            preparing
                .job
                .join()
                .unwrap_or_else(|_| Err(ReplayRefused::ReaderPanicked(preparing.path))),
        )
    }

    /// Installs a prepared replay; returns the world and scene it starts
    /// from, for the caller to swap in. (The recording's clock is not the
    /// server's: replayed frames are numbered on from the live ones, their
    /// recorded ids and times travel in their headers.)
    pub(crate) fn begin(&mut self, prepared: Prepared) -> (World, Scene) {
        self.sensor_ids.clear();
        self.keep_actors = prepared.keep_actors;
        self.report = prepared.report;
        self.active = Some(prepared.replay);
        (prepared.world, prepared.scene)
    }

    /// The recorded actor sensors spawned without a parent ride on.
    pub(crate) fn follow_id(&self) -> u64 {
        self.active.as_ref().map_or(0, |r| r.follow_id)
    }

    /// The recorded sensors that appeared or ended since last asked, when
    /// the replay spawns them again (else none).
    pub(crate) fn sensor_changes(&mut self) -> Vec<SensorChange> {
        match &mut self.active {
            Some(replay) if replay.replay_sensors => {
                std::mem::take(&mut replay.cursor.sensor_changes)
            }
            Some(replay) => {
                replay.cursor.sensor_changes.clear();
                Vec::new()
            }
            None => Vec::new(),
        }
    }

    /// Sets the time factor (refused unless positive and finite).
    pub(crate) fn set_time_factor(&mut self, factor: f64) -> Result<(), ReplayRefused> {
        if !(factor.is_finite() && factor > 0.0) {
            return Err(ReplayRefused::TimeFactor(factor));
        }
        let Some(replay) = &mut self.active else {
            return Err(ReplayRefused::NotReplaying);
        };
        self.report.time_factor = factor;
        // Pace from here on at the new factor.
        replay.anchor = None;
        Ok(())
    }

    /// Ends the replay as `state` (stopped by a client, or failed).
    pub(crate) fn end(&mut self, state: ReplayState, message: String) {
        if self.active.take().is_some() {
            info!(
                path = self.report.path,
                frames = self.report.frames,
                ?state,
                "replay ended"
            );
            self.report.state = state;
            self.report.message = message;
        }
    }

    /// When the next replayed frame is due in asynchronous mode (exact and
    /// resimulate: the recording's pace over the time factor); `None` for
    /// interpolation, which follows the server's own pacing.
    pub(crate) fn next_frame_at(&mut self, now: Instant) -> Option<Instant> {
        let replay = self.active.as_mut()?;
        if self.report.mode == ReplayMode::Interpolate {
            return None;
        }
        let next_ns = replay.cursor.next_log_ns()?;
        let (wall, log_ns) = *replay.anchor.get_or_insert((now, next_ns));
        let ahead_ns = next_ns.saturating_sub(log_ns) as f64 / self.report.time_factor;
        Some(wall + Duration::from_secs_f64((ahead_ns * 1e-9).min(1e9)))
    }

    /// Produces the next frame into `world`: exact and interpolate set the
    /// actors' states; resimulate steps `world` for real and compares.
    /// `delta_ns` is the server's own step (interpolation only). `None`
    /// when the replay has nothing more (it is then finished).
    pub(crate) fn next_frame(&mut self, world: &mut World, delta_ns: u64) -> Option<ReplayFrame> {
        let mode = self.report.mode;
        let factor = self.report.time_factor;
        let replay = self.active.as_mut()?;
        let produced = match mode {
            ReplayMode::Exact | ReplayMode::Resimulate => replay.cursor.next_recorded(world, mode),
            ReplayMode::Interpolate => {
                // The first frame is the start itself; each next one is a
                // server step (times the factor) later.
                if self.report.produced > 0 {
                    let step = (delta_ns as f64 * factor) as u64;
                    replay.replay_ns = replay.replay_ns.saturating_add(step.max(1));
                }
                if replay.replay_ns > replay.selection.end_log_ns {
                    replay.replay_ns = replay.selection.end_log_ns;
                }
                replay.cursor.interpolated(world, replay.replay_ns)
            }
        };
        let frame = match produced {
            Ok(Some(frame)) => frame,
            Ok(None) => {
                self.end(ReplayState::Finished, String::new());
                return None;
            }
            Err(error) => {
                let message = crate::error::message(&error);
                warn!("replay failed: {message}");
                self.end(ReplayState::Failed, message);
                return None;
            }
        };
        // Progress counts recorded frames (an interpolated replay makes as
        // many frames of its own as its step asks).
        self.report.frames = replay.cursor.passed.min(self.report.total);
        self.report.produced += 1;
        if mode == ReplayMode::Resimulate {
            match frame.mismatch {
                None => self.report.verified += 1,
                Some(at) => {
                    if self.report.mismatch.is_none() {
                        warn!(
                            frame = at.0,
                            actor = at.1,
                            "re-simulation differs from the recording"
                        );
                        self.report.mismatch = Some(at);
                    }
                }
            }
        }
        // The first replayed frame starts a new episode, and so does each
        // recorded load or reload.
        let new_episode = replay.episode != Some(frame.header.episode);
        replay.episode = Some(frame.header.episode);
        let last = match mode {
            // Exact and resimulate: the selected number of recorded frames.
            ReplayMode::Exact | ReplayMode::Resimulate => self.report.frames >= self.report.total,
            // Interpolate: the selected time.
            ReplayMode::Interpolate => frame.log_ns >= replay.selection.end_log_ns,
        } || replay.cursor.exhausted();
        if last {
            self.end(ReplayState::Finished, String::new());
        }
        Some(ReplayFrame {
            header: frame.header,
            actors: frame.actors,
            last,
            new_episode,
        })
    }
}

/// A replay checked and ready to begin (built off the frame loop: reading a
/// large recording takes a while).
#[derive(Debug)]
pub(crate) struct Prepared {
    replay: Replay,
    report: ReplayReport,
    keep_actors: bool,
    world: World,
    scene: Scene,
}

impl Prepared {
    /// The recording's path.
    pub(crate) fn path(&self) -> &str {
        &self.report.path
    }
}

/// Reads and checks `request`'s recording (all of it: a damaged file is
/// refused before anything changes) and builds the world it starts from.
/// Touches nothing of the server's, so it runs on its own thread.
pub(crate) fn prepare(request: &ReplayRequest) -> Result<Prepared, ReplayRefused> {
    if !(request.time_factor.is_finite() && request.time_factor > 0.0) {
        return Err(ReplayRefused::TimeFactor(request.time_factor));
    }
    let finite = request.start_seconds.is_finite() && request.duration_seconds.is_finite();
    if !(finite && request.duration_seconds >= 0.0) {
        return Err(ReplayRefused::BadSpan);
    }
    let selection = Selection::scan(
        &request.path,
        request.start_seconds,
        request.duration_seconds,
    )?;
    if request.follow_id != 0 && !selection.actor_ids.contains(&request.follow_id) {
        return Err(ReplayRefused::UnknownActor(request.follow_id));
    }
    let mode = request.mode.unwrap_or(if selection.variable_step {
        ReplayMode::Interpolate
    } else {
        ReplayMode::Exact
    });
    let reader = RecordingReader::open(&request.path).map_err(ReplayError::from)?;
    let (cursor, world, _recorded_clock, scene) = Cursor::start(reader, &selection, mode)?;
    info!(
        path = request.path,
        mode = mode.name(),
        frames = selection.frames,
        from_keyframe = selection.keyframe_frame,
        start_frame = selection.first_frame,
        "replay ready"
    );
    let report = ReplayReport {
        state: ReplayState::Running,
        mode,
        path: request.path.clone(),
        frames: 0,
        produced: 0,
        total: selection.frames,
        verified: 0,
        mismatch: None,
        time_factor: request.time_factor,
        message: String::new(),
    };
    let replay = Replay {
        cursor,
        replay_ns: selection.start_log_ns,
        selection,
        anchor: None,
        follow_id: request.follow_id,
        replay_sensors: request.replay_sensors,
        episode: None,
    };
    Ok(Prepared {
        replay,
        report,
        keep_actors: request.keep_actors,
        world,
        scene,
    })
}

/// The world of a recorded episode: `scene`'s placements with `seed`, ids from `first_id`.
pub(crate) fn episode_world(
    scene: &str,
    seed: u64,
    first_id: u64,
) -> Result<(World, Scene), ReplayError> {
    let scene: Scene = scene.parse().map_err(ReplayError::EpisodeScene)?;
    Ok((World::new(&scene.placements(seed), first_id), scene))
}

/// The plan a recorded frame was stepped with.
pub(crate) fn recorded_plan(header: &FrameHeader) -> SubstepPlan {
    SubstepPlan::new(
        header.timestamp.delta_ns,
        &WorldSettings::from(header.settings),
    )
}

/// A keyframe decoded into the world and clock it describes.
pub(crate) fn restore(bytes: &[u8]) -> Result<(World, Clock, String), KeyframeFault> {
    let keyframe = Keyframe::decode(bytes)?;
    keyframe
        .world
        .check()
        .map_err(KeyframeFault::Inconsistent)?;
    let clock = Clock::at(
        keyframe.frame,
        keyframe.elapsed_ns,
        keyframe.delta_ns,
        Instant::now(),
    );
    Ok((keyframe.world, clock, keyframe.scene))
}

/// Whether an event starts a new episode.
pub(crate) fn episode_of(entry: &Entry) -> Option<(&str, u64)> {
    match entry {
        Entry::Event(RecordedEvent::Episode {
            scene,
            first_actor_id,
            ..
        }) => Some((scene.as_str(), *first_actor_id)),
        _ => None,
    }
}
