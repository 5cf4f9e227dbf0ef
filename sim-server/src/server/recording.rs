//! What recording and replaying do to the whole server: start a recording
//! from the current frame, swap a replay's world in and out, and produce a
//! replayed frame in place of a computed one.

use std::time::Instant;

use shared_types::{
    FrameHeader, PathText, RecorderKind, RecorderResponse, ReplayMode, ResponseStatus, SensorEnd,
    PROTOCOL_VERSION,
};
use simbus_recording::{
    RecordedEvent, RecordingHeader, DEFAULT_KEYFRAME_SECONDS, RECORDING_VERSION,
};
use tracing::{info, warn};

use super::error::ServerError;
use super::Domains;
use super::Outgoing;
use crate::clock::{platform_timestamp, Clock};
use crate::error::PortError;
use crate::recorder::{RecorderCall, Refused};
use crate::replayer::{
    Prepared, ReplayFrame, ReplayRefused, ReplayRequest, SavedWorld, SensorChange,
};

impl Domains {
    /// Carries out a decoded recorder request from `client_pid` and answers
    /// it; `None` for a replay being prepared, answered once it is (see
    /// [`Domains::replay_prepared`]).
    pub(super) fn answer_recorder(
        &mut self,
        call: RecorderCall,
        client_pid: u32,
    ) -> Option<RecorderResponse> {
        let (kind, done) = match call {
            RecorderCall::Refuse(status) => {
                let response = RecorderResponse::new(status);
                return Some(self.recorder_status(RecorderKind::Status, response));
            }
            RecorderCall::Status => (RecorderKind::Status, Ok(())),
            RecorderCall::Start { path, sensors } => {
                (RecorderKind::Start, self.start_recording(path, sensors))
            }
            RecorderCall::Stop => {
                let stopped = self.recorder.stop("stop", self.clock.frame()).is_some();
                let done = match (stopped, self.recorder.last.failure()) {
                    (true, _) => Ok(()),
                    (false, Some(failure)) => Err(Refused::StoppedByItself(failure)),
                    (false, None) => Err(Refused::NotRecording),
                };
                (RecorderKind::Stop, done)
            }
            RecorderCall::Replay(request) => match self.prepare_replay(request) {
                Ok(()) => return None,
                Err(refused) => (RecorderKind::Replay, Err(refused)),
            },
            RecorderCall::StopReplay { keep_actors } => {
                let done = if self.replayer.is_running() || self.replayer.saved.is_some() {
                    self.stop_replay(keep_actors).map_err(Refused::StopReplay)
                } else {
                    Err(ReplayRefused::NotReplaying.into())
                };
                (RecorderKind::StopReplay, done)
            }
            RecorderCall::TimeFactor(factor) => (
                RecorderKind::TimeFactor,
                self.replayer.set_time_factor(factor).map_err(Refused::from),
            ),
        };
        Some(self.reply(kind, client_pid, done))
    }

    /// The answer to the replay request whose preparation finished, if one
    /// did: the replay starts, or is refused.
    pub(super) fn replay_prepared(&mut self) -> Option<RecorderResponse> {
        let prepared = self.replayer.prepared()?;
        let done = prepared
            .map_err(Refused::from)
            .map(|prepared| self.start_replay(prepared));
        Some(self.reply(RecorderKind::Replay, 0, done))
    }

    /// The answer to a request of `kind` that did `done`.
    fn reply(
        &self,
        kind: RecorderKind,
        client_pid: u32,
        done: Result<(), Refused>,
    ) -> RecorderResponse {
        match done {
            Ok(()) => self.recorder_status(kind, RecorderResponse::new(ResponseStatus::Ok)),
            Err(refused) => {
                let message = crate::error::message(&refused);
                info!(client_pid, ?kind, "refused: {message}");
                let mut response =
                    self.recorder_status(kind, RecorderResponse::new(ResponseStatus::Refused));
                response.refusal = refused.code() as u32;
                response.message = PathText::cut(&message);
                response
            }
        }
    }

    /// Checks a replay request against what runs, then has the replayer
    /// read its recording off the frame loop.
    fn prepare_replay(&mut self, request: Result<ReplayRequest, Refused>) -> Result<(), Refused> {
        if let Some(path) = self.replayer.preparing() {
            return Err(ReplayRefused::AlreadyPreparing(path.to_string()).into());
        }
        if self.replayer.is_running() {
            return Err(Refused::AlreadyReplaying(self.replayer.report.path.clone()));
        }
        if let Some((path, _)) = self.recorder.progress() {
            return Err(Refused::Recording(path.to_string()));
        }
        Ok(self.replayer.prepare_in_background(request?)?)
    }

    /// Starts recording to `path` from the current frame, unless a
    /// recording or a replay (or its preparation) runs.
    fn start_recording(
        &mut self,
        path: Result<String, Refused>,
        sensors: bool,
    ) -> Result<(), Refused> {
        if let Some(path) = self.replayer.preparing() {
            return Err(Refused::PreparingReplay(path.to_string()));
        }
        if let Some((path, _)) = self.recorder.progress() {
            return Err(Refused::AlreadyRecording(path.to_string()));
        }
        if self.replayer.is_running() {
            return Err(Refused::ReplayRuns);
        }
        let path = path?;
        let header = self.recording_header(sensors);
        // The current frame as it was published (its substeps, flags and
        // time), with the actors the world holds now.
        let now = self.frame_header(0, 0);
        let frame = match self
            .recorder
            .last_published(now.timestamp.frame, now.episode)
        {
            Some(published) => FrameHeader {
                actor_count: now.actor_count,
                first_actor_id: now.first_actor_id,
                ..published
            },
            None => now,
        };
        let scene = self.runtime.scene.to_string();
        // The sensors alive now are part of the recording, before its first frame.
        let sensors = self.sensors.recorded_spawns(self.clock.frame());
        self.recorder
            .start(&path, header, sensors, (&frame, &self.world), scene)
            .map_err(Refused::CannotWrite)
    }

    /// The header of a recording (or a journal segment) starting now.
    pub(super) fn recording_header(&self, sensors: bool) -> RecordingHeader {
        RecordingHeader {
            recording_version: RECORDING_VERSION,
            simbus_version: env!("CARGO_PKG_VERSION").to_string(),
            protocol_version: PROTOCOL_VERSION,
            world: self.config.world.to_string(),
            scene: self.runtime.scene.to_string(),
            seed: self.config.seed,
            settings: self.runtime.settings.into(),
            start_frame: self.clock.frame(),
            start_elapsed_ns: self.clock.elapsed_ns(),
            episode: self.runtime.episode,
            start_platform_timestamp: platform_timestamp(),
            sensors,
            keyframe_seconds: self
                .config
                .keyframe_seconds
                .unwrap_or(DEFAULT_KEYFRAME_SECONDS),
            journal_sync_frames: 0,
            run_pid: self.runtime.run_pid,
        }
    }

    /// Spawns the sensors a journal left alive again, under their ids.
    pub(super) fn resume_sensors(&mut self, resumed: &crate::journal::resume::Resumed) {
        self.respawn_sensors(&resumed.sensors);
        self.sensors.go_on_after(resumed.last_sensor_id);
        // Their spawns go into the journal's next segment with its start.
        self.sensors.take_journal().for_each(drop);
    }

    /// Spawns `sensors` again under their ids (a resume, a restore).
    pub(super) fn respawn_sensors(&mut self, sensors: &[(u64, shared_types::SensorSpec)]) {
        for (id, spec) in sensors {
            match self
                .sensors
                .respawn(&self.transport, *id, *spec, &self.world, &self.clock)
            {
                Ok(_) => info!(id, "sensor spawned again"),
                Err(refusal) => warn!(id, "sensor not spawned again: {refusal}"),
            }
        }
    }

    /// Replaces the world with the one the
    /// replay starts from (the live one is put aside). The live sensors
    /// end now; the first replayed frame comes with the next step (the
    /// next tick in synchronous mode), as the next frame id and the first
    /// of a new episode: frame ids on the bus never go back, so lockstep
    /// participants and readers follow a replay like any other frames.
    fn start_replay(&mut self, prepared: Prepared) {
        let path = prepared.path().to_string();
        let (world, scene) = self.replayer.begin(prepared);
        self.sensors.end_all(
            SensorEnd::EpisodeEnded,
            self.clock.frame(),
            self.runtime.episode,
        );
        let live = SavedWorld {
            world: std::mem::replace(&mut self.world, world),
            scene: std::mem::replace(&mut self.runtime.scene, scene),
        };
        self.replayer.saved = Some(live);
        self.runtime.pacer.reset();
        info!(
            path,
            frame = self.clock.frame() + 1,
            "replay starts with the next {}",
            if self.runtime.settings.synchronous_mode {
                "tick"
            } else {
                "frame"
            }
        );
    }

    /// Stops the replay: with `keep_actors` the replayed world goes on live
    /// from where it is; otherwise the world from before the replay comes
    /// back. Either way a new episode starts and its frame is published.
    fn stop_replay(&mut self, keep_actors: bool) -> Result<(), PortError> {
        self.replayer.end(
            shared_types::ReplayState::Stopped,
            "stopped by a client".to_string(),
        );
        self.leave_replay(keep_actors)
    }

    /// After a replay: keep its world live, or bring back the one from
    /// before, published at once as the next frame id (in no simulation
    /// time) and the first frame of a new episode.
    fn leave_replay(&mut self, keep_actors: bool) -> Result<(), PortError> {
        self.replayer.sensor_ids.clear();
        let saved = self.replayer.saved.take();
        self.sensors.end_all(
            SensorEnd::EpisodeEnded,
            self.clock.frame(),
            self.runtime.episode,
        );
        if let (false, Some(saved)) = (keep_actors, saved) {
            self.world = saved.world;
            self.runtime.scene = saved.scene;
        }
        // Frame ids go on; a variable step counts wall time from now, not
        // across the replay.
        self.clock = Clock::at(
            self.clock.frame() + 1,
            self.clock.elapsed_ns(),
            0,
            Instant::now(),
        );
        self.runtime.episode += 1;
        self.debug.new_episode();
        self.runtime.source_offset = None;
        self.runtime.pacer.reset();
        self.journal_episode(None);
        info!(
            keep_actors,
            episode = self.runtime.episode,
            frame = self.clock.frame(),
            "replay over; the world goes on live"
        );
        self.publish(0, 0)?;
        self.publication.notify()
    }

    /// Produces the next replayed frame in place of a computed one.
    pub(super) fn replay_frame(&mut self, now: Instant, ticks: usize) -> Result<(), ServerError> {
        let delta_ns = self.clock.next_delta_ns(&self.runtime.settings, now);
        let Some(frame) = self.replayer.next_frame(&mut self.world, delta_ns) else {
            // Nothing more to replay.
            self.leave_replay(self.replayer.keep_actors)?;
            self.ticker
                .answer_stepped(ticks, &self.clock, self.runtime.settings.synchronous_mode);
            return Ok(());
        };
        if frame.new_episode {
            // The replay's first frame, or a recorded load or reload: a new
            // episode here too. The live sensors ended when the replay
            // started; a recorded load ends the replayed ones.
            if self.replayer.report.produced > 1 {
                self.sensors.end_all(
                    SensorEnd::EpisodeEnded,
                    self.clock.frame(),
                    self.runtime.episode,
                );
            }
            self.runtime.episode += 1;
            self.debug.new_episode();
        }
        let recorded = frame.header.timestamp;
        // The server's own next frame: exact and resimulate step by the
        // recorded delta, interpolate by the server's own step.
        let step = match self.replayer.report.mode {
            ReplayMode::Interpolate => delta_ns,
            ReplayMode::Exact | ReplayMode::Resimulate => recorded.delta_ns,
        };
        self.clock.advance(step, now);
        self.runtime.frames_computed += 1;
        self.replay_sensors();
        if !self.sensors.is_empty() {
            self.world.sync_queries();
        }
        self.finish_frame(Outgoing::Replayed(&frame), ticks)?;
        if frame.last {
            info!(
                frame = self.clock.frame(),
                recorded_frame = recorded.frame,
                "replay finished"
            );
            self.leave_replay(self.replayer.keep_actors)?;
        }
        Ok(())
    }

    /// The header a replayed frame is published under: the recorded
    /// frame's, numbered and timed as this server's next frame.
    pub(super) fn replayed_header(&self, frame: &ReplayFrame) -> FrameHeader {
        let recorded = frame.header.timestamp;
        FrameHeader {
            episode: self.runtime.episode,
            // A recording of an older protocol replays as this one's frames.
            protocol_version: PROTOCOL_VERSION,
            sensor_rays: self.sensors.rays(),
            flags: frame.header.flags | FrameHeader::REPLAY | FrameHeader::STEPPED,
            server_pid: shared_types::this_process_id(),
            timestamp: shared_types::Timestamp {
                frame: self.clock.frame(),
                elapsed_ns: self.clock.elapsed_ns(),
                delta_ns: self.clock.delta_ns(),
                platform_timestamp: platform_timestamp(),
            },
            recorded_frame: recorded.frame,
            recorded_elapsed_ns: recorded.elapsed_ns,
            actor_count: frame.actors.len() as u32,
            // The settings frames are delivered under are the server's.
            settings: self.runtime.settings.into(),
            ..frame.header
        }
    }

    /// Spawns the recorded sensors that appeared (riding on the same
    /// recorded actors), and destroys those that ended.
    fn replay_sensors(&mut self) {
        for change in self.replayer.sensor_changes() {
            match change {
                SensorChange::Spawned(recorded, spec) => {
                    match self
                        .sensors
                        .spawn(&self.transport, spec, &self.world, &self.clock)
                    {
                        Ok(info) => {
                            info!(recorded, id = info.id, "recorded sensor spawned again");
                            self.replayer.sensor_ids.push((recorded, info.id));
                        }
                        Err(refusal) => warn!(recorded, "recorded sensor not replayed: {refusal}"),
                    }
                }
                SensorChange::Ended(recorded) => {
                    if let Some(at) = self
                        .replayer
                        .sensor_ids
                        .iter()
                        .position(|(r, _)| *r == recorded)
                    {
                        let (_, id) = self.replayer.sensor_ids.remove(at);
                        self.sensors
                            .destroy(id, self.clock.frame(), self.runtime.episode);
                    }
                }
            }
        }
    }

    /// The recorder service's view of the recorder and the replayer, as
    /// the answer to a request of `kind`. Its message is the recorder's
    /// last error for `start` and `stop`, the replay's (why it ended) for
    /// requests about the replay, either for `status`: a replay stopped
    /// long ago is no warning about a recording.
    fn recorder_status(
        &self,
        kind: RecorderKind,
        mut response: RecorderResponse,
    ) -> RecorderResponse {
        let failure = self.recorder.last.failure();
        let mut recorder_error = None;
        match self.recorder.progress() {
            Some((path, frames)) => {
                response.recording = 1;
                response.flags |= RecorderResponse::RECORDED;
                response.frames_written = frames;
                response.path = PathText::cut(path);
            }
            None => {
                let last = &self.recorder.last;
                response.frames_written = last.frames;
                response.bytes_written = last.bytes;
                response.path = PathText::cut(&last.path);
                if !last.path.is_empty() {
                    response.flags |= RecorderResponse::RECORDED;
                }
                recorder_error = failure.as_deref();
            }
        }
        let report = &self.replayer.report;
        response.replay_state = report.state as u32;
        response.replay_mode = report.mode as u32;
        response.replay_frames = report.frames;
        response.replay_total = report.total;
        response.verified_frames = report.verified;
        if let Some((frame, actor)) = report.mismatch {
            response.mismatch = 1;
            response.mismatch_frame = frame;
            response.mismatch_actor = actor;
        }
        response.time_factor = report.time_factor;
        if self.recorder.progress().is_none() && !report.path.is_empty() && response.path.len == 0 {
            response.path = PathText::cut(&report.path);
        }
        let replay_message = (!report.message.is_empty()).then_some(report.message.as_str());
        let message = match kind {
            RecorderKind::Start | RecorderKind::Stop => recorder_error,
            RecorderKind::Replay | RecorderKind::StopReplay | RecorderKind::TimeFactor => {
                replay_message
            }
            RecorderKind::Status => recorder_error.or(replay_message),
        };
        if let Some(message) = message {
            response.message = PathText::cut(message);
        }
        response
    }

    /// Records that a new episode began (load or reload).
    pub(super) fn record_episode(&mut self, reset_settings: bool) {
        let event = RecordedEvent::Episode {
            episode: self.runtime.episode,
            scene: self.runtime.scene.to_string(),
            first_actor_id: self.world.first_id(),
            reset_settings,
        };
        self.journal_episode(Some(event.clone()));
        self.recorder.event(event);
    }

    /// A new episode began: the journal notes it (when it is a load or a
    /// reload) and keyframes its first frame, so a resume never needs to
    /// re-simulate across it.
    pub(super) fn journal_episode(&mut self, event: Option<RecordedEvent>) {
        if let Some(journal) = &mut self.journal {
            if let Some(event) = event {
                journal.recorder().event(event);
            }
            journal.recorder().keyframe_next();
        }
    }
}
