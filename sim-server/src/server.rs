//! The server loop: answer control requests, pace, step, publish.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use iceoryx2::port::listener::ListenerWaitError;
use shared_types::{
    ControlRequest, ControlResponse, FixedText, FrameHeader, RequestKind, ResponseStatus,
    StatusReport, Timestamp, WireSettings, WorldName, WorldSettings, PROTOCOL_VERSION,
};
use tracing::{debug, debug_span, info, warn};

use crate::clock::{long_substep, Clock, SubstepPlan, LONG_FRAME_NS};
use crate::scene::Scene;
use crate::services::ServerPorts;
use crate::world::World;
use crate::ServerError;

/// How a server is started.
#[derive(Debug, Clone)]
pub struct ServerConfig {
    /// The world the server owns.
    pub world: WorldName,
    /// The scene loaded at start.
    pub scene: Scene,
    /// The settings at start (validated by [`Server::start`]).
    pub settings: WorldSettings,
    /// Fixed step, async: pace frames so simulation time follows wall time.
    pub realtime: bool,
    /// Variable step, async: at most this many frames per second (0 = no limit).
    pub max_fps: f64,
    /// Stop after computing this many frames.
    pub max_frames: Option<u64>,
}

/// What a finished run did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunSummary {
    /// Frames computed (frame 0 is not computed, only published).
    pub frames: u64,
    /// Wall time from the first step to the last, in seconds.
    pub wall_seconds: f64,
    /// Simulation time at the end, in seconds.
    pub elapsed_seconds: f64,
}

impl RunSummary {
    /// Frames computed per wall-clock second.
    pub fn frames_per_second(&self) -> f64 {
        if self.wall_seconds > 0.0 {
            self.frames as f64 / self.wall_seconds
        } else {
            0.0
        }
    }
}

/// How often the server looks for dead clients and removes what they left.
const CLEANUP_PERIOD: Duration = Duration::from_secs(1);
/// The longest the server sleeps without looking at requests and signals.
const MAX_IDLE_WAIT: Duration = Duration::from_millis(50);
/// Below this, waits are plain sleeps (event timeouts are this coarse).
const COARSE_WAIT: Duration = Duration::from_millis(5);
/// A realtime server that falls this far behind stops trying to catch up.
const MAX_REALTIME_LAG: Duration = Duration::from_millis(250);
/// The least time between two "physics unreliable" warnings.
const WARN_PERIOD: Duration = Duration::from_secs(5);

/// A running world: physics, clock, settings and the ports that publish them.
pub struct Server {
    config: ServerConfig,
    ports: ServerPorts,
    world: World,
    clock: Clock,
    settings: WorldSettings,
    episode: u64,
    /// Realtime pacing: wall instant and simulation time that correspond.
    pace_anchor: Option<(Instant, u64)>,
    last_cleanup: Instant,
    last_warning: Option<Instant>,
}

fn platform_timestamp() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

impl Server {
    /// Validates the settings, loads the scene, opens the world's services
    /// (cleaning up after a crashed predecessor) and publishes frame 0.
    pub fn start(config: ServerConfig) -> Result<Self, ServerError> {
        let settings = config.settings.normalized();
        settings.validate()?;
        if settings.synchronous_mode {
            return Err(ServerError::SyncNeedsTicker);
        }
        for warning in settings.warnings() {
            warn!("{warning}");
        }
        let world = World::new(config.scene);
        let ports = ServerPorts::open(&config.world, world.actor_count())?;
        let now = Instant::now();
        let mut server = Self {
            ports,
            world,
            clock: Clock::new(now),
            settings,
            episode: 1,
            pace_anchor: None,
            last_cleanup: now,
            last_warning: None,
            config,
        };
        server.publish(0, 0)?;
        info!(
            world = %server.config.world,
            scene = %server.config.scene,
            actors = server.world.actor_count(),
            "server up: {}",
            describe(&server.settings)
        );
        Ok(server)
    }

    /// Runs until `shutdown` is set or `max_frames` frames were computed.
    pub fn run(&mut self, shutdown: &AtomicBool) -> Result<RunSummary, ServerError> {
        let started = Instant::now();
        let first_frame = self.clock.frame();
        while !shutdown.load(Ordering::Relaxed) {
            if self
                .config
                .max_frames
                .is_some_and(|max| self.clock.frame() - first_frame >= max)
            {
                break;
            }
            self.handle_control()?;
            self.housekeeping();
            let now = Instant::now();
            match self.next_frame_at(now) {
                Some(at) if at > now => self.idle((at - now).min(MAX_IDLE_WAIT))?,
                _ => self.step_frame(now)?,
            }
        }
        let summary = RunSummary {
            frames: self.clock.frame() - first_frame,
            wall_seconds: started.elapsed().as_secs_f64(),
            elapsed_seconds: Timestamp {
                elapsed_ns: self.clock.elapsed_ns(),
                ..Default::default()
            }
            .elapsed_seconds(),
        };
        info!(
            frames = summary.frames,
            fps = format_args!("{:.1}", summary.frames_per_second()),
            "server stopped"
        );
        Ok(summary)
    }

    /// When the next frame is due, `None` for "now".
    fn next_frame_at(&mut self, now: Instant) -> Option<Instant> {
        match self.settings.fixed_delta_nanos() {
            Some(dt) if self.config.realtime => {
                let (wall, sim) = *self
                    .pace_anchor
                    .get_or_insert((now, self.clock.elapsed_ns()));
                let due = wall + Duration::from_nanos(self.clock.elapsed_ns() + dt - sim);
                if now.saturating_duration_since(due) > MAX_REALTIME_LAG {
                    warn!("realtime pacing fell behind by more than {MAX_REALTIME_LAG:?}; resynchronising");
                    self.pace_anchor = None;
                }
                Some(due)
            }
            Some(_) => None,
            None if self.config.max_fps > 0.0 => Some(
                self.clock.last_frame_at() + Duration::from_secs_f64(1.0 / self.config.max_fps),
            ),
            None => None,
        }
    }

    /// Sleeps up to `timeout`, waking early for a control request.
    ///
    /// The event listener's timeout is rounded up to the kernel's tick (a few
    /// milliseconds), so the last stretch before a due frame is a plain,
    /// precise sleep.
    fn idle(&mut self, timeout: Duration) -> Result<(), ServerError> {
        if timeout <= COARSE_WAIT {
            std::thread::sleep(timeout);
            return Ok(());
        }
        match self
            .ports
            .control_wake
            .timed_wait(|_| {}, timeout - COARSE_WAIT)
        {
            // A signal (Ctrl-C) ends the sleep early; the loop looks at the flag.
            Ok(_) | Err(ListenerWaitError::InterruptSignal) => Ok(()),
            Err(e) => Err(ServerError::transport("control wake-up wait", e)),
        }
    }

    fn step_frame(&mut self, now: Instant) -> Result<(), ServerError> {
        let delta_ns = self.clock.next_delta_ns(&self.settings, now);
        let plan = SubstepPlan::new(delta_ns, &self.settings);
        let frame = self.clock.frame() + 1;
        let _span = debug_span!("frame", frame, delta_ns, substeps = plan.count).entered();
        self.warn_if_unreliable(delta_ns, &plan, now);
        self.world.step(&plan);
        self.clock.advance(delta_ns, now);
        self.publish(
            plan.count,
            if plan.capped {
                FrameHeader::SUBSTEPS_CAPPED
            } else {
                0
            },
        )
    }

    fn warn_if_unreliable(&mut self, delta_ns: u64, plan: &SubstepPlan, now: Instant) {
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
            "frame {} is too long for reliable physics (frame dt > 0.1 s or substep dt > 1/60 s)",
            self.clock.frame() + 1
        );
    }

    /// Writes the current frame straight into loaned shared memory and wakes
    /// waiting clients.
    fn publish(&mut self, physics_substeps: u32, flags: u32) -> Result<(), ServerError> {
        let count = self.world.actor_count();
        let mut sample = self
            .ports
            .frames
            .loan_slice_uninit(count)
            .map_err(|e| ServerError::transport("frame loan", e))?;
        *sample.user_header_mut() = FrameHeader {
            protocol_version: PROTOCOL_VERSION,
            actor_count: count as u32,
            episode: self.episode,
            timestamp: Timestamp {
                frame: self.clock.frame(),
                elapsed_ns: self.clock.elapsed_ns(),
                delta_ns: self.clock.delta_ns(),
                platform_timestamp: platform_timestamp(),
            },
            settings: self.settings.into(),
            physics_substeps,
            flags,
        };
        let world = &self.world;
        let sample = sample.write_from_fn(|i| world.actor_state(i));
        sample
            .send()
            .map_err(|e| ServerError::transport("frame send", e))?;
        self.ports
            .frame_ready
            .notify()
            .map_err(|e| ServerError::transport("frame-ready notify", e))?;
        Ok(())
    }

    /// Answers every pending control request.
    fn handle_control(&mut self) -> Result<(), ServerError> {
        while let Some(request) = self
            .ports
            .control
            .receive()
            .map_err(|e| ServerError::transport("control receive", e))?
        {
            let response = self.answer(request.payload());
            if let Err(e) = request.send_copy(response) {
                debug!("control response not delivered (client gone?): {e:?}");
            }
        }
        Ok(())
    }

    fn answer(&mut self, request: &ControlRequest) -> ControlResponse {
        if request.protocol_version != PROTOCOL_VERSION {
            warn!(
                client_pid = request.client_pid,
                client_version = request.protocol_version,
                "refused a request: protocol version {} is not the server's {PROTOCOL_VERSION}",
                request.protocol_version
            );
            return ControlResponse::refused(ResponseStatus::ProtocolMismatch, self.report());
        }
        match RequestKind::from_u32(request.kind) {
            Some(RequestKind::Hello) => {
                debug!(client_pid = request.client_pid, "client connected");
                ControlResponse::ok(self.report())
            }
            Some(RequestKind::GetSettings | RequestKind::Status) => {
                ControlResponse::ok(self.report())
            }
            Some(RequestKind::ApplySettings) => self.apply_settings(request),
            None => ControlResponse::refused(ResponseStatus::UnknownRequest, self.report()),
        }
    }

    fn apply_settings(&mut self, request: &ControlRequest) -> ControlResponse {
        let settings = WorldSettings::from(request.settings).normalized();
        if let Err(error) = settings.validate() {
            info!(client_pid = request.client_pid, "refused settings: {error}");
            return ControlResponse::invalid_settings(&error, self.report());
        }
        if settings.synchronous_mode {
            info!(
                client_pid = request.client_pid,
                "refused settings: synchronous mode is entered by the tick owner"
            );
            return ControlResponse::refused(ResponseStatus::SyncNeedsTicker, self.report());
        }
        for warning in settings.warnings() {
            warn!("{warning}");
        }
        let effective_frame = self.clock.frame() + 1;
        if settings != self.settings {
            info!(
                client_pid = request.client_pid,
                effective_frame,
                "settings changed: {}",
                describe(&settings)
            );
            self.settings = settings;
            self.pace_anchor = None;
        }
        ControlResponse {
            effective_frame,
            ..ControlResponse::ok(self.report())
        }
    }

    fn report(&self) -> StatusReport {
        StatusReport {
            frame: self.clock.frame(),
            elapsed_ns: self.clock.elapsed_ns(),
            episode: self.episode,
            server_pid: std::process::id(),
            actor_count: self.world.actor_count() as u32,
            settings: WireSettings::from(self.settings),
            scene: FixedText::new(&self.config.scene.to_string()),
        }
    }

    /// Once a second: remove what dead clients left in the world's services.
    fn housekeeping(&mut self) {
        if self.last_cleanup.elapsed() < CLEANUP_PERIOD {
            return;
        }
        self.last_cleanup = Instant::now();
        let cleanup = self.ports.node.try_cleanup_dead_nodes();
        if cleanup.cleanups > 0 {
            info!(
                removed = cleanup.cleanups,
                "removed resources of dead clients"
            );
        }
    }
}

/// One line describing the time settings, for logs.
pub fn describe(settings: &WorldSettings) -> String {
    let mode = if settings.synchronous_mode {
        "sync"
    } else {
        "async"
    };
    let step = match settings.fixed_delta_seconds {
        Some(dt) => format!("fixed step {dt} s"),
        None => "variable step".to_owned(),
    };
    let substeps = if settings.substepping {
        format!(
            "substepping <= {} s x {}",
            settings.max_substep_delta_time, settings.max_substeps
        )
    } else {
        "no substepping".to_owned()
    };
    format!("{mode}, {step}, {substeps}")
}
