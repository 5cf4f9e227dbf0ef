//! The server loop: pace (async) or wait for the ticker (sync), step,
//! capture sensors, publish. The answers to requests live in `server/requests.rs`.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use iceoryx2::active_request::ActiveRequest;
use iceoryx2::port::listener::ListenerWaitError;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::ipc;
use shared_types::{
    CommandResult, FixedText, FrameHeader, ResponseStatus, SensorEnd, ServiceNames, SettingsError,
    StatusReport, TickRequest, TickResponse, TickerInfo, Timestamp, WireSettings, WorldName,
    WorldSettings, PROTOCOL_VERSION,
};
use tracing::{debug, debug_span, info, warn};

use shared_types::limits::WorldLimits;

use crate::clock::{long_substep, Clock, SubstepPlan, LONG_FRAME_NS};
use crate::lockstep::Participants;
use crate::scene::Scene;
use crate::sensors::Sensors;
use crate::services::ServerPorts;
use crate::ticker::{node_process_alive, OnTickerLoss, TickOwnership};
use crate::world::World;
use crate::ServerError;

mod requests;

use requests::{respond_batch, PendingBatch};

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
    /// What to do when the ticker dies in synchronous mode.
    pub on_ticker_loss: OnTickerLoss,
    /// Synchronous mode: poll for ticks instead of sleeping on the wake-up
    /// event (lowest tick latency, one core busy while waiting).
    pub spin: bool,
    /// Synchronous mode: after each frame, poll this long for the next tick
    /// before sleeping (a ticker in a tight loop then costs no kernel wake-up).
    pub spin_window: Duration,
    /// Seed of the scene's placement (0: none); kept across reloads.
    pub seed: u64,
    /// A lockstep participant that keeps a tick waiting this long is
    /// dropped (a hung reader must not stop the world).
    pub lockstep_timeout: Duration,
    /// How many clients (and readers per sensor) the world admits.
    pub limits: WorldLimits,
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
/// How often new subscribers are connected while no frame is sent.
const CONNECTION_PERIOD: Duration = Duration::from_millis(10);
/// How often the server checks that the ticker's process still lives.
const TICKER_LIVENESS_PERIOD: Duration = Duration::from_millis(100);
/// A tick held up by a lockstep participant this long is told which one,
/// and how long the server will wait for it, so the ticker's own timeout
/// can wait that long too.
const WAIT_NOTICE_AFTER: Duration = Duration::from_millis(200);

/// A tick request waiting for its frame.
type PendingTick = ActiveRequest<ipc::Service, TickRequest, (), TickResponse, ()>;

/// A request for one frame step, answered once the frame is published.
enum PendingStep {
    /// `Ticker::tick`.
    Tick(PendingTick),
    /// `apply_batch_sync(.., tick = true)`, with the batch's results.
    Batch(PendingBatch, Vec<CommandResult>),
}

/// Why a settings change was refused.
enum Refusal {
    Invalid(SettingsError),
    Status(ResponseStatus),
}

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
    ownership: TickOwnership,
    participants: Participants,
    pending_steps: VecDeque<PendingStep>,
    frames_computed: u64,
    sensors: Sensors,
    names: ServiceNames,
    /// Since when a tick waits for lockstep participants.
    waiting_for_participants_since: Option<Instant>,
    /// Whether the waiting tick was told which participant it waits for.
    ticker_told_of_wait: bool,
    last_liveness_check: Instant,
    last_connection_update: Instant,
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
        for warning in settings.warnings() {
            warn!("{warning}");
        }
        let world = World::new(&config.scene.placements(config.seed), 1);
        let ports = ServerPorts::open(&config.world, world.actor_count(), &config.limits)?;
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
            ownership: TickOwnership::default(),
            participants: Participants::default(),
            pending_steps: VecDeque::new(),
            frames_computed: 0,
            sensors: Sensors::new(config.limits.max_sensor_readers),
            waiting_for_participants_since: None,
            ticker_told_of_wait: false,
            names: ServiceNames::new(&config.world),
            last_liveness_check: now,
            last_connection_update: now,
            config,
        };
        server.publish(0, 0)?;
        server.notify_frame()?;
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
        let first_frame = self.frames_computed;
        while !shutdown.load(Ordering::Relaxed) {
            if self
                .config
                .max_frames
                .is_some_and(|max| self.frames_computed - first_frame >= max)
            {
                break;
            }
            self.handle_control()?;
            self.handle_batches()?;
            self.handle_lockstep()?;
            self.handle_sensor_requests()?;
            self.handle_ticks()?;
            self.housekeeping();
            let now = Instant::now();
            if self.settings.synchronous_mode {
                // Synchronous: one frame per tick, nothing without one, and
                // not before every lockstep participant is done.
                let ticked = !self.pending_steps.is_empty();
                if !ticked || !self.participants.all_done(self.clock.frame()) {
                    if ticked {
                        self.drop_late_participants(now);
                        self.tell_ticker_who_it_waits_for(now);
                    }
                    let just_stepped =
                        self.clock.last_frame_at().elapsed() < self.config.spin_window;
                    if self.config.spin || just_stepped {
                        std::hint::spin_loop();
                    } else {
                        self.idle(MAX_IDLE_WAIT)?;
                    }
                } else {
                    self.waiting_for_participants_since = None;
                    self.ticker_told_of_wait = false;
                    self.step_frame(now, 1)?;
                }
                continue;
            }
            match self.next_frame_at(now) {
                Some(at) if at > now => self.idle((at - now).min(MAX_IDLE_WAIT))?,
                // Asynchronous: a tick just waits for the next frame.
                _ => self.step_frame(now, self.pending_steps.len())?,
            }
        }
        // Readers of the sensors learn why their stream ended.
        self.sensors
            .end_all(SensorEnd::ServerStopped, self.clock.frame(), self.episode);
        let summary = RunSummary {
            frames: self.frames_computed - first_frame,
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

    /// Computes and publishes the next frame, answers the first `ticks`
    /// pending tick requests with it, then wakes waiting clients.
    fn step_frame(&mut self, now: Instant, ticks: usize) -> Result<(), ServerError> {
        let delta_ns = self.clock.next_delta_ns(&self.settings, now);
        let plan = SubstepPlan::new(delta_ns, &self.settings);
        let frame = self.clock.frame() + 1;
        let _span = debug_span!("frame", frame, delta_ns, substeps = plan.count).entered();
        self.warn_if_unreliable(delta_ns, &plan, now);
        self.world.step(&plan);
        self.clock.advance(delta_ns, now);
        self.frames_computed += 1;
        // Sensors first: whoever sees the frame's snapshot (or hears the
        // tick is done) finds its captures already queued.
        self.sensors.capture(
            &self.world,
            self.clock.frame(),
            self.clock.elapsed_ns(),
            self.episode,
        );
        self.publish(
            plan.count,
            if plan.capped {
                FrameHeader::SUBSTEPS_CAPPED
            } else {
                0
            },
        )?;
        for _ in 0..ticks {
            let Some(step) = self.pending_steps.pop_front() else {
                break;
            };
            match step {
                PendingStep::Tick(tick) => {
                    let response = TickResponse::new(
                        ResponseStatus::Ok,
                        self.clock.frame(),
                        self.clock.elapsed_ns(),
                        self.ownership.info(),
                    );
                    if let Err(e) = tick.send_copy(response) {
                        debug!("tick response not delivered (ticker gone?): {e:?}");
                    }
                }
                PendingStep::Batch(request, results) => {
                    respond_batch(&request, ResponseStatus::Ok, self.clock.frame(), &results)
                }
            }
        }
        self.notify_frame()
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

    /// Writes the current frame straight into loaned shared memory and sends it.
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
            first_actor_id: self.world.first_id(),
            server_pid: std::process::id(),
            reserved: 0,
        };
        let world = &self.world;
        let sample = sample.write_from_fn(|i| world.actor_state(i));
        sample
            .send()
            .map_err(|e| ServerError::transport("frame send", e))?;
        Ok(())
    }

    /// Wakes every client blocked on the frame-ready event.
    fn notify_frame(&self) -> Result<(), ServerError> {
        self.ports
            .frame_ready
            .notify()
            .map_err(|e| ServerError::transport("frame-ready notify", e))?;
        Ok(())
    }

    /// Drops the participants that kept a tick waiting past the lockstep timeout.
    fn drop_late_participants(&mut self, now: Instant) {
        let since = *self.waiting_for_participants_since.get_or_insert(now);
        if now.duration_since(since) < self.config.lockstep_timeout {
            return;
        }
        self.waiting_for_participants_since = None;
        self.ticker_told_of_wait = false;
        for late in self.participants.drop_not_done(self.clock.frame()) {
            warn!(
                pid = late.pid,
                name = %late.name,
                frame = self.clock.frame(),
                timeout = ?self.config.lockstep_timeout,
                "lockstep participant did not report done in time; no longer waiting for it"
            );
        }
    }

    /// Once a tick has waited [`WAIT_NOTICE_AFTER`] for lockstep
    /// participants, sends the ticker an interim answer naming the first it
    /// waits for and the lockstep timeout. Off the hot path: a tick that is
    /// not held up sends nothing.
    fn tell_ticker_who_it_waits_for(&mut self, now: Instant) {
        let Some(since) = self.waiting_for_participants_since else {
            return;
        };
        if self.ticker_told_of_wait || now.duration_since(since) < WAIT_NOTICE_AFTER {
            return;
        }
        self.ticker_told_of_wait = true;
        let Some(late) = self.participants.first_not_done(self.clock.frame()) else {
            return;
        };
        let waiting_for = TickerInfo {
            active: 1,
            pid: late.pid,
            since_frame: self.clock.frame(),
            node_name: FixedText::new(&late.name),
        };
        info!(
            pid = late.pid,
            name = %late.name,
            frame = self.clock.frame(),
            "a tick waits for a lockstep participant"
        );
        if let Some(PendingStep::Tick(tick)) = self.pending_steps.front() {
            let response = TickResponse {
                waiting_for,
                lockstep_timeout_ns: u64::try_from(self.config.lockstep_timeout.as_nanos())
                    .unwrap_or(u64::MAX),
                ..TickResponse::new(
                    ResponseStatus::WaitingForParticipants,
                    self.clock.frame(),
                    self.clock.elapsed_ns(),
                    self.ownership.info(),
                )
            };
            if let Err(e) = tick.send_copy(response) {
                debug!("interim tick answer not delivered: {e:?}");
            }
        }
    }

    /// Drops a ticker whose process died, applying the ticker-loss policy.
    fn check_ticker(&mut self) {
        let Some(lost) = self.ownership.take_if_dead(node_process_alive) else {
            return;
        };
        self.drop_pending_ticks(ResponseStatus::NotOwner, TickerInfo::none());
        // Frees the dead ticker's port, so a new ticker can claim.
        self.ports.node.try_cleanup_dead_nodes();
        let frame = self.clock.frame();
        match (self.settings.synchronous_mode, self.config.on_ticker_loss) {
            (true, OnTickerLoss::Async) => {
                self.settings.synchronous_mode = false;
                self.pace_anchor = None;
                warn!(
                    pid = lost.pid,
                    node = %lost.node_name,
                    frame,
                    "ticker died; falling back to asynchronous mode (--on-ticker-loss async)"
                );
            }
            (true, OnTickerLoss::Wait) => warn!(
                pid = lost.pid,
                node = %lost.node_name,
                frame,
                "ticker died; staying in synchronous mode until a new ticker claims (--on-ticker-loss wait)"
            ),
            (false, _) => info!(pid = lost.pid, node = %lost.node_name, frame, "ticker died"),
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
            ticker: self.ownership.info(),
            seed: self.config.seed,
            participants: self.participants.len() as u32,
            max_clients: self.config.limits.max_clients as u32,
            max_sensor_readers: self.config.limits.max_sensor_readers as u32,
            reserved: 0,
        }
    }

    /// Every 10 ms: connect new subscribers. Every 100 ms: is the ticker
    /// alive? Once a second: remove what dead clients left in the services.
    fn housekeeping(&mut self) {
        if self.last_connection_update.elapsed() >= CONNECTION_PERIOD {
            self.last_connection_update = Instant::now();
            // A subscriber that joined since the last frame gets the current
            // frame (the service's history) now, not only when the next frame
            // is sent: in synchronous mode that may be a long wait.
            if let Err(e) = self.ports.frames.update_connections() {
                debug!("connecting new subscribers: {e}");
            }
        }
        if (self.ownership.owner().is_some() || !self.participants.is_empty())
            && self.last_liveness_check.elapsed() >= TICKER_LIVENESS_PERIOD
        {
            self.last_liveness_check = Instant::now();
            self.check_ticker();
            for dead in self.participants.drop_dead(node_process_alive) {
                warn!(
                    pid = dead.pid,
                    name = %dead.name,
                    frame = self.clock.frame(),
                    "lockstep participant died; no longer waiting for it"
                );
            }
        }
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
