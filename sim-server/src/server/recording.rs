//! What recording and replaying do to the whole server: start a recording
//! from the current frame, swap a replay's world in and out, and produce a
//! replayed frame in place of a computed one.

use std::time::Instant;

use shared_types::recording::{
    RecordedEvent, RecordingHeader, DEFAULT_KEYFRAME_SECONDS, RECORDING_VERSION,
};
use shared_types::{FrameHeader, PathText, RecorderResponse, SensorEnd, PROTOCOL_VERSION};
use tracing::{info, warn};

use super::{platform_timestamp, Domains};
use crate::clock::Clock;
use crate::replayer::{Prepared, SavedWorld, SensorChange};
use crate::ServerError;

impl Domains {
    /// Starts recording to `path` from the current frame.
    pub(crate) fn start_recording(&mut self, path: &str, sensors: bool) -> Result<(), String> {
        let header = RecordingHeader {
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
        };
        let frame = self.frame_header(0, 0);
        let scene = self.runtime.scene.to_string();
        // The sensors alive now are part of the recording, before its first frame.
        let sensors = self.sensors.recorded_spawns(self.clock.frame());
        self.recorder
            .start(path, header, sensors, (&frame, &self.world), scene)
    }

    /// Checks the recording, then replaces the world with the one the
    /// replay starts from (the live one is put aside), as a new episode.
    /// The first replayed frame comes with the next step (the next tick in
    /// synchronous mode).
    pub(crate) fn start_replay(&mut self, prepared: Prepared) {
        let path = prepared.path().to_string();
        let (world, clock, scene) = self.replayer.begin(prepared);
        self.sensors.end_all(
            SensorEnd::EpisodeEnded,
            self.clock.frame(),
            self.runtime.episode,
        );
        let live = SavedWorld {
            world: std::mem::replace(&mut self.world, world),
            clock: std::mem::replace(&mut self.clock, clock),
            scene: std::mem::replace(&mut self.runtime.scene, scene),
        };
        self.replayer.saved = Some(live);
        self.runtime.episode += 1;
        self.runtime.pacer.reset();
        self.lockstep.new_episode();
        info!(
            path,
            episode = self.runtime.episode,
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
    pub(crate) fn stop_replay(&mut self, keep_actors: bool) -> Result<(), ServerError> {
        self.replayer.end(
            shared_types::ReplayState::Stopped,
            "stopped by a client".to_string(),
        );
        self.leave_replay(keep_actors)
    }

    /// After a replay: keep its world live, or bring back the one from before.
    fn leave_replay(&mut self, keep_actors: bool) -> Result<(), ServerError> {
        self.replayer.sensor_ids.clear();
        let saved = self.replayer.saved.take();
        self.sensors.end_all(
            SensorEnd::EpisodeEnded,
            self.clock.frame(),
            self.runtime.episode,
        );
        let clock = match (keep_actors, saved) {
            (false, Some(saved)) => {
                self.world = saved.world;
                self.runtime.scene = saved.scene;
                saved.clock
            }
            _ => self.clock.clone(),
        };
        // The clock goes on from its frame, its wall time from now: a
        // variable step must not span the replay.
        self.clock = Clock::at(
            clock.frame(),
            clock.elapsed_ns(),
            clock.delta_ns(),
            Instant::now(),
        );
        self.runtime.episode += 1;
        self.runtime.pacer.reset();
        self.lockstep.new_episode();
        info!(
            keep_actors,
            episode = self.runtime.episode,
            "replay over; the world goes on live"
        );
        self.publish(0, 0)?;
        self.frames.notify()
    }

    /// Produces the next replayed frame in place of a computed one.
    pub(crate) fn replay_frame(&mut self, now: Instant, ticks: usize) -> Result<(), ServerError> {
        let delta_ns = self.clock.next_delta_ns(&self.runtime.settings, now);
        let Some(frame) = self.replayer.next_frame(&mut self.world, delta_ns) else {
            // Nothing more to replay.
            self.leave_replay(self.replayer.keep_actors)?;
            self.ticker.answer_stepped(ticks, &self.clock);
            return Ok(());
        };
        if frame.new_episode {
            // A recorded load or reload: a new episode here too, so every
            // (episode, frame) a client sees is new.
            self.sensors.end_all(
                SensorEnd::EpisodeEnded,
                self.clock.frame(),
                self.runtime.episode,
            );
            self.runtime.episode += 1;
            self.lockstep.new_episode();
        }
        let t = frame.header.timestamp;
        self.clock = Clock::at_timestamp(&t, now);
        self.runtime.frames_computed += 1;
        self.replay_sensors();
        if !self.sensors.is_empty() {
            self.world.sync_queries();
        }
        self.sensors.capture(
            &self.world,
            self.clock.frame(),
            self.clock.elapsed_ns(),
            self.runtime.episode,
            None,
        );
        let header = FrameHeader {
            episode: self.runtime.episode,
            flags: frame.header.flags | FrameHeader::REPLAY,
            server_pid: shared_types::this_process_id(),
            timestamp: shared_types::Timestamp {
                platform_timestamp: platform_timestamp(),
                ..t
            },
            actor_count: frame.actors.len() as u32,
            // The settings frames are delivered under are the server's.
            settings: self.runtime.settings.into(),
            ..frame.header
        };
        self.frames.publish_states(header, &frame.actors)?;
        self.ticker.answer_stepped(ticks, &self.clock);
        self.frames.notify()?;
        if frame.last {
            info!(frame = t.frame, "replay finished");
            self.leave_replay(self.replayer.keep_actors)?;
        }
        Ok(())
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

    /// The recorder service's view of the recorder and the replayer.
    pub(crate) fn recorder_status(&self, mut response: RecorderResponse) -> RecorderResponse {
        match self.recorder.progress() {
            Some((path, frames)) => {
                response.recording = 1;
                response.frames_written = frames;
                response.path = PathText::cut(path);
            }
            None => {
                let last = &self.recorder.last;
                response.frames_written = last.frames;
                response.bytes_written = last.bytes;
                response.path = PathText::cut(&last.path);
                if let Some(error) = &last.error {
                    response.message = PathText::cut(error);
                }
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
        if response.message.len == 0 && !report.message.is_empty() {
            response.message = PathText::cut(&report.message);
        }
        response
    }

    /// Records that a new episode began (load or reload).
    pub(crate) fn record_episode(&mut self, reset_settings: bool) {
        self.recorder.event(RecordedEvent::Episode {
            episode: self.runtime.episode,
            scene: self.runtime.scene.to_string(),
            first_actor_id: self.world.first_id(),
            reset_settings,
        });
    }
}
