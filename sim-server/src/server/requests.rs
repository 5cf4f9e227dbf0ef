//! The server's answers: control (settings, status, worlds), ticks and tick
//! ownership, command batches, lockstep participants and sensors. Every
//! handler drains its service at a frame boundary, so whatever arrived before
//! a step applies before it.

use std::time::Instant;

use iceoryx2::active_request::ActiveRequest;
use iceoryx2::prelude::ipc;
use shared_types::{
    BatchHeader, BatchResponseHeader, Command, CommandResult, CommandStatus, ControlRequest,
    ControlResponse, LockstepKind, LockstepRequest, LockstepResponse, RequestKind, ResponseStatus,
    SensorEnd, SensorInfo, SensorRequestKind, SensorResponseHeader, TickRequestKind, TickResponse,
    TickerInfo, WorldSettings, PROTOCOL_VERSION,
};
use tracing::{debug, info, warn};

use super::{describe, PendingStep, Refusal, Server};
use crate::clock::Clock;
use crate::scene::Scene;
use crate::ticker::{node_process_alive, Owner};
use crate::world::World;
use crate::ServerError;

/// A batch request (already applied) waiting for the answer.
pub(super) type PendingBatch =
    ActiveRequest<ipc::Service, [Command], BatchHeader, [CommandResult], BatchResponseHeader>;

impl Server {
    /// Answers every pending control request.
    pub(super) fn handle_control(&mut self) -> Result<(), ServerError> {
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
        let settings = WorldSettings::from(request.settings).normalized();
        // While a ticker holds the world only it changes settings; anyone
        // may leave synchronous mode (CARLA's escape hatch), which ends the
        // ticker's ownership.
        if let Some(owner) = self.ownership.owner() {
            let leaving_sync = self.settings.synchronous_mode
                && settings
                    == WorldSettings {
                        synchronous_mode: false,
                        ..self.settings
                    };
            if leaving_sync {
                let by = TickerInfo {
                    active: 1,
                    pid: request.client_pid,
                    since_frame: self.clock.frame(),
                    node_name: request.client_name,
                };
                warn!(
                    pid = request.client_pid,
                    name = %request.client_name.to_string_lossy(),
                    ticker_pid = owner.pid,
                    frame = self.clock.frame(),
                    "another client left synchronous mode; the ticker's ownership ends"
                );
                self.ownership.revoke(by);
                self.drop_pending_ticks(ResponseStatus::Revoked, by);
            } else if settings != self.settings {
                info!(
                    pid = request.client_pid,
                    ticker_pid = owner.pid,
                    "refused settings: the ticker holds the world"
                );
                return ControlResponse::refused(ResponseStatus::NotOwner, self.report());
            }
        }
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
    pub(super) fn handle_ticks(&mut self) -> Result<(), ServerError> {
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
            let kind = TickRequestKind::from_u32(payload.kind);
            let revoked_by = self.ownership.revoked_by(origin);
            let response = if payload.protocol_version != PROTOCOL_VERSION {
                respond(self, ResponseStatus::ProtocolMismatch)
            } else if let (Some(by), Some(TickRequestKind::Tick | TickRequestKind::ApplySettings)) =
                (revoked_by, kind)
            {
                TickResponse {
                    revoked_by: by,
                    ..respond(self, ResponseStatus::Revoked)
                }
            } else {
                match kind {
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
                            self.drop_pending_ticks(ResponseStatus::NotOwner, TickerInfo::none());
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

    /// Answers the ticker's pending ticks and ticking batches with
    /// `status` (it released, died or was revoked by `revoked_by`).
    pub(super) fn drop_pending_ticks(&mut self, status: ResponseStatus, revoked_by: TickerInfo) {
        for step in self.pending_steps.drain(..) {
            match step {
                PendingStep::Tick(tick) => {
                    let response = TickResponse {
                        revoked_by,
                        ..TickResponse::new(
                            status,
                            self.clock.frame(),
                            self.clock.elapsed_ns(),
                            self.ownership.info(),
                        )
                    };
                    if let Err(e) = tick.send_copy(response) {
                        debug!("tick answer not delivered (ticker gone?): {e:?}");
                    }
                }
                PendingStep::Batch(request, results) => {
                    respond_batch(&request, status, self.clock.frame(), &results)
                }
            }
        }
    }

    /// Applies every pending batch, in arrival order, at this frame boundary.
    pub(super) fn handle_batches(&mut self) -> Result<(), ServerError> {
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
            // A sensor dies with the actor it rides on.
            self.sensors
                .end_orphans(&self.world, self.clock.frame(), self.episode);
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
    pub(super) fn handle_lockstep(&mut self) -> Result<(), ServerError> {
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
                        if !self.participants.contains(origin) {
                            // Dropped (hung past the timeout) or never joined:
                            // the answer tells it so.
                            ResponseStatus::NotParticipant
                        } else {
                            // A "done" for an earlier episode means nothing now.
                            if payload.episode == self.episode {
                                self.participants.done(origin, payload.frame);
                            }
                            ResponseStatus::Ok
                        }
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

    /// Spawns, destroys and lists sensors.
    pub(super) fn handle_sensor_requests(&mut self) -> Result<(), ServerError> {
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
                        if self
                            .sensors
                            .destroy(payload.id, self.clock.frame(), self.episode)
                        {
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
        // Sensors belong to the episode: their readers learn it ended.
        self.sensors
            .end_all(SensorEnd::EpisodeEnded, self.clock.frame(), self.episode);
        // Ids go on from the last episode's: never reused in a server's life.
        let first_id = self.world.next_id();
        self.world = World::new(&scene.placements(self.config.seed), first_id);
        self.config.scene = scene;
        self.clock = Clock::new(now);
        self.episode += 1;
        self.pace_anchor = None;
        self.participants.new_episode();
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
}

/// Answers a batch with `status`, the frame it concerns and its results.
pub(super) fn respond_batch(
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
