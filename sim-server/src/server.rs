//! The server loop: answer control and tick requests, pace (async) or wait
//! for the ticker (sync), step, publish.

use std::collections::VecDeque;
use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use iceoryx2::active_request::ActiveRequest;
use iceoryx2::port::listener::ListenerWaitError;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::ipc;
use shared_types::{
    BatchHeader, BatchResponseHeader, Command, CommandResult, CommandStatus, ControlRequest,
    ControlResponse, FixedText, FrameHeader, LockstepKind, LockstepRequest, LockstepResponse,
    RequestKind, ResponseStatus, SensorInfo, SensorRequestKind, SensorResponseHeader, ServiceNames,
    SettingsError, StatusReport, TickRequest, TickRequestKind, TickResponse, Timestamp,
    WireSettings, WorldName, WorldSettings, PROTOCOL_VERSION,
};
use tracing::{debug, debug_span, info, warn};

use crate::clock::{long_substep, Clock, SubstepPlan, LONG_FRAME_NS};
use crate::lockstep::Participants;
use crate::scene::Scene;
use crate::sensors::Sensors;
use crate::services::ServerPorts;
use crate::ticker::{node_process_alive, OnTickerLoss, Owner, TickOwnership};
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

/// A tick request waiting for its frame.
type PendingTick = ActiveRequest<ipc::Service, TickRequest, (), TickResponse, ()>;
/// A batch request (already applied) waiting for the answer.
type PendingBatch =
    ActiveRequest<ipc::Service, [Command], BatchHeader, [CommandResult], BatchResponseHeader>;

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
        let world = World::new(&config.scene.placements(config.seed));
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
            ownership: TickOwnership::default(),
            participants: Participants::default(),
            pending_steps: VecDeque::new(),
            frames_computed: 0,
            sensors: Sensors::default(),
            waiting_for_participants_since: None,
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
            Some(kind @ (RequestKind::LoadWorld | RequestKind::ReloadWorld)) => {
                let scene = match kind {
                    RequestKind::LoadWorld => match request.scene.to_string_lossy().parse() {
                        Ok(scene) => scene,
                        Err(e) => {
                            info!(client_pid = request.client_pid, "refused to load: {e}");
                            return ControlResponse::refused(
                                ResponseStatus::UnknownScene,
                                self.report(),
                            );
                        }
                    },
                    _ => self.config.scene,
                };
                let reset = request.flags & ControlRequest::RESET_SETTINGS != 0;
                match self.load_world(scene, reset, request.client_pid) {
                    Ok(()) => ControlResponse::ok(self.report()),
                    Err(e) => {
                        warn!("loading {scene} failed: {e}");
                        ControlResponse::refused(ResponseStatus::UnknownRequest, self.report())
                    }
                }
            }
            None => ControlResponse::refused(ResponseStatus::UnknownRequest, self.report()),
        }
    }

    fn apply_settings(&mut self, request: &ControlRequest) -> ControlResponse {
        let settings = WorldSettings::from(request.settings);
        match self.change_settings(settings, false, request.client_pid) {
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

    /// Validates and applies `settings`; returns the first frame computed
    /// with them. Only the ticker may enter synchronous mode; anyone may keep
    /// it or leave it.
    fn change_settings(
        &mut self,
        settings: WorldSettings,
        from_ticker: bool,
        pid: u32,
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
        let effective_frame = self.clock.frame() + 1;
        if settings != self.settings {
            info!(
                pid,
                effective_frame,
                "settings changed: {}",
                describe(&settings)
            );
            self.settings = settings;
            self.pace_anchor = None;
        }
        Ok(effective_frame)
    }

    /// Answers every pending request of the ticker; ticks are queued for
    /// the frame loop.
    fn handle_ticks(&mut self) -> Result<(), ServerError> {
        while let Some(request) = self
            .ports
            .tick
            .receive()
            .map_err(|e| ServerError::transport("tick receive", e))?
        {
            let payload = *request.payload();
            let origin = request.origin();
            let respond = |server: &Self, status: ResponseStatus| {
                TickResponse::new(
                    status,
                    server.clock.frame(),
                    server.clock.elapsed_ns(),
                    server.ownership.info(),
                )
            };
            let response = if payload.protocol_version != PROTOCOL_VERSION {
                respond(self, ResponseStatus::ProtocolMismatch)
            } else {
                match TickRequestKind::from_u32(payload.kind) {
                    Some(TickRequestKind::Claim) => {
                        let candidate = Owner {
                            client: origin,
                            pid: payload.pid,
                            node_name: payload.node_name.to_string_lossy(),
                            since_frame: self.clock.frame(),
                        };
                        match self.ownership.claim(candidate, node_process_alive) {
                            Ok(owner) => {
                                info!(
                                    pid = owner.pid,
                                    node = %owner.node_name,
                                    frame = owner.since_frame,
                                    "ticker claimed ownership"
                                );
                                respond(self, ResponseStatus::Ok)
                            }
                            Err(current) => {
                                info!(
                                    pid = payload.pid,
                                    owner_pid = current.pid,
                                    "refused a second ticker"
                                );
                                respond(self, ResponseStatus::NotOwner)
                            }
                        }
                    }
                    Some(TickRequestKind::Release) => {
                        if self.ownership.release(origin) {
                            info!(
                                pid = payload.pid,
                                frame = self.clock.frame(),
                                "ticker released ownership"
                            );
                            self.drop_pending_ticks();
                            respond(self, ResponseStatus::Ok)
                        } else {
                            respond(self, ResponseStatus::NotOwner)
                        }
                    }
                    Some(TickRequestKind::Tick) if self.ownership.is_owner(origin) => {
                        self.pending_steps.push_back(PendingStep::Tick(request));
                        continue;
                    }
                    Some(TickRequestKind::ApplySettings) if self.ownership.is_owner(origin) => {
                        let settings = WorldSettings::from(payload.settings);
                        match self.change_settings(settings, true, payload.pid) {
                            Ok(effective_frame) => TickResponse {
                                effective_frame,
                                ..respond(self, ResponseStatus::Ok)
                            },
                            Err(Refusal::Invalid(error)) => {
                                respond(self, ResponseStatus::InvalidSettings)
                                    .with_settings_error(&error)
                            }
                            Err(Refusal::Status(status)) => respond(self, status),
                        }
                    }
                    Some(TickRequestKind::Tick | TickRequestKind::ApplySettings) => {
                        warn!(
                            pid = payload.pid,
                            "refused a request from a client that is not the ticker"
                        );
                        respond(self, ResponseStatus::NotOwner)
                    }
                    None => respond(self, ResponseStatus::UnknownRequest),
                }
            };
            if let Err(e) = request.send_copy(response) {
                debug!("tick response not delivered (ticker gone?): {e:?}");
            }
        }
        Ok(())
    }

    /// Forgets the ticker's pending ticks (it released or died); ticking
    /// batches are answered as refused.
    fn drop_pending_ticks(&mut self) {
        for step in self.pending_steps.drain(..) {
            if let PendingStep::Batch(request, results) = step {
                respond_batch(
                    &request,
                    ResponseStatus::NotOwner,
                    self.clock.frame(),
                    &results,
                );
            }
        }
    }

    /// Applies every pending batch, in arrival order, at this frame boundary.
    fn handle_batches(&mut self) -> Result<(), ServerError> {
        while let Some(request) = self
            .ports
            .batch
            .receive()
            .map_err(|e| ServerError::transport("batch receive", e))?
        {
            let header = *request.user_header();
            let next_frame = self.clock.frame() + 1;
            if header.protocol_version != PROTOCOL_VERSION {
                respond_batch(&request, ResponseStatus::ProtocolMismatch, next_frame, &[]);
                continue;
            }
            let tick = header.flags & BatchHeader::TICK != 0;
            let ticker_pid = self.ownership.owner().map(|o| o.pid);
            if tick && ticker_pid != Some(header.pid) {
                warn!(
                    pid = header.pid,
                    "refused a ticking batch from a process that is not the ticker"
                );
                respond_batch(&request, ResponseStatus::NotOwner, next_frame, &[]);
                continue;
            }
            let results: Vec<CommandResult> = request
                .payload()
                .iter()
                .map(|c| self.world.apply(c))
                .collect();
            let failed = results
                .iter()
                .filter(|r| r.status != CommandStatus::Ok as u32)
                .count();
            debug!(
                pid = header.pid,
                commands = results.len(),
                failed,
                tick,
                "batch applied"
            );
            if tick {
                self.pending_steps
                    .push_back(PendingStep::Batch(request, results));
            } else {
                respond_batch(&request, ResponseStatus::Ok, next_frame, &results);
            }
        }
        Ok(())
    }

    /// Joins, leaves and "done with frame N" of lockstep participants.
    fn handle_lockstep(&mut self) -> Result<(), ServerError> {
        while let Some(request) = self
            .ports
            .lockstep
            .receive()
            .map_err(|e| ServerError::transport("lockstep receive", e))?
        {
            let payload: LockstepRequest = *request.payload();
            let origin = request.origin();
            let status = if payload.protocol_version != PROTOCOL_VERSION {
                ResponseStatus::ProtocolMismatch
            } else {
                match LockstepKind::from_u32(payload.kind) {
                    Some(LockstepKind::Join) => {
                        let name = payload.name.to_string_lossy();
                        info!(pid = payload.pid, %name, frame = self.clock.frame(), "lockstep participant joined");
                        self.participants.join(origin, payload.pid, name);
                        ResponseStatus::Ok
                    }
                    Some(LockstepKind::Leave) => {
                        if self.participants.leave(origin) {
                            info!(pid = payload.pid, "lockstep participant left");
                        }
                        ResponseStatus::Ok
                    }
                    Some(LockstepKind::Done) => {
                        // A "done" for an earlier episode means nothing now.
                        if payload.episode == self.episode {
                            self.participants.done(origin, payload.frame);
                        }
                        ResponseStatus::Ok
                    }
                    None => ResponseStatus::UnknownRequest,
                }
            };
            let response = LockstepResponse {
                protocol_version: PROTOCOL_VERSION,
                status: status as u32,
                frame: self.clock.frame(),
                episode: self.episode,
            };
            if let Err(e) = request.send_copy(response) {
                debug!("lockstep response not delivered: {e:?}");
            }
        }
        Ok(())
    }

    /// Drops the participants that kept a tick waiting past the lockstep timeout.
    fn drop_late_participants(&mut self, now: Instant) {
        let since = *self.waiting_for_participants_since.get_or_insert(now);
        if now.duration_since(since) < self.config.lockstep_timeout {
            return;
        }
        self.waiting_for_participants_since = None;
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

    /// Spawns, destroys and lists sensors.
    fn handle_sensor_requests(&mut self) -> Result<(), ServerError> {
        while let Some(request) = self
            .ports
            .sensors
            .receive()
            .map_err(|e| ServerError::transport("sensor receive", e))?
        {
            let payload = *request.payload();
            let (status, error, infos): (ResponseStatus, u32, Vec<SensorInfo>) = if payload
                .protocol_version
                != PROTOCOL_VERSION
            {
                (ResponseStatus::ProtocolMismatch, 0, Vec::new())
            } else {
                match SensorRequestKind::from_u32(payload.kind) {
                    Some(SensorRequestKind::Spawn) => match self.sensors.spawn(
                        &self.ports.node,
                        &self.names,
                        payload.spec,
                        &self.world,
                        self.clock.elapsed_ns(),
                    )? {
                        Ok(info) => (ResponseStatus::Ok, 0, vec![info]),
                        Err(refusal) => {
                            (ResponseStatus::UnknownRequest, refusal as u32, Vec::new())
                        }
                    },
                    Some(SensorRequestKind::Destroy) => {
                        if self.sensors.destroy(payload.id) {
                            (ResponseStatus::Ok, 0, Vec::new())
                        } else {
                            (ResponseStatus::UnknownRequest, 3, Vec::new())
                        }
                    }
                    Some(SensorRequestKind::List) => (ResponseStatus::Ok, 0, self.sensors.list()),
                    None => (ResponseStatus::UnknownRequest, 0, Vec::new()),
                }
            };
            let response = request.loan_slice_uninit(infos.len()).map(|mut response| {
                *response.user_header_mut() = SensorResponseHeader {
                    protocol_version: PROTOCOL_VERSION,
                    status: status as u32,
                    error,
                    reserved: 0,
                };
                response.write_from_slice(&infos)
            });
            match response.map(|r| r.send()) {
                Ok(Ok(())) => {}
                Ok(Err(e)) => debug!("sensor response not delivered: {e:?}"),
                Err(e) => debug!("sensor response not loaned: {e:?}"),
            }
        }
        Ok(())
    }

    /// Replaces the world with `scene`'s initial state as a new episode,
    /// starting again at frame 0; settings are kept unless `reset`.
    fn load_world(&mut self, scene: Scene, reset: bool, pid: u32) -> Result<(), ServerError> {
        let now = Instant::now();
        self.world = World::new(&scene.placements(self.config.seed));
        self.config.scene = scene;
        self.clock = Clock::new(now);
        self.episode += 1;
        self.pace_anchor = None;
        self.participants.new_episode();
        self.sensors.new_episode();
        if reset {
            self.settings = WorldSettings::default();
        }
        info!(
            pid,
            %scene,
            episode = self.episode,
            actors = self.world.actor_count(),
            "world loaded: {}",
            describe(&self.settings)
        );
        self.publish(0, 0)?;
        self.notify_frame()
    }

    /// Drops a ticker whose process died, applying the ticker-loss policy.
    fn check_ticker(&mut self) {
        let Some(lost) = self.ownership.take_if_dead(node_process_alive) else {
            return;
        };
        self.drop_pending_ticks();
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

/// Answers a batch with `status`, the frame it concerns and its results.
fn respond_batch(
    request: &PendingBatch,
    status: ResponseStatus,
    frame: u64,
    results: &[CommandResult],
) {
    let response = request
        .loan_slice_uninit(results.len())
        .map(|mut response| {
            *response.user_header_mut() = BatchResponseHeader {
                protocol_version: PROTOCOL_VERSION,
                status: status as u32,
                frame,
            };
            response.write_from_slice(results)
        });
    match response.map(|r| r.send()) {
        Ok(Ok(())) => {}
        // Fire-and-forget batches have nobody waiting for the answer.
        Ok(Err(e)) => debug!("batch response not delivered: {e:?}"),
        Err(e) => debug!("batch response not loaned: {e:?}"),
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
