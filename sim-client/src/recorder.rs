//! The recorder and the replayer, CARLA's API: `start_recorder`,
//! `stop_recorder`, `replay_file`, `set_replayer_time_factor`,
//! `stop_replayer`, all answered with a [`RecorderStatus`].
//!
//! Reading a recording without a server (CARLA's `show_recorder_*`) is in
//! the `simbus-recording` crate's `inspect` module, which keeps MCAP out of
//! this library.

use std::path::{Path, PathBuf};
use std::time::Duration;

use iceoryx2::prelude::*;
use serde::Serialize;
use shared_types::{
    PathText, RecorderKind, RecorderRefusal, RecorderRequest, RecorderResponse, ReplayMode,
    ReplayState, ResponseStatus,
};
use simbus_transport::spec::WorldServices;

use crate::rpc::{client_error, RequestPort, Wait};
use crate::{Client, RequestError};

/// The longest a replay request waits for the server to read its recording
/// through (a few GiB take seconds).
pub const REPLAY_READ_TIMEOUT: Duration = Duration::from_secs(600);

/// The recorder service's request port.
pub(crate) type RecorderClient = RequestPort<RecorderRequest, RecorderResponse>;

/// Why a recorder request failed.
#[derive(Debug, thiserror::Error)]
pub enum RecorderError {
    /// The server refused; nothing changed. The message says why in words.
    #[error("{message}")]
    Refused {
        /// Why, as a code.
        refusal: RecorderRefusal,
        /// Why, in words (from the server).
        message: String,
    },
    /// The path is longer than the wire carries.
    #[error("the path is longer than {} bytes", PathText::CAPACITY)]
    PathTooLong,
    /// The request failed.
    #[error(transparent)]
    Request(#[from] RequestError),
}

/// How a replay goes (or went).
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct ReplayStatus {
    /// `idle`, `running`, `finished`, `stopped` or `failed`.
    pub state: &'static str,
    /// `exact`, `interpolate` or `resimulate`.
    pub mode: &'static str,
    /// Frames replayed so far.
    pub frames: u64,
    /// Frames the replay covers.
    pub total: u64,
    /// Resimulate: frames whose state matched the recording bit for bit.
    pub verified: u64,
    /// Resimulate: the first frame that differed, and the first actor that
    /// differed in it (0: the sets of actors differ).
    pub mismatch: Option<Mismatch>,
    /// The time factor.
    pub time_factor: f64,
}

/// Where a re-simulation first left the recording.
#[derive(Debug, Clone, Copy, PartialEq, Serialize)]
pub struct Mismatch {
    /// The frame.
    pub frame: u64,
    /// The actor (0: the actor sets differ).
    pub actor: u64,
}

/// How the recorder and the replayer are doing.
#[derive(Debug, Clone, PartialEq, Serialize)]
pub struct RecorderStatus {
    /// A recording runs.
    pub recording: bool,
    /// This server recorded since it started: `path`, `frames` and `bytes`
    /// are its current or last recording's. Otherwise `path` is the last
    /// replay's file, and there is no recording to speak of.
    pub recorded: bool,
    /// The current (or last) recording's path, as the server sees it (the
    /// last replay's file when nothing was recorded).
    pub path: String,
    /// Frames written to it.
    pub frames: u64,
    /// Its size once closed (0 while it runs).
    pub bytes: u64,
    /// The current (or last) replay.
    pub replay: ReplayStatus,
    /// What went wrong last, if anything.
    pub message: String,
}

impl ReplayStatus {
    /// The replay's [`ReplayState`], if the server sent one this version knows.
    pub fn replay_state(&self) -> ReplayState {
        ReplayState::ALL
            .into_iter()
            .find(|s| state_name(*s) == self.state)
            .unwrap_or(ReplayState::Idle)
    }
}

fn state_name(state: ReplayState) -> &'static str {
    match state {
        ReplayState::Idle => "idle",
        ReplayState::Running => "running",
        ReplayState::Finished => "finished",
        ReplayState::Stopped => "stopped",
        ReplayState::Failed => "failed",
    }
}

impl From<&RecorderResponse> for RecorderStatus {
    fn from(r: &RecorderResponse) -> Self {
        Self {
            recording: r.recording != 0,
            recorded: r.flags & RecorderResponse::RECORDED != 0,
            path: r.path.to_string_lossy(),
            frames: r.frames_written,
            bytes: r.bytes_written,
            replay: ReplayStatus {
                state: ReplayState::from_u32(r.replay_state).map_or("unknown", state_name),
                mode: ReplayMode::from_u32(r.replay_mode).map_or("unknown", |m| m.name()),
                frames: r.replay_frames,
                total: r.replay_total,
                verified: r.verified_frames,
                mismatch: (r.mismatch != 0).then_some(Mismatch {
                    frame: r.mismatch_frame,
                    actor: r.mismatch_actor,
                }),
                time_factor: r.time_factor,
            },
            message: r.message.to_string_lossy(),
        }
    }
}

/// What a replay should do: CARLA's `replay_file` arguments and simbus's mode.
#[derive(Debug, Clone, PartialEq)]
pub struct ReplayOptions {
    /// Seconds from the recording's start (negative: from its end).
    pub start: f64,
    /// Seconds to replay (0: to the end).
    pub duration: f64,
    /// Sensors spawned without a parent during the replay ride on this
    /// recorded actor (0: none).
    pub follow_id: u64,
    /// Spawn the recorded sensors again, capturing the replayed scene.
    pub replay_sensors: bool,
    /// Simulation speed relative to the recording (asynchronous mode).
    pub time_factor: f64,
    /// `None`: exact for fixed-step recordings, interpolate otherwise.
    pub mode: Option<ReplayMode>,
    /// Keep the replayed world when the replay ends.
    pub keep_actors: bool,
}

impl Default for ReplayOptions {
    fn default() -> Self {
        Self {
            start: 0.0,
            duration: 0.0,
            follow_id: 0,
            replay_sensors: false,
            time_factor: 1.0,
            mode: None,
            keep_actors: false,
        }
    }
}

/// `path` made absolute against this process's directory (the server's may
/// differ).
fn absolute(path: &Path) -> PathBuf {
    std::path::absolute(path).unwrap_or_else(|_| path.to_path_buf())
}

fn path_text(path: &Path) -> Result<PathText, RecorderError> {
    PathText::exact(&absolute(path).to_string_lossy()).ok_or(RecorderError::PathTooLong)
}

impl Client {
    /// The recorder port, opened on first use and kept.
    fn recorder_port(&self) -> Result<&RecorderClient, RequestError> {
        if let Some(port) = self.recorder_port.get() {
            return Ok(port);
        }
        let specs = WorldServices::new(&self.names)
            .map_err(|e| RequestError::transport("service name", e))?;
        let service = specs
            .recorder
            .open(&self.node)
            .map_err(|e| RequestError::transport("recorder service", e))?;
        let client = service.client_builder().create().map_err(|e| {
            let max = service.static_config().max_clients();
            client_error(
                e,
                max,
                "clients sending recorder requests",
                "recorder client",
            )
        })?;
        let port = RequestPort::new(
            client,
            None,
            specs.recorder.doorbell,
            "recorder send",
            self.world.as_str(),
            self.server_pid,
        );
        Ok(self.recorder_port.get_or_init(|| port))
    }

    fn recorder_request(&self, request: RecorderRequest) -> Result<RecorderStatus, RecorderError> {
        self.recorder_request_within(request, self.request_timeout)
    }

    fn recorder_request_within(
        &self,
        request: RecorderRequest,
        timeout: Duration,
    ) -> Result<RecorderStatus, RecorderError> {
        let answer = self
            .recorder_port()?
            .request_waking(request, self, timeout, Wait::Backoff)?;
        match ResponseStatus::from_u32(answer.status) {
            Some(ResponseStatus::Ok) => Ok(RecorderStatus::from(&answer)),
            Some(ResponseStatus::Refused) => Err(RecorderError::Refused {
                refusal: RecorderRefusal::from_u32(answer.refusal)
                    .unwrap_or(RecorderRefusal::InvalidArgument),
                message: answer.message.to_string_lossy(),
            }),
            Some(ResponseStatus::UnknownRequest) => Err(RequestError::UnknownRequest.into()),
            _ => Err(RequestError::UnknownAnswer {
                status: answer.status,
            }
            .into()),
        }
    }

    /// Starts recording the world into `path` (CARLA's `start_recorder`).
    ///
    /// `path` is an MCAP file, created by the server (made absolute here),
    /// with every sensor capture if `record_sensors`. Returns the path the
    /// server writes.
    ///
    /// # Errors
    ///
    /// Returns [`RecorderError::PathTooLong`] if the absolute path is longer
    /// than the wire carries ([`PathText::CAPACITY`] bytes);
    /// [`RecorderError::Refused`] (with a [`RecorderRefusal`] and the server's
    /// message) if a recording already runs (`AlreadyRecording`), a replay runs
    /// (`Replaying`) or the server cannot create the file (`CannotWrite`); and
    /// [`RecorderError::Request`] if the request fails
    /// ([`RequestError::Timeout`], [`RequestError::ServerGone`],
    /// [`RequestError::Full`], ...). Nothing changes when it is refused.
    ///
    /// # Examples
    ///
    /// A server runs on a thread here, so the example runs as a test:
    ///
    /// ```
    /// use std::time::Duration;
    /// use sim_client::Client;
    /// use shared_types::WorldSettings;
    ///
    /// # fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// # use std::sync::{atomic::{AtomicBool, Ordering}, Arc};
    /// # let name = format!("doc-{}-{}", "recorder", std::process::id());
    /// # let stop = Arc::new(AtomicBool::new(false));
    /// # let server = {
    /// #     let (stop, world) = (stop.clone(), shared_types::WorldName::new(&name)?);
    /// #     std::thread::spawn(move || {
    /// #         let mut config = sim_server::ServerConfig::new(world);
    /// #         config.settings.fixed_delta_seconds = Some(0.01);
    /// #         config.realtime = true;
    /// #         sim_server::Server::start(config).and_then(|mut s| s.run(&stop))
    /// #     })
    /// # };
    /// let client = Client::connect(&name, Duration::from_secs(5))?;
    /// let mut ticker = client.claim_ticker()?;
    /// let sync = WorldSettings { synchronous_mode: true, ..client.get_settings()? };
    /// ticker.apply_settings(sync)?;
    /// let path = std::env::temp_dir().join(format!("{name}.mcap"));
    /// let written = client.start_recorder(&path, false)?; // the current frame is the first
    /// for _ in 0..10 {
    ///     ticker.tick(Duration::from_secs(1))?;
    /// }
    /// let status = client.stop_recorder()?;
    /// assert_eq!(status.frames, 11);
    /// assert_eq!(std::fs::metadata(&written)?.len(), status.bytes);
    /// # std::fs::remove_file(&written)?;
    /// # drop(ticker);
    /// # stop.store(true, Ordering::Relaxed);
    /// # server.join().expect("server thread")?;
    /// # Ok(())
    /// # }
    /// ```
    pub fn start_recorder(
        &self,
        path: impl AsRef<Path>,
        record_sensors: bool,
    ) -> Result<PathBuf, RecorderError> {
        let mut request = RecorderRequest::new(RecorderKind::Start);
        request.path = path_text(path.as_ref())?;
        if record_sensors {
            request.flags |= RecorderRequest::SENSORS;
        }
        let status = self.recorder_request(request)?;
        Ok(PathBuf::from(status.path))
    }

    /// Stops the recording and closes its file; the status says how many
    /// frames and bytes it holds.
    ///
    /// # Errors
    ///
    /// Returns [`RecorderError::Refused`] with `NotRecording` if no recording
    /// runs, and [`RecorderError::Request`] if the request fails
    /// ([`RequestError::Timeout`], [`RequestError::ServerGone`], ...).
    pub fn stop_recorder(&self) -> Result<RecorderStatus, RecorderError> {
        self.recorder_request(RecorderRequest::new(RecorderKind::Stop))
    }

    /// How the recorder and the replayer are doing.
    ///
    /// # Errors
    ///
    /// Returns [`RecorderError::Request`] if the request fails
    /// ([`RequestError::Timeout`], [`RequestError::ServerGone`],
    /// [`RequestError::Full`] if the world admits no more clients sending
    /// recorder requests, ...).
    pub fn recorder_status(&self) -> Result<RecorderStatus, RecorderError> {
        self.recorder_request(RecorderRequest::new(RecorderKind::Status))
    }

    /// CARLA's `replay_file(name, start, duration, follow_id, replay_sensors)`:
    /// replays the recording at `path` in the default mode.
    ///
    /// # Errors
    ///
    /// Returns the errors of [`Client::replay`]:
    /// [`RecorderError::PathTooLong`], [`RecorderError::Refused`] (a bad file,
    /// a `start` past the end, an unknown `follow_id`, a recording or replay
    /// running), and [`RecorderError::Request`].
    pub fn replay_file(
        &self,
        path: impl AsRef<Path>,
        start: f64,
        duration: f64,
        follow_id: u64,
        replay_sensors: bool,
    ) -> Result<RecorderStatus, RecorderError> {
        self.replay(
            path,
            &ReplayOptions {
                start,
                duration,
                follow_id,
                replay_sensors,
                ..ReplayOptions::default()
            },
        )
    }

    /// Replays the recording at `path` as `options` say.
    ///
    /// The server reads the whole file first (off its frame loop; a damaged
    /// one is refused and nothing changes), so this waits up to
    /// [`REPLAY_READ_TIMEOUT`] (or the request timeout, if longer) — less if
    /// the server dies. In synchronous mode the replay starts with the next
    /// tick.
    ///
    /// # Errors
    ///
    /// Returns [`RecorderError::PathTooLong`] if the absolute path is longer
    /// than the wire carries; [`RecorderError::Refused`] (nothing changes) with
    /// `BadFile` if the file is not a readable recording, `StartPastEnd` if
    /// `options.start` is past its end, `UnknownActor` if `options.follow_id`
    /// names no recorded actor, `Recording` or `Replaying` if a recording or
    /// another replay runs, `InvalidArgument` for a value out of range (the
    /// time factor, the duration, the mode); and [`RecorderError::Request`] if
    /// the request fails ([`RequestError::Timeout`] after the wait above,
    /// [`RequestError::ServerGone`], ...).
    pub fn replay(
        &self,
        path: impl AsRef<Path>,
        options: &ReplayOptions,
    ) -> Result<RecorderStatus, RecorderError> {
        let mut request = RecorderRequest::new(RecorderKind::Replay);
        request.path = path_text(path.as_ref())?;
        request.start_seconds = options.start;
        request.duration_seconds = options.duration;
        request.follow_id = options.follow_id;
        request.time_factor = options.time_factor;
        request.mode = options.mode.map_or(0, |m| m as u32);
        if options.replay_sensors {
            request.flags |= RecorderRequest::REPLAY_SENSORS;
        }
        if options.keep_actors {
            request.flags |= RecorderRequest::KEEP_ACTORS;
        }
        self.recorder_request_within(request, self.request_timeout.max(REPLAY_READ_TIMEOUT))
    }

    /// CARLA's `set_replayer_time_factor`: the replay's speed relative to
    /// the recording (asynchronous mode).
    ///
    /// # Errors
    ///
    /// Returns [`RecorderError::Refused`] with `NotReplaying` if no replay runs
    /// or `InvalidArgument` if `factor` is out of range, and
    /// [`RecorderError::Request`] if the request fails.
    pub fn set_replayer_time_factor(&self, factor: f64) -> Result<RecorderStatus, RecorderError> {
        let mut request = RecorderRequest::new(RecorderKind::TimeFactor);
        request.time_factor = factor;
        self.recorder_request(request)
    }

    /// CARLA's `stop_replayer(keep_actors)`: ends the replay; with
    /// `keep_actors` the replayed world goes on live, otherwise the world
    /// from before the replay comes back.
    ///
    /// # Errors
    ///
    /// Returns [`RecorderError::Refused`] with `NotReplaying` if no replay
    /// runs, and [`RecorderError::Request`] if the request fails
    /// ([`RequestError::Timeout`], [`RequestError::ServerGone`], ...).
    pub fn stop_replayer(&self, keep_actors: bool) -> Result<RecorderStatus, RecorderError> {
        let mut request = RecorderRequest::new(RecorderKind::StopReplay);
        if keep_actors {
            request.flags |= RecorderRequest::KEEP_ACTORS;
        }
        self.recorder_request(request)
    }
}
