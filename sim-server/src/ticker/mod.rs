//! The ticker domain: the tick service (which admits a single client, so a
//! second would-be ticker cannot even send), tick ownership, the ticks
//! waiting for their frame, and what happens when the ticker dies.

mod ownership;
mod standby;

use iceoryx2::service::port_factory::PortFactory as _;
use simbus_transport::EarlierClients;
use std::collections::VecDeque;
use std::time::Duration;

use iceoryx2::active_request::ActiveRequest;
use iceoryx2::identifiers::UniqueClientId;
use iceoryx2::port::server::Server as RequestServer;
use shared_types::limits::WorldLimits;
use shared_types::{
    CommandResult, FixedText, ResponseStatus, TickRequest, TickRequestKind, TickResponse,
    TickerInfo, PROTOCOL_VERSION,
};
use simbus_transport::stamps::{self, Stage};
use simbus_transport::Bus;
use tracing::{debug, info, warn};

pub(crate) use ownership::{Owner, TickOwnership};
use standby::Standbys;

use crate::batches::{respond_batch, PendingBatch};
use crate::clock::Clock;
use crate::config::OnTickerLoss;
use crate::error::PortError;
use crate::liveness::LiveProcesses;
use crate::ports::{sender_pid, Transport};
use crate::state::{Refusal, Runtime};

type TickServer = RequestServer<Bus, TickRequest, (), TickResponse, ()>;
type PendingTick = ActiveRequest<Bus, TickRequest, (), TickResponse, ()>;

/// A request for one frame step, answered once the frame is published.
#[derive(Debug)]
pub(crate) enum PendingStep {
    /// `Ticker::tick`.
    Tick(PendingTick),
    /// `apply_batch_sync(.., tick = true)`, with the batch's results.
    Batch(PendingBatch, Vec<CommandResult>),
}

/// The tick service, its owner and the steps waiting for a frame.
#[derive(Debug)]
pub(crate) struct Ticker {
    port: TickServer,
    /// The previous server's clients (their requests are dropped).
    earlier: EarlierClients,
    ownership: TickOwnership,
    pending: VecDeque<PendingStep>,
    /// Claims waiting for the world to be free.
    standbys: Standbys,
}

impl Ticker {
    /// Opens the tick service.
    pub(crate) fn open(transport: &Transport, limits: &WorldLimits) -> Result<Self, PortError> {
        let service = transport
            .services
            .tick
            .open_or_create(&transport.node, limits)
            .map_err(|e| PortError::transport("tick service", e))?;
        let earlier = EarlierClients::of(service.dynamic_config());
        let port = service
            .server_builder()
            .create()
            .map_err(|e| PortError::transport("tick server", e))?;
        Ok(Self {
            port,
            earlier,
            ownership: TickOwnership::default(),
            pending: VecDeque::new(),
            standbys: Standbys::default(),
        })
    }

    /// The owner as it travels on the wire.
    pub(crate) fn info(&self) -> TickerInfo {
        self.ownership.info()
    }

    /// The owner's process id, if a ticker holds the world.
    pub(crate) fn owner_pid(&self) -> Option<u32> {
        self.ownership.owner().map(|o| o.pid)
    }

    /// Whether a tick (or a ticking batch) waits for its frame.
    pub(crate) fn has_pending(&self) -> bool {
        !self.pending.is_empty()
    }

    /// Forgets the steps whose sender stopped waiting (a tick that timed
    /// out on the client): no frame is stepped for nobody. Call before a
    /// step, not on every turn of the loop (it takes a lock per step).
    pub(crate) fn drop_abandoned(&mut self) {
        let before = self.pending.len();
        self.pending.retain(|step| match step {
            PendingStep::Tick(tick) => tick.is_connected(),
            PendingStep::Batch(batch, _) => batch.is_connected(),
        });
        let dropped = before - self.pending.len();
        if dropped > 0 {
            debug!(dropped, "dropped ticks nobody waits for any more");
        }
    }

    /// Whether a standby ticker waits for the world.
    pub(crate) fn has_standby(&self) -> bool {
        !self.standbys.is_empty()
    }

    /// How many steps wait for a frame.
    pub(crate) fn pending_count(&self) -> usize {
        self.pending.len()
    }

    /// Queues a ticking batch, answered with the frame it steps.
    pub(crate) fn queue_batch(&mut self, request: PendingBatch, results: Vec<CommandResult>) {
        self.pending.push_back(PendingStep::Batch(request, results));
    }

    fn response(&self, status: ResponseStatus, clock: &Clock) -> TickResponse {
        TickResponse::new(
            status,
            clock.frame(),
            clock.elapsed_ns(),
            self.ownership.info(),
        )
    }

    /// Answers every pending request of the ticker; ticks are queued for
    /// the frame loop. Settings from the ticker change `runtime`.
    pub(crate) fn handle(&mut self, runtime: &mut Runtime, clock: &Clock) -> Result<(), PortError> {
        while let Some(request) = self
            .port
            .receive()
            .map_err(|e| PortError::transport("tick receive", e))?
        {
            if self.earlier.sent(request.header()) {
                debug!("dropped a request from a client of the previous server");
                continue;
            }
            if let Some((request, response)) = self.answer(request, runtime, clock) {
                if let Err(e) = request.send_copy(response) {
                    debug!("tick response not delivered (ticker gone?): {e:?}");
                }
            }
        }
        Ok(())
    }

    /// The answer to one request, or None when the request waits: a tick
    /// for its frame, a standby for the world to be free.
    fn answer(
        &mut self,
        request: PendingTick,
        runtime: &mut Runtime,
        clock: &Clock,
    ) -> Option<(PendingTick, TickResponse)> {
        let payload = *request.payload();
        let origin = request.origin();
        // The requesting port's process, as iceoryx2 recorded it; the
        // payload's pid is the client's own word and is not trusted.
        let pid = sender_pid(request.header());
        let kind = TickRequestKind::from_u32(payload.kind);
        if payload.protocol_version != PROTOCOL_VERSION {
            return Some((
                request,
                self.response(ResponseStatus::ProtocolMismatch, clock),
            ));
        }
        if let (Some(by), Some(TickRequestKind::Tick | TickRequestKind::ApplySettings)) =
            (self.ownership.revoked_by(origin), kind)
        {
            let response = TickResponse {
                revoked_by: by,
                ..self.response(ResponseStatus::Revoked, clock)
            };
            return Some((request, response));
        }
        let response = match kind {
            Some(TickRequestKind::Claim) => self.claim(&payload, origin, pid, clock),
            Some(TickRequestKind::Release) => self.release(origin, pid, clock),
            Some(TickRequestKind::Tick) if self.ownership.is_owner(origin) => {
                let frame = clock.frame() + 1 + self.pending.len() as u64;
                stamps::stamp_wake(Stage::ServerWake, frame);
                stamps::stamp(Stage::ServerTick, frame);
                self.pending.push_back(PendingStep::Tick(request));
                return None;
            }
            Some(TickRequestKind::ApplySettings) if self.ownership.is_owner(origin) => {
                let changed = payload.settings.settings().map_err(Refusal::Invalid);
                match changed.and_then(|settings| {
                    runtime.change_settings(settings, true, pid, clock.frame() + 1)
                }) {
                    Ok(effective_frame) => TickResponse {
                        effective_frame,
                        ..self.response(ResponseStatus::Ok, clock)
                    },
                    Err(Refusal::Invalid(error)) => self
                        .response(ResponseStatus::InvalidSettings, clock)
                        .with_settings_error(&error),
                    Err(Refusal::Status(status)) => self.response(status, clock),
                }
            }
            Some(TickRequestKind::Tick | TickRequestKind::ApplySettings) => {
                warn!(
                    pid,
                    "refused a request from a client that is not the ticker"
                );
                self.response(ResponseStatus::NotTicker, clock)
            }
            Some(TickRequestKind::Standby) => {
                let candidate = Self::candidate(&payload, origin, pid, clock);
                match self.standby(candidate, clock) {
                    Ok(granted) => granted,
                    Err(candidate) => {
                        self.queue_standby(request, candidate, clock);
                        return None;
                    }
                }
            }
            None => self.response(ResponseStatus::UnknownRequest, clock),
        };
        Some((request, response))
    }

    /// A claim: granted if the world has no living ticker.
    fn claim(
        &mut self,
        payload: &TickRequest,
        origin: UniqueClientId,
        pid: u32,
        clock: &Clock,
    ) -> TickResponse {
        let candidate = Self::candidate(payload, origin, pid, clock);
        let sweep = LiveProcesses::now();
        match self.ownership.claim(candidate, |pid| sweep.alive(pid)) {
            Ok(owner) => {
                info!(
                    pid = owner.pid,
                    node = %owner.node_name,
                    frame = owner.since_frame,
                    "ticker claimed ownership"
                );
                self.response(ResponseStatus::Ok, clock)
            }
            Err(current) => {
                info!(pid, owner_pid = current.pid, "refused a second ticker");
                self.response(ResponseStatus::NotTicker, clock)
            }
        }
    }

    /// A release: by the ticker (the world goes to the first standby), or
    /// by a standby that stops waiting.
    fn release(&mut self, origin: UniqueClientId, pid: u32, clock: &Clock) -> TickResponse {
        let withdrawn = self.standbys.withdraw(origin);
        if self.ownership.release(origin) {
            info!(pid, frame = clock.frame(), "ticker released ownership");
            self.drop_pending(ResponseStatus::NotTicker, TickerInfo::none(), clock);
            let response = self.response(ResponseStatus::Ok, clock);
            self.grant_standby(&LiveProcesses::now(), clock);
            response
        } else if withdrawn {
            debug!(pid, "a standby ticker stopped waiting");
            self.response(ResponseStatus::Ok, clock)
        } else {
            self.response(ResponseStatus::NotTicker, clock)
        }
    }

    /// Answers the first `count` waiting steps with the frame just published
    /// (`synchronous`: in synchronous mode, where a tick answered by its
    /// frame gets no other answer; an asynchronous world's frames come
    /// whatever ticks, so there every tick is answered).
    pub(crate) fn answer_stepped(&mut self, count: usize, clock: &Clock, synchronous: bool) {
        for _ in 0..count {
            let Some(step) = self.pending.pop_front() else {
                break;
            };
            match step {
                // Answered by its frame, published already: no answer.
                PendingStep::Tick(tick)
                    if synchronous && tick.payload().flags & TickRequest::BY_FRAME != 0 => {}
                PendingStep::Tick(tick) => {
                    let response = self.response(ResponseStatus::Ok, clock);
                    if let Err(e) = tick.send_copy(response) {
                        debug!("tick response not delivered (ticker gone?): {e:?}");
                    }
                }
                PendingStep::Batch(request, results) => {
                    respond_batch(&request, ResponseStatus::Ok, clock.frame(), &results)
                }
            }
        }
    }

    /// Answers every waiting step with `status` (the ticker released, died
    /// or was revoked by `revoked_by`).
    pub(crate) fn drop_pending(
        &mut self,
        status: ResponseStatus,
        revoked_by: TickerInfo,
        clock: &Clock,
    ) {
        for step in std::mem::take(&mut self.pending) {
            match step {
                PendingStep::Tick(tick) => {
                    let response = TickResponse {
                        revoked_by,
                        ..self.response(status, clock)
                    };
                    if let Err(e) = tick.send_copy(response) {
                        debug!("tick answer not delivered (ticker gone?): {e:?}");
                    }
                }
                PendingStep::Batch(request, results) => {
                    respond_batch(&request, status, clock.frame(), &results)
                }
            }
        }
    }

    /// Ends the ticker's ownership because `by` left synchronous mode: its
    /// waiting ticks and its next requests are told who did.
    pub(crate) fn revoke(&mut self, by: TickerInfo, clock: &Clock) {
        if let Some(owner) = self.ownership.revoke(by) {
            warn!(
                pid = by.pid,
                name = %by.node_name.to_string_lossy(),
                ticker_pid = owner.pid,
                frame = clock.frame(),
                "another client left synchronous mode; the ticker's ownership ends"
            );
        }
        self.drop_pending(ResponseStatus::Revoked, by, clock);
        if !self.standbys.is_empty() {
            self.grant_standby(&LiveProcesses::now(), clock);
        }
    }

    /// Tells the waiting tick which lockstep participant holds it up and how
    /// long the server waits for it (an interim answer; the frame follows).
    pub(crate) fn tell_held_up(
        &self,
        participant: TickerInfo,
        lockstep_timeout: Duration,
        clock: &Clock,
    ) {
        if let Some(PendingStep::Tick(tick)) = self.pending.front() {
            let response = TickResponse {
                waiting_for: participant,
                lockstep_timeout_ns: u64::try_from(lockstep_timeout.as_nanos()).unwrap_or(u64::MAX),
                ..self.response(ResponseStatus::WaitingForParticipants, clock)
            };
            if let Err(e) = tick.send_copy(response) {
                debug!("interim tick answer not delivered: {e:?}");
            }
        }
    }

    /// Drops a ticker whose process died (by `sweep`), applying `policy`;
    /// returns whether it did (its port is freed by the next cleanup, which
    /// takes ~15 ms: after the claims and status requests already waiting).
    pub(crate) fn drop_if_dead(
        &mut self,
        sweep: &LiveProcesses,
        runtime: &mut Runtime,
        policy: OnTickerLoss,
        clock: &Clock,
    ) -> bool {
        let Some(lost) = self.ownership.take_if_dead(|pid| sweep.alive(pid)) else {
            return false;
        };
        self.drop_pending(ResponseStatus::NotTicker, TickerInfo::none(), clock);
        let frame = clock.frame();
        match (runtime.settings.synchronous_mode, policy) {
            (true, OnTickerLoss::Async) => {
                runtime.settings.synchronous_mode = false;
                runtime.pacer.reset();
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
        // A standby takes over at once: its answer goes out now, and the
        // frame-ready event the loop rings after a drop wakes it.
        self.grant_standby(sweep, clock);
        true
    }

    /// The owner a claim (or standby claim) of `payload` from the port
    /// `origin` of process `pid` would make.
    fn candidate(payload: &TickRequest, origin: UniqueClientId, pid: u32, clock: &Clock) -> Owner {
        let on_behalf = payload.flags & TickRequest::ON_BEHALF != 0;
        Owner {
            client: origin,
            pid,
            reported_pid: if on_behalf { payload.pid } else { pid },
            node_name: payload.node_name.to_string_lossy(),
            since_frame: clock.frame(),
        }
    }

    /// A standby claim: granted now (the answer) when no other standby
    /// waits and nobody live holds the world; otherwise `candidate` back,
    /// to be queued.
    fn standby(&mut self, candidate: Owner, clock: &Clock) -> Result<TickResponse, Owner> {
        if !self.standbys.is_empty() {
            return Err(candidate);
        }
        let sweep = LiveProcesses::now();
        let claimed = self.ownership.claim(candidate.clone(), |p| sweep.alive(p));
        match claimed {
            Ok(owner) => {
                let (pid, node) = (owner.pid, &owner.node_name);
                info!(pid, %node, frame = owner.since_frame, "standby claimed a free world");
                Ok(self.response(ResponseStatus::Ok, clock))
            }
            Err(_) => Err(candidate),
        }
    }

    /// Queues a standby claim behind the owner (and the standbys before
    /// it), telling it at once who owns the world (an interim answer).
    fn queue_standby(&mut self, request: PendingTick, candidate: Owner, clock: &Clock) {
        let (pid, node) = (candidate.pid, &candidate.node_name);
        let owner_pid = self.ownership.info().pid;
        info!(pid, %node, owner_pid, "standby ticker waits for the world");
        if let Err(e) = request.send_copy(self.response(ResponseStatus::NotTicker, clock)) {
            debug!("interim standby answer not delivered: {e:?}");
        }
        self.standbys.push(request, candidate);
    }

    /// Nobody holds the world: makes the oldest live standby the owner and
    /// answers its claim (the moment it learns it ticks). Returns whether
    /// one took over.
    fn grant_standby(&mut self, sweep: &LiveProcesses, clock: &Clock) -> bool {
        while self.ownership.owner().is_none() {
            let Some(waiting) = self.standbys.next_alive(|pid| sweep.alive(pid)) else {
                return false;
            };
            let candidate = Owner {
                since_frame: clock.frame(),
                ..waiting.candidate
            };
            let client = candidate.client;
            let Some(owner) = self.ownership.grant(candidate) else {
                return false;
            };
            let granted = self.response(ResponseStatus::Ok, clock);
            match waiting.request.send_copy(granted) {
                Ok(_) => {
                    let (pid, node) = (owner.pid, &owner.node_name);
                    info!(pid, %node, frame = owner.since_frame, "standby ticker took over");
                    return true;
                }
                Err(e) => {
                    debug!("standby not told it took over (gone?): {e:?}");
                    self.ownership.release(client);
                }
            }
        }
        false
    }

    /// The client info of a process `pid` named `name`, as a ticker answer
    /// names it (who revoked, who holds a tick up).
    pub(crate) fn named(pid: u32, name: FixedText, frame: u64) -> TickerInfo {
        TickerInfo {
            active: 1,
            pid,
            since_frame: frame,
            node_name: name,
        }
    }
}
