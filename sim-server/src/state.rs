//! What changes while a server runs: the settings in force, the scene and
//! episode, and the pacing of asynchronous frames. The settings the server
//! was started with stay in [`ServerConfig`](crate::config::ServerConfig).

use std::time::{Duration, Instant};

use shared_types::{ResponseStatus, SettingsError, WorldSettings};
use tracing::{info, warn};

use shared_types::LONG_FRAME_NS;

use crate::clock::{long_substep, Pacer, SubstepPlan};
use crate::config::ServerConfig;
use crate::scene::Scene;

/// The least time between two "physics unreliable" warnings.
const WARN_PERIOD: Duration = Duration::from_secs(5);

/// Why a settings change was refused.
#[derive(Debug)]
pub(crate) enum Refusal {
    /// The settings break a rule.
    Invalid(SettingsError),
    /// Refused for another reason, answered with this status.
    Status(ResponseStatus),
}

/// The runtime state of a world.
#[derive(Debug)]
pub(crate) struct Runtime {
    /// The settings in force for the next frame.
    pub settings: WorldSettings,
    /// The scene the current episode was loaded from.
    pub scene: Scene,
    /// The current episode: 1 at start, one more per load or reload.
    pub episode: u64,
    /// When the next asynchronous frame is due.
    pub pacer: Pacer,
    /// Frames computed since start (all episodes).
    pub frames_computed: u64,
    /// After a snapshot was restored in this episode: the current frame id
    /// minus its id in the snapshot's line of frames.
    pub source_offset: Option<u64>,
    /// The run this server continues ([`shared_types::StatusReport::run_pid`]):
    /// its own pid, or the resumed journal's.
    pub run_pid: u32,
    last_warning: Option<Instant>,
}

impl Runtime {
    /// The state at start: `config`'s scene and (validated) settings, episode 1.
    pub(crate) fn new(config: &ServerConfig, settings: WorldSettings) -> Self {
        Self {
            settings,
            scene: config.scene,
            episode: 1,
            pacer: Pacer::new(config.realtime, config.max_fps),
            frames_computed: 0,
            source_offset: None,
            run_pid: shared_types::this_process_id(),
            last_warning: None,
        }
    }

    /// Validates and applies `settings` from process `pid`; returns the
    /// first frame computed with them (`next_frame`). Only the ticker
    /// (`from_ticker`) may enter synchronous mode.
    pub(crate) fn change_settings(
        &mut self,
        settings: WorldSettings,
        from_ticker: bool,
        pid: u32,
        next_frame: u64,
    ) -> Result<u64, Refusal> {
        let settings = settings.normalized();
        if let Err(error) = settings.validate() {
            info!(pid, "refused settings: {error}");
            return Err(Refusal::Invalid(error));
        }
        if settings.synchronous_mode && !self.settings.synchronous_mode && !from_ticker {
            info!(
                pid,
                "refused settings: synchronous mode is entered by the tick owner"
            );
            return Err(Refusal::Status(ResponseStatus::SyncNeedsTicker));
        }
        for warning in settings.warnings() {
            warn!("{warning}");
        }
        if settings.synchronous_mode && settings.fixed_delta_seconds.is_none() {
            warn!("synchronous mode with a variable step: each frame's dt is the time the ticker took; physics is unreliable (set a fixed step)");
        }
        if settings != self.settings {
            info!(
                pid,
                effective_frame = next_frame,
                "settings changed: {settings}"
            );
            self.settings = settings;
            self.pacer.reset();
        }
        Ok(next_frame)
    }

    /// Warns (at most every 5 s) when `frame` of `delta_ns` run as `plan`
    /// makes physics unreliable.
    pub(crate) fn warn_if_unreliable(
        &mut self,
        frame: u64,
        delta_ns: u64,
        plan: &SubstepPlan,
        now: Instant,
    ) {
        let unreliable = delta_ns > LONG_FRAME_NS || plan.capped || long_substep(plan);
        if !unreliable
            || self
                .last_warning
                .is_some_and(|at| now.duration_since(at) < WARN_PERIOD)
        {
            return;
        }
        self.last_warning = Some(now);
        warn!(
            delta_seconds = delta_ns as f64 * 1e-9,
            substeps = plan.count,
            substep_seconds = plan.substep_seconds,
            capped = plan.capped,
            clamped = plan.clamped,
            "frame {frame} is too long for reliable physics (frame dt > 0.1 s or substep dt > 1/60 s)",
        );
    }
}
