//! The batch domain: command batches, applied atomically and in order at a
//! frame boundary, answered with one result per command (written straight
//! into the loaned response), or queued with the ticker when they tick.

use iceoryx2::active_request::ActiveRequest;
use iceoryx2::port::server::Server as RequestServer;
use iceoryx2::service::port_factory::PortFactory as _;
use shared_types::limits::WorldLimits;
use shared_types::{
    BatchHeader, BatchResponseHeader, Command, CommandResult, CommandStatus, ResponseStatus,
    PROTOCOL_VERSION,
};
use simbus_transport::Bus;
use simbus_transport::EarlierClients;
use tracing::{debug, warn};

use crate::clock::Clock;
use crate::error::PortError;
use crate::ports::{sender_pid, Transport};
use crate::world::World;

type BatchServer = RequestServer<Bus, [Command], BatchHeader, [CommandResult], BatchResponseHeader>;

/// A batch request (already applied) waiting for its answer.
pub(crate) type PendingBatch =
    ActiveRequest<Bus, [Command], BatchHeader, [CommandResult], BatchResponseHeader>;

/// What applying batches asks of the other domains, for the loop to do.
#[derive(Debug)]
pub(crate) enum BatchEffect<'a> {
    /// A command was applied for the next frame, with this result (a
    /// recording keeps both).
    Applied(&'a Command, &'a CommandResult),
    /// A ticking batch, applied, waits for its frame: the ticker answers it.
    Tick(PendingBatch, Vec<CommandResult>),
}

/// The batch service.
#[derive(Debug)]
pub(crate) struct Batches {
    port: BatchServer,
    /// The previous server's clients (their requests are dropped).
    earlier: EarlierClients,
}

impl Batches {
    /// Opens the batch service. A batch is never dropped: a sender that
    /// outruns the server waits.
    pub(crate) fn open(transport: &Transport, limits: &WorldLimits) -> Result<Self, PortError> {
        let spec = &transport.services.batch;
        let service = spec
            .open_or_create(&transport.node, limits)
            .map_err(|e| PortError::transport("batch service", e))?;
        let earlier = EarlierClients::of(service.dynamic_config());
        let port = spec
            .server(&service)
            .map_err(|e| PortError::transport("batch server", e))?;
        Ok(Self { port, earlier })
    }

    /// Applies every pending batch, in arrival order, at this frame
    /// boundary; what that asks of the other domains goes to `effect`
    /// (every command applied, for the recording; every ticking batch, for
    /// the ticker `ticker_pid`). Returns whether a batch was applied: a
    /// sensor whose parent a batch destroyed then ends with it.
    pub(crate) fn handle(
        &mut self,
        world: &mut World,
        ticker_pid: Option<u32>,
        clock: &Clock,
        mut effect: impl FnMut(BatchEffect<'_>),
    ) -> Result<bool, PortError> {
        let mut applied = false;
        while let Some(request) = self
            .port
            .receive()
            .map_err(|e| PortError::transport("batch receive", e))?
        {
            if self.earlier.sent(request.header()) {
                debug!("dropped a request from a client of the previous server");
                continue;
            }
            let header = *request.user_header();
            let next_frame = clock.frame() + 1;
            if header.protocol_version != PROTOCOL_VERSION {
                respond_batch(&request, ResponseStatus::ProtocolMismatch, next_frame, &[]);
                continue;
            }
            let tick = header.flags & BatchHeader::TICK != 0;
            // Who may tick is decided by the sending port's process, never
            // by the pid the header claims.
            let sender = sender_pid(request.header());
            if tick && ticker_pid != Some(sender) {
                warn!(
                    pid = sender,
                    claimed_pid = header.pid,
                    "refused a ticking batch from a process that is not the ticker"
                );
                respond_batch(&request, ResponseStatus::NotTicker, next_frame, &[]);
                continue;
            }
            if tick {
                apply_ticking(request, world, sender, &mut effect);
            } else {
                apply_answered(&request, world, sender, next_frame, &mut effect);
            }
            applied = true;
        }
        Ok(applied)
    }
}

impl Batches {
    /// Refuses every pending batch: a replay runs, its actors follow the
    /// recording (and a spawn would shift the recorded actor ids).
    pub(crate) fn refuse_while_replaying(&mut self, clock: &Clock) -> Result<(), PortError> {
        while let Some(request) = self
            .port
            .receive()
            .map_err(|e| PortError::transport("batch receive", e))?
        {
            if self.earlier.sent(request.header()) {
                debug!("dropped a request from a client of the previous server");
                continue;
            }
            debug!(
                pid = sender_pid(request.header()),
                "refused a batch: a replay runs"
            );
            respond_batch(&request, ResponseStatus::Replaying, clock.frame() + 1, &[]);
        }
        Ok(())
    }
}

/// Applies a ticking batch; its answer waits for the frame, so the results
/// are kept and the batch goes to the ticker (`effect`).
fn apply_ticking(
    request: PendingBatch,
    world: &mut World,
    sender: u32,
    effect: &mut impl FnMut(BatchEffect<'_>),
) {
    let results: Vec<CommandResult> = request
        .payload()
        .iter()
        .map(|c| {
            let result = world.apply(c);
            effect(BatchEffect::Applied(c, &result));
            result
        })
        .collect();
    debug!(
        pid = sender,
        commands = results.len(),
        "ticking batch applied"
    );
    effect(BatchEffect::Tick(request, results));
}

/// Applies a batch and answers it at once, each result written straight
/// into the loaned answer (applied all the same when no answer can be
/// loaned).
fn apply_answered(
    request: &PendingBatch,
    world: &mut World,
    sender: u32,
    next_frame: u64,
    effect: &mut impl FnMut(BatchEffect<'_>),
) {
    let commands = request.payload();
    let mut failed = 0;
    match request.loan_slice_uninit(commands.len()) {
        Ok(mut response) => {
            *response.user_header_mut() = BatchResponseHeader {
                protocol_version: PROTOCOL_VERSION,
                status: ResponseStatus::Ok as u32,
                frame: next_frame,
            };
            let response = response.write_from_fn(|i| {
                let result = world.apply(&commands[i]);
                effect(BatchEffect::Applied(&commands[i], &result));
                failed += usize::from(result.status != CommandStatus::Ok as u32);
                result
            });
            if let Err(e) = response.send() {
                // Fire-and-forget batches have nobody waiting.
                debug!("batch response not delivered: {e:?}");
            }
        }
        Err(e) => {
            debug!("batch response not loaned: {e:?}");
            for command in commands {
                let result = world.apply(command);
                effect(BatchEffect::Applied(command, &result));
            }
        }
    }
    debug!(
        pid = sender,
        commands = commands.len(),
        failed,
        "batch applied"
    );
}

/// Answers a batch with `status`, the frame it concerns and its results.
pub(crate) fn respond_batch(
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
