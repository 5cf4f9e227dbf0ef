//! How the loop answers a control request: the status report every answer
//! carries, settings (and who may change them while a ticker holds the
//! world) and loads.

use std::time::Instant;

use shared_types::{
    ControlResponse, FixedText, ResponseStatus, StatusReport, WireSettings, WorldSettings,
};
use tracing::{info, warn};

use super::Domains;
use crate::control::{ControlCall, WhileTicked};
use crate::state::Refusal;
use crate::ticker::Ticker;

impl Domains {
    /// The world's status as the control service reports it.
    pub(super) fn report(&self) -> StatusReport {
        StatusReport {
            frame: self.clock.frame(),
            elapsed_ns: self.clock.elapsed_ns(),
            episode: self.runtime.episode,
            server_pid: shared_types::this_process_id(),
            actor_count: self.world.actor_count() as u32,
            settings: WireSettings::from(self.runtime.settings),
            scene: FixedText::new(&self.runtime.scene.to_string()),
            ticker: self.ticker.info(),
            seed: self.config.seed,
            participants: self.lockstep.len() as u32,
            max_clients: self.config.limits.max_clients as u32,
            max_sensor_readers: self.config.limits.max_sensor_readers as u32,
            journal: match &self.journal {
                None => StatusReport::NO_JOURNAL,
                Some(j) if j.stopped.is_some() => StatusReport::JOURNAL_STOPPED,
                Some(_) => StatusReport::JOURNALING,
            },
            journal_durable_frame: self
                .journal
                .as_ref()
                .and_then(|j| j.durable)
                .map_or(0, |(_, frame)| frame),
            journal_note: FixedText::new(&self.journal.as_ref().map_or(String::new(), |j| {
                j.stopped
                    .clone()
                    .unwrap_or_else(|| j.dir().display().to_string())
            })),
            snapshots: self.snapshots.len() as u32,
            run_pid: self.runtime.run_pid,
            lockstep: self.lockstep.statuses(self.clock.frame()),
        }
    }

    /// Carries out a decoded control request and answers it.
    pub(super) fn answer_control(&mut self, call: ControlCall) -> ControlResponse {
        match call {
            ControlCall::Status => ControlResponse::ok(self.report()),
            ControlCall::Refuse(status) => ControlResponse::refused(status, self.report()),
            ControlCall::RefuseSettings(error) => {
                ControlResponse::invalid_settings(&error, self.report())
            }
            ControlCall::ApplySettings {
                settings,
                pid,
                name,
            } => self.apply_settings(settings, pid, name),
            ControlCall::SaveSnapshot { pid } => self.save_snapshot(pid),
            ControlCall::RestoreSnapshot { id, pid } => self.restore_snapshot(id, pid),
            ControlCall::ListSnapshots => ControlResponse {
                snapshots: self.snapshots.list(),
                ..ControlResponse::ok(self.report())
            },
            ControlCall::DropSnapshot { id, pid } => {
                if self.ticker.owner_pid().is_some_and(|t| t != pid) {
                    return ControlResponse::refused(ResponseStatus::NotTicker, self.report());
                }
                if self.snapshots.forget(id) {
                    info!(client_pid = pid, id, "snapshot dropped");
                    ControlResponse::ok(self.report())
                } else {
                    ControlResponse::refused(ResponseStatus::UnknownSnapshot, self.report())
                }
            }
            ControlCall::Load { scene, reset, pid } => {
                let scene = scene.unwrap_or(self.runtime.scene);
                let ticker = self.ticker.owner_pid();
                if reset && ticker.is_some() && ticker != Some(pid) {
                    // Resetting settings is a settings change: the ticker's
                    // (its own process may).
                    info!(
                        client_pid = pid,
                        "refused to reset settings: the ticker holds the world"
                    );
                    return ControlResponse::refused(ResponseStatus::NotTicker, self.report());
                }
                match self.load_world(scene, reset, pid, Instant::now()) {
                    Ok(()) => ControlResponse::ok(self.report()),
                    Err(e) => {
                        warn!("loading {scene} failed: {e}");
                        ControlResponse::refused(ResponseStatus::LoadFailed, self.report())
                    }
                }
            }
        }
    }

    /// Settings from a client that is not the ticker (see [`WhileTicked`]).
    fn apply_settings(
        &mut self,
        settings: WorldSettings,
        pid: u32,
        name: FixedText,
    ) -> ControlResponse {
        if let Some(ticker_pid) = self.ticker.owner_pid() {
            match WhileTicked::of(self.runtime.settings, settings) {
                WhileTicked::Unchanged => {}
                WhileTicked::EndsOwnership => {
                    let by = Ticker::named(pid, name, self.clock.frame());
                    self.ticker.revoke(by, &self.clock);
                }
                WhileTicked::Refused => {
                    info!(
                        pid,
                        ticker_pid, "refused settings: the ticker holds the world"
                    );
                    return ControlResponse::refused(ResponseStatus::NotTicker, self.report());
                }
            }
        }
        let next_frame = self.clock.frame() + 1;
        match self
            .runtime
            .change_settings(settings, false, pid, next_frame)
        {
            Ok(effective_frame) => ControlResponse {
                effective_frame,
                ..ControlResponse::ok(self.report())
            },
            Err(Refusal::Invalid(error)) => {
                ControlResponse::invalid_settings(&error, self.report())
            }
            Err(Refusal::Status(status)) => ControlResponse::refused(status, self.report()),
        }
    }
}
