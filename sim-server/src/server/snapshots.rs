//! What saving and restoring a snapshot do to the whole server.

use std::time::Instant;

use shared_types::{
    ControlResponse, FrameHeader, ResponseStatus, SensorEnd, SnapshotInfo, WorldSettings,
};
use tracing::{info, warn};

use super::Domains;
use crate::clock::Clock;
use crate::snapshots::Snapshot;

impl Domains {
    /// Whether `pid` may save or restore: the ticker's process while one
    /// holds the world, anyone otherwise; never while a replay runs.
    fn may_snapshot(&self, pid: u32, what: &str) -> Result<(), ResponseStatus> {
        if let Some(ticker) = self.ticker.owner_pid() {
            if ticker != pid {
                info!(
                    client_pid = pid,
                    ticker, "refused to {what} a snapshot: the ticker holds the world"
                );
                return Err(ResponseStatus::NotTicker);
            }
        }
        if self.replayer.is_running() || self.replayer.preparing().is_some() {
            info!(
                client_pid = pid,
                "refused to {what} a snapshot: a replay runs"
            );
            return Err(ResponseStatus::Replaying);
        }
        Ok(())
    }

    /// Saves the world as it is after the current frame.
    pub(super) fn save_snapshot(&mut self, pid: u32) -> ControlResponse {
        if let Err(status) = self.may_snapshot(pid, "save") {
            return ControlResponse::refused(status, self.report());
        }
        if self.snapshots.is_full() {
            return ControlResponse::refused(ResponseStatus::SnapshotsFull, self.report());
        }
        let header = self.frame_header(0, 0);
        let sensors = self.sensors.alive();
        let info = SnapshotInfo {
            id: 0,
            frame: self.clock.frame(),
            source_frame: header.source_timestamp().frame,
            episode: self.runtime.episode,
            elapsed_ns: self.clock.elapsed_ns(),
            actors: self.world.actor_count() as u32,
            sensors: sensors.len() as u32,
        };
        let snapshot = Snapshot {
            info,
            world: self.world.duplicate(),
            scene: self.runtime.scene,
            settings: self.runtime.settings,
            delta_ns: self.clock.delta_ns(),
            sensors,
        };
        let info = self.snapshots.keep(snapshot);
        info!(
            client_pid = pid,
            id = info.id,
            frame = info.frame,
            actors = info.actors,
            "snapshot saved"
        );
        ControlResponse {
            snapshot: info.id,
            ..ControlResponse::ok(self.report())
        }
    }

    /// Restores snapshot `id` as a new episode, published at once as the
    /// next frame id: the world, time, ids, sensors and settings are the
    /// snapshot's (synchronous mode stays as it is: it is the ticker's).
    pub(super) fn restore_snapshot(&mut self, id: u64, pid: u32) -> ControlResponse {
        if let Err(status) = self.may_snapshot(pid, "restore") {
            return ControlResponse::refused(status, self.report());
        }
        let Some(snapshot) = self.snapshots.get(id) else {
            return ControlResponse::refused(ResponseStatus::UnknownSnapshot, self.report());
        };
        let world = snapshot.world.duplicate();
        let (info, scene, delta_ns) = (snapshot.info, snapshot.scene, snapshot.delta_ns);
        let settings = WorldSettings {
            synchronous_mode: self.runtime.settings.synchronous_mode,
            ..snapshot.settings
        };
        let sensors = snapshot.sensors.clone();
        self.sensors.end_all(
            SensorEnd::EpisodeEnded,
            self.clock.frame(),
            self.runtime.episode,
        );
        self.note_sensors();
        self.world = world;
        self.runtime.scene = scene;
        if settings != self.runtime.settings {
            info!("settings restored with the snapshot: {settings}");
            self.runtime.settings = settings;
        }
        let frame = self.clock.frame() + 1;
        self.clock = Clock::at(frame, info.elapsed_ns, delta_ns, Instant::now());
        self.runtime.source_offset = Some(frame - info.source_frame);
        self.runtime.episode += 1;
        self.debug.new_episode();
        self.runtime.pacer.reset();
        self.lockstep.new_episode();
        self.respawn_sensors(&sensors);
        self.journal_episode(None);
        self.recorder.keyframe_next();
        info!(
            client_pid = pid,
            id,
            frame,
            from_frame = info.frame,
            episode = self.runtime.episode,
            "snapshot restored"
        );
        if let Err(e) = self.publish(0, 0).and_then(|()| self.publication.notify()) {
            warn!("publishing the restored frame failed: {e}");
        }
        ControlResponse {
            snapshot: id,
            ..ControlResponse::ok(self.report())
        }
    }

    /// The header fields a frame of a restored line carries.
    pub(super) fn restored_fields(&self, header: &mut FrameHeader) {
        if let Some(offset) = self.runtime.source_offset {
            header.flags |= FrameHeader::RESTORED;
            header.recorded_frame = self.clock.frame().saturating_sub(offset);
            header.recorded_elapsed_ns = self.clock.elapsed_ns();
        }
    }
}
