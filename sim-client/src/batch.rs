//! Commands in batches: fire and forget, or with one result per command.

use shared_types::Bus;
use std::time::Duration;

use iceoryx2::port::client::Client as RequestClient;
use iceoryx2::prelude::*;
use shared_types::limits::{INITIAL_MAX_BATCH, MAX_CLIENTS_FLAG};
use shared_types::{
    BatchHeader, BatchResponseHeader, Command, CommandResult, CommandStatus, ResponseStatus,
};

use crate::rpc::{await_slice_response, check_answer, Wait};
use crate::{Client, RequestError};

pub(crate) type BatchClient =
    RequestClient<Bus, [Command], BatchHeader, [CommandResult], BatchResponseHeader>;

type PendingBatch = iceoryx2::pending_response::PendingResponse<
    Bus,
    [Command],
    BatchHeader,
    [CommandResult],
    BatchResponseHeader,
>;

/// The answer to [`Client::apply_batch_sync`].
#[derive(Debug, Clone, PartialEq)]
pub struct BatchResponse {
    /// The first frame that shows the batch's effects (with `tick`: the
    /// frame that was stepped).
    pub frame: u64,
    /// One result per command, in order.
    pub results: Vec<CommandResult>,
}

impl BatchResponse {
    /// The commands that failed: (index in the batch, what went wrong).
    pub fn errors(&self) -> Vec<(usize, CommandStatus)> {
        self.results
            .iter()
            .enumerate()
            .filter_map(|(i, r)| match CommandStatus::from_u32(r.status) {
                Some(CommandStatus::Ok) => None,
                status => Some((i, status.unwrap_or(CommandStatus::UnknownCommand))),
            })
            .collect()
    }
}

/// Why a batch as a whole failed (single commands fail in their results).
#[derive(Debug, thiserror::Error)]
pub enum BatchError {
    /// `tick = true` from a process that is not the ticker; nothing applied.
    #[error("only the ticker's process may apply a batch with tick = true")]
    NotTicker,
    /// A ticking batch was applied, but its frame was never stepped: the
    /// ticker released, died or was revoked meanwhile (the results say what
    /// each command did).
    #[error("the batch was applied at frame {}, but its tick was dropped: this process is no longer the ticker", .0.frame)]
    NotStepped(BatchResponse),
    /// The world is replaying a recording; nothing applied. Commands work
    /// again when the replay ends (or after `stop_replayer`).
    #[error("the world is replaying a recording: its actors follow the recording, so commands are refused until the replay ends (or stop_replayer)")]
    Replaying,
    /// The request failed.
    #[error(transparent)]
    Request(#[from] RequestError),
}

/// Why a single command (spawn, destroy) failed.
#[derive(Debug, thiserror::Error)]
pub enum CommandError {
    /// The server refused the command.
    #[error("actor {actor}: {status}")]
    Refused {
        /// The actor named by the command.
        actor: u64,
        /// What went wrong.
        status: CommandStatus,
    },
    /// The batch failed.
    #[error(transparent)]
    Batch(#[from] BatchError),
}

pub(crate) fn open_batch_client(node: &Node<Bus>, name: &str) -> Result<BatchClient, RequestError> {
    use iceoryx2::service::port_factory::client::ClientCreateError;
    let name = ServiceName::new(name).map_err(|e| RequestError::transport("service name", e))?;
    let service = node
        .service_builder(&name)
        .request_response::<[Command], [CommandResult]>()
        .request_user_header::<BatchHeader>()
        .response_user_header::<BatchResponseHeader>()
        .open()
        .map_err(|e| RequestError::transport("batch service", e))?;
    service
        .client_builder()
        .initial_max_slice_len(INITIAL_MAX_BATCH)
        .allocation_strategy(AllocationStrategy::PowerOfTwo)
        .create()
        .map_err(|e| match e {
            ClientCreateError::ExceedsMaxSupportedClients => RequestError::Full {
                what: "clients sending command batches",
                max: service.static_config().max_clients(),
                flag: MAX_CLIENTS_FLAG,
            },
            e => RequestError::transport("batch client", e),
        })
}

impl Client {
    /// Sends an empty batch on `port` and waits up to `timeout` for its answer.
    pub(crate) fn round_trip_empty_batch(
        &self,
        port: &BatchClient,
        timeout: Duration,
    ) -> Result<(), RequestError> {
        let pending = self.send_batch_on(port, &[], false)?;
        let (header, _) = await_slice_response(
            &pending,
            timeout,
            self.world.as_str(),
            self.server_pid,
            Wait::Backoff,
        )?;
        check_answer(&header, self.world.as_str())
    }

    fn send_batch(&self, commands: &[Command], tick: bool) -> Result<PendingBatch, RequestError> {
        self.send_batch_on(self.batch()?, commands, tick)
    }

    fn send_batch_on(
        &self,
        port: &BatchClient,
        commands: &[Command],
        tick: bool,
    ) -> Result<PendingBatch, RequestError> {
        let mut request = port
            .loan_slice_uninit(commands.len())
            .map_err(|e| RequestError::transport("batch loan", e))?;
        *request.user_header_mut() = BatchHeader::new(tick);
        let pending = request
            .write_from_slice(commands)
            .send()
            .map_err(|e| RequestError::transport("batch send", e))?;
        self.wake_server()?;
        Ok(pending)
    }

    /// Sends `commands` to be applied, in order, at the next frame boundary,
    /// and returns without waiting (CARLA's `apply_batch`). Batches from one
    /// client are applied in the order sent; none is dropped.
    pub fn apply_batch(&self, commands: &[Command]) -> Result<(), RequestError> {
        self.send_batch(commands, false).map(drop)
    }

    /// Applies `commands` atomically at the next frame boundary, in order,
    /// and returns one result per command and the frame that first shows
    /// them. With `tick`, one frame is then stepped (only the ticker's
    /// process may ask), and `frame` is that frame.
    pub fn apply_batch_sync(
        &self,
        commands: &[Command],
        tick: bool,
    ) -> Result<BatchResponse, BatchError> {
        let pending = self.send_batch(commands, tick)?;
        let wait = if tick {
            Wait::for_mode(self.frames.mode, self.frames.ready())
        } else {
            Wait::Backoff
        };
        // The response is a slice: read it in place and copy the results out.
        let (header, results) = await_slice_response(
            &pending,
            self.request_timeout,
            self.world.as_str(),
            self.server_pid,
            wait,
        )?;
        check_answer(&header, self.world.as_str())?;
        let response = BatchResponse {
            frame: header.frame,
            results,
        };
        match ResponseStatus::from_u32(header.status) {
            Some(ResponseStatus::Ok) => Ok(response),
            Some(ResponseStatus::Replaying) => Err(BatchError::Replaying),
            Some(ResponseStatus::NotTicker) if response.results.is_empty() => {
                Err(BatchError::NotTicker)
            }
            // Applied, but the frame it asked for was never stepped: the
            // ticker released, died or was revoked meanwhile.
            Some(ResponseStatus::NotTicker | ResponseStatus::Revoked) => {
                Err(BatchError::NotStepped(response))
            }
            _ => Err(RequestError::UnknownAnswer {
                status: header.status,
            }
            .into()),
        }
    }

    fn single(&self, command: Command) -> Result<u64, CommandError> {
        let response = self.apply_batch_sync(&[command], false)?;
        let result = response.results.first().copied().unwrap_or_default();
        match CommandStatus::from_u32(result.status) {
            Some(CommandStatus::Ok) => Ok(result.actor),
            status => Err(CommandError::Refused {
                actor: command.actor,
                status: status.unwrap_or(CommandStatus::UnknownCommand),
            }),
        }
    }

    /// Spawns an actor (a `Command::spawn_*`) and returns its id.
    pub fn spawn_actor(&self, spawn: Command) -> Result<u64, CommandError> {
        self.single(spawn)
    }

    /// Removes actor `id`.
    pub fn destroy(&self, id: u64) -> Result<(), CommandError> {
        self.single(Command::destroy(id)).map(drop)
    }
}
