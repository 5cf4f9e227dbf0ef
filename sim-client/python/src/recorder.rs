//! The recorder and the replayer (CARLA's `start_recorder`,
//! `stop_recorder`, `replay_file`, `set_replayer_time_factor`,
//! `stop_replayer`), and `simbus.recording.info(path)`, which reads a
//! recording without a server.

use std::path::PathBuf;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use shared_types::{RecorderRefusal, ReplayMode, WorldSettings};
use sim_client::{RecorderError, ReplayOptions};
use simbus_recording::inspect::{self, EpisodeFrames, FileInfo};

use crate::client::Client;
use crate::errors::{message, raise, request};
use crate::gil::detached;
use crate::settings::Settings;

/// A recorder error as its exception: a bad argument (a path too long, a
/// value out of range, a start past the end, an unknown `follow_id`) is a
/// `ValueError`, any other refusal `simbus.Error`; nothing changed.
fn recorder_error(error: RecorderError) -> PyErr {
    match error {
        RecorderError::Request(e) => request(e),
        RecorderError::PathTooLong
        | RecorderError::Refused {
            refusal:
                RecorderRefusal::InvalidArgument
                | RecorderRefusal::StartPastEnd
                | RecorderRefusal::UnknownActor,
            ..
        } => PyValueError::new_err(message(&error)),
        RecorderError::Refused { .. } => raise("Error", message(&error)),
    }
}

/// `value` if finite.
fn finite(name: &str, value: f64) -> PyResult<f64> {
    if value.is_finite() {
        Ok(value)
    } else {
        Err(PyValueError::new_err(format!(
            "{name} must be a finite number, got {value}"
        )))
    }
}

/// How a replay goes (or went).
#[pyclass(module = "simbus", frozen, get_all)]
#[derive(Debug, Clone)]
pub(crate) struct ReplayStatus {
    /// `"idle"`, `"running"`, `"finished"`, `"stopped"` or `"failed"`.
    state: &'static str,
    /// `"exact"`, `"interpolate"` or `"resimulate"`.
    mode: &'static str,
    /// Frames replayed so far.
    frames: u64,
    /// Frames the replay covers.
    total: u64,
    /// Resimulate: frames whose state matched the recording bit for bit.
    verified: u64,
    /// Resimulate: (frame, actor) where the state first differed (actor 0:
    /// the sets of actors differ), or `None`.
    mismatch: Option<(u64, u64)>,
    /// The replay's speed relative to the recording.
    time_factor: f64,
}

#[pymethods]
impl ReplayStatus {
    fn __repr__(&self) -> String {
        format!(
            "ReplayStatus(state={:?}, mode={:?}, frames={}, total={}, verified={}, mismatch={}, time_factor={:?})",
            self.state,
            self.mode,
            self.frames,
            self.total,
            self.verified,
            self.mismatch
                .map_or("None".to_owned(), |(f, a)| format!("({f}, {a})")),
            self.time_factor
        )
    }
}

/// How the recorder and the replayer are doing.
#[pyclass(module = "simbus", frozen, get_all)]
#[derive(Debug, Clone)]
pub(crate) struct RecorderStatus {
    /// A recording runs.
    recording: bool,
    /// The server recorded since it started (otherwise `path` is the last
    /// replay's file).
    recorded: bool,
    /// The current (or last) recording's path, as the server sees it.
    path: String,
    /// Frames written to it.
    frames: u64,
    /// Its size once closed (0 while it runs).
    bytes: u64,
    /// The current (or last) replay.
    replay: ReplayStatus,
    /// What went wrong last, if anything ("" otherwise).
    message: String,
}

impl From<sim_client::RecorderStatus> for RecorderStatus {
    fn from(s: sim_client::RecorderStatus) -> Self {
        let r = s.replay;
        Self {
            recording: s.recording,
            recorded: s.recorded,
            path: s.path,
            frames: s.frames,
            bytes: s.bytes,
            replay: ReplayStatus {
                state: r.state,
                mode: r.mode,
                frames: r.frames,
                total: r.total,
                verified: r.verified,
                mismatch: r.mismatch.map(|m| (m.frame, m.actor)),
                time_factor: r.time_factor,
            },
            message: s.message,
        }
    }
}

#[pymethods]
impl RecorderStatus {
    fn __repr__(&self) -> String {
        format!(
            "RecorderStatus(recording={}, path={:?}, frames={}, bytes={}, replay={}, message={:?})",
            if self.recording { "True" } else { "False" },
            self.path,
            self.frames,
            self.bytes,
            self.replay.__repr__(),
            self.message
        )
    }
}

#[pymethods]
impl Client {
    /// Starts recording the world into `path` (an MCAP file the server
    /// creates; a relative path is made absolute here), with every sensor
    /// capture if `sensors`. Returns the path the server writes.
    #[pyo3(signature = (path, *, sensors = false))]
    fn start_recorder(&self, py: Python<'_>, path: PathBuf, sensors: bool) -> PyResult<String> {
        let written = detached(py, &self.inner, |c| c.start_recorder(&path, sensors))
            .map_err(recorder_error)?;
        Ok(written.to_string_lossy().into_owned())
    }

    /// Stops the recording and closes its file; the status says how many
    /// frames and bytes it holds.
    fn stop_recorder(&self, py: Python<'_>) -> PyResult<RecorderStatus> {
        let status = detached(py, &self.inner, |c| c.stop_recorder()).map_err(recorder_error)?;
        Ok(status.into())
    }

    /// How the recorder and the replayer are doing.
    fn recorder_status(&self, py: Python<'_>) -> PyResult<RecorderStatus> {
        let status = detached(py, &self.inner, |c| c.recorder_status()).map_err(recorder_error)?;
        Ok(status.into())
    }

    /// Replays the recording at `path` (CARLA's `replay_file`). `mode`:
    /// `"exact"` (the recorded deltas one by one), `"interpolate"` (the
    /// server's own step, recorded states interpolated) or `"resimulate"`
    /// (the recorded commands re-applied to real physics, every frame
    /// compared); `None`: exact for fixed-step recordings, interpolate
    /// otherwise. `start` seconds from the start (negative: from the end),
    /// `duration` seconds (0: to the end), `follow_id` a recorded actor that
    /// unparented sensors ride on, `replay_sensors` spawns the recorded
    /// sensors again, `time_factor` the speed (asynchronous mode),
    /// `keep_actors` keeps the replayed world when the replay ends. In
    /// synchronous mode the replay starts with the next tick, one recorded
    /// frame per tick. A damaged file raises `simbus.Error`; nothing changes.
    #[pyo3(signature = (path, *, mode = None, start = 0.0, duration = 0.0, follow_id = 0, replay_sensors = false, time_factor = 1.0, keep_actors = false))]
    #[allow(clippy::too_many_arguments)]
    fn replay(
        &self,
        py: Python<'_>,
        path: PathBuf,
        mode: Option<&str>,
        start: f64,
        duration: f64,
        follow_id: u64,
        replay_sensors: bool,
        time_factor: f64,
        keep_actors: bool,
    ) -> PyResult<RecorderStatus> {
        let options = ReplayOptions {
            start: finite("start", start)?,
            duration: finite("duration", duration)?,
            follow_id,
            replay_sensors,
            time_factor: finite("time_factor", time_factor)?,
            mode: mode
                .map(str::parse::<ReplayMode>)
                .transpose()
                .map_err(PyValueError::new_err)?,
            keep_actors,
        };
        let status =
            detached(py, &self.inner, |c| c.replay(&path, &options)).map_err(recorder_error)?;
        Ok(status.into())
    }

    /// The replay's speed relative to the recording (CARLA's
    /// `set_replayer_time_factor`; asynchronous mode).
    fn set_replayer_time_factor(&self, py: Python<'_>, factor: f64) -> PyResult<RecorderStatus> {
        let factor = finite("factor", factor)?;
        let status = detached(py, &self.inner, |c| c.set_replayer_time_factor(factor))
            .map_err(recorder_error)?;
        Ok(status.into())
    }

    /// Ends the replay (CARLA's `stop_replayer`): with `keep_actors` the
    /// replayed world goes on live, otherwise the world from before the
    /// replay comes back.
    #[pyo3(signature = (keep_actors = false))]
    fn stop_replayer(&self, py: Python<'_>, keep_actors: bool) -> PyResult<RecorderStatus> {
        let status =
            detached(py, &self.inner, |c| c.stop_replayer(keep_actors)).map_err(recorder_error)?;
        Ok(status.into())
    }
}

/// A recording's header: who wrote it, from which world, scene and settings.
#[pyclass(module = "simbus", frozen, get_all)]
#[derive(Debug, Clone)]
pub(crate) struct RecordingHeader {
    /// The recording format's version.
    recording_version: u32,
    /// The simbus version that wrote it.
    simbus_version: String,
    /// The wire protocol version of the writer.
    protocol_version: u32,
    /// The world's name.
    world: String,
    /// The scene of the episode the recording started in.
    scene: String,
    /// The seed the scene was built with.
    seed: u64,
    /// The settings in force when the recording started.
    settings: Settings,
    /// The frame the recording starts at.
    start_frame: u64,
    /// Its simulation time, integer nanoseconds.
    start_elapsed_ns: u64,
    /// Its episode.
    episode: u64,
    /// Wall-clock seconds since the Unix epoch at the start.
    start_platform_timestamp: f64,
    /// Whether sensor captures are recorded.
    sensors: bool,
    /// Simulation seconds between keyframes.
    keyframe_seconds: f64,
}

/// The frames one episode contributed to a recording.
#[pyclass(module = "simbus", frozen, get_all)]
#[derive(Debug, Clone)]
pub(crate) struct RecordedEpisode {
    /// The episode.
    episode: u64,
    /// Its frames in the recording.
    frames: u64,
    /// Its first recorded frame id.
    first_frame: u64,
    /// Its last recorded frame id.
    last_frame: u64,
}

impl From<&EpisodeFrames> for RecordedEpisode {
    fn from(e: &EpisodeFrames) -> Self {
        Self {
            episode: e.episode,
            frames: e.frames,
            first_frame: e.first_frame,
            last_frame: e.last_frame,
        }
    }
}

/// What a recording holds (`simbus.recording.info(path)`; CARLA's
/// `show_recorder_file_info`).
#[pyclass(module = "simbus", frozen, get_all)]
#[derive(Debug, Clone)]
pub(crate) struct RecordingInfo {
    /// The file.
    path: String,
    /// Its header: versions, world, scene, seed, settings, start.
    header: RecordingHeader,
    /// Frames recorded.
    frames: u64,
    /// The first recorded frame id (of the first episode).
    first_frame: u64,
    /// The last recorded frame id (of the last episode).
    last_frame: u64,
    /// The frames of each episode the recording covers, in order.
    episode_list: Vec<RecordedEpisode>,
    /// Simulation seconds covered (summed over episodes).
    duration_seconds: f64,
    /// Episodes begun during the recording (loads and reloads).
    episodes: u64,
    /// Commands recorded.
    commands: u64,
    /// Actors spawned by commands.
    actors_spawned: u64,
    /// Actors destroyed by commands.
    actors_destroyed: u64,
    /// The most actors in one frame.
    max_actors: u64,
    /// Sensors spawned.
    sensors: u64,
    /// Sensor captures recorded.
    captures: u64,
    /// Collisions.
    collisions: u64,
    /// Keyframes.
    keyframes: u64,
    /// Settings changes.
    settings_changes: u64,
    /// The file's size in bytes.
    bytes: u64,
    /// Bytes of frames, commands and captures before compression.
    raw_bytes: u64,
    /// `raw_bytes / bytes`.
    compression_ratio: f64,
    /// The file is still being recorded, or was not closed (its server was
    /// killed): every complete chunk was read.
    truncated: bool,
    /// Why the recording stopped, if it was closed.
    stopped: Option<String>,
    /// With `show_all`: every frame as (frame, episode, elapsed_seconds,
    /// delta_seconds, substeps, actors); empty otherwise.
    frame_list: Vec<(u64, u64, f64, f64, u32, u32)>,
}

impl From<FileInfo> for RecordingInfo {
    fn from(i: FileInfo) -> Self {
        let h = i.header;
        Self {
            path: i.path,
            header: RecordingHeader {
                recording_version: h.recording_version,
                simbus_version: h.simbus_version,
                protocol_version: h.protocol_version,
                world: h.world,
                scene: h.scene,
                seed: h.seed,
                settings: WorldSettings::from(h.settings).into(),
                start_frame: h.start_frame,
                start_elapsed_ns: h.start_elapsed_ns,
                episode: h.episode,
                start_platform_timestamp: h.start_platform_timestamp,
                sensors: h.sensors,
                keyframe_seconds: h.keyframe_seconds,
            },
            frames: i.frames,
            first_frame: i.first_frame,
            last_frame: i.last_frame,
            episode_list: i.episode_list.iter().map(RecordedEpisode::from).collect(),
            duration_seconds: i.duration_seconds,
            episodes: i.episodes,
            commands: i.commands,
            actors_spawned: i.actors_spawned,
            actors_destroyed: i.actors_destroyed,
            max_actors: i.max_actors,
            sensors: i.sensors,
            captures: i.captures,
            collisions: i.collisions,
            keyframes: i.keyframes,
            settings_changes: i.settings_changes,
            bytes: i.bytes,
            raw_bytes: i.raw_bytes,
            compression_ratio: i.compression_ratio,
            truncated: i.truncated,
            stopped: i.stopped,
            frame_list: i
                .frame_list
                .iter()
                .map(|f| {
                    let (e, t, d) = (f.episode, f.elapsed_seconds, f.delta_seconds);
                    (f.frame, e, t, d, f.substeps, f.actors)
                })
                .collect(),
        }
    }
}

#[pymethods]
impl RecordingInfo {
    fn __repr__(&self) -> String {
        format!(
            "RecordingInfo(path={:?}, frames={}, first_frame={}, last_frame={}, duration_seconds={:?}, episodes={}, world={:?}, scene={:?})",
            self.path,
            self.frames,
            self.first_frame,
            self.last_frame,
            self.duration_seconds,
            self.episodes,
            self.header.world,
            self.header.scene
        )
    }
}

/// What the recording at `path` holds, read without a server; with
/// `show_all`, every frame too (`frame_list`). A file that is not a
/// readable simbus recording raises `simbus.Error` saying why.
#[pyfunction]
#[pyo3(signature = (path, show_all = false))]
fn recording_info(py: Python<'_>, path: PathBuf, show_all: bool) -> PyResult<RecordingInfo> {
    let Some(path) = path.to_str() else {
        return Err(PyValueError::new_err(format!(
            "the path {} is not UTF-8",
            path.display()
        )));
    };
    let info = py
        .detach(|| inspect::file_info(path, show_all))
        .map_err(|e| raise("Error", message(&e)))?;
    Ok(info.into())
}

/// Adds this module's classes and functions to the extension module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<RecorderStatus>()?;
    m.add_class::<ReplayStatus>()?;
    m.add_class::<RecordingHeader>()?;
    m.add_class::<RecordedEpisode>()?;
    m.add_class::<RecordingInfo>()?;
    m.add_function(wrap_pyfunction!(recording_info, m)?)?;
    Ok(())
}
