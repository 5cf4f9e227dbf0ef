//! Commands in batches: fire and forget, or with one result per command.

use std::time::Duration;

use iceoryx2::prelude::*;
use shared_types::{
    BatchHeader, BatchResponseHeader, Command, CommandResult, CommandStatus, ResponseStatus,
    ServiceNames,
};
use simbus_transport::spec::WorldServices;
use simbus_transport::Bus;

use crate::rpc::{client_error, Pending, RequestPort, Wait};
use crate::{Client, RequestError};

/// The batch service's request port.
pub(crate) type BatchClient =
    RequestPort<[Command], [CommandResult], BatchHeader, BatchResponseHeader>;

type PendingBatch = Pending<[Command], [CommandResult], BatchHeader, BatchResponseHeader>;

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
    /// A spawn was refused because its body would overlap `occupant`'s
    /// (CARLA's "Spawn failed because of collision at spawn position");
    /// nothing was spawned.
    #[error(
        "spawn failed because of a collision at the spawn position: actor {occupant} is there"
    )]
    SpawnCollision {
        /// The actor whose body is where the new one would be.
        occupant: u64,
    },
    /// The batch failed.
    #[error(transparent)]
    Batch(#[from] BatchError),
}

/// Opens a batch port on `node` to `world`, whose services `names` names
/// (its server `server_pid`); it wakes the server through its client.
pub(crate) fn open_batch_client(
    node: &Node<Bus>,
    names: &ServiceNames,
    world: &str,
    server_pid: u32,
) -> Result<BatchClient, RequestError> {
    let specs =
        WorldServices::new(names).map_err(|e| RequestError::transport("service name", e))?;
    let service = specs
        .batch
        .open(node)
        .map_err(|e| RequestError::transport("batch service", e))?;
    let client = specs.batch.client(&service).map_err(|e| {
        let max = service.static_config().max_clients();
        client_error(e, max, "clients sending command batches", "batch client")
    })?;
    Ok(RequestPort::new(
        client,
        None,
        specs.batch.doorbell,
        "batch send",
        world,
        server_pid,
    ))
}

impl Client {
    /// Sends an empty batch on `port` and waits up to `timeout` for its answer.
    pub(crate) fn round_trip_empty_batch(
        &self,
        port: &BatchClient,
        timeout: Duration,
    ) -> Result<(), RequestError> {
        port.request_waking(
            (BatchHeader::new(false), &[][..]),
            self,
            timeout,
            Wait::Backoff,
        )
        .map(drop)
    }

    fn send_batch(&self, commands: &[Command], tick: bool) -> Result<PendingBatch, RequestError> {
        self.batch()?
            .send_waking((BatchHeader::new(tick), commands), self)
    }

    /// Sends `commands` to be applied, in order, at the next frame boundary,
    /// and returns without waiting (CARLA's `apply_batch`). Batches from one
    /// client are applied in the order sent; none is dropped.
    ///
    /// # Errors
    ///
    /// Returns [`RequestError`] if the batch cannot be sent: opening the batch
    /// port on first use fails ([`RequestError::Full`] if the world admits no
    /// more clients sending batches, [`RequestError::Timeout`] if the server
    /// does not answer the port's first, empty batch within the request
    /// timeout, [`RequestError::Transport`] if iceoryx2 refuses), or iceoryx2
    /// cannot loan or send the request ([`RequestError::Transport`]). A command
    /// the server refuses is not an error here: use
    /// [`Client::apply_batch_sync`] to see each command's result.
    pub fn apply_batch(&self, commands: &[Command]) -> Result<(), RequestError> {
        self.send_batch(commands, false).map(drop)
    }

    /// Applies `commands` atomically at the next frame boundary, in order.
    ///
    /// Returns one result per command and the frame that first shows them.
    /// With `tick`, one frame is then stepped (only the ticker's process may
    /// ask), and `frame` is that frame.
    ///
    /// # Errors
    ///
    /// Returns [`BatchError::NotTicker`] if `tick` is asked by a process that
    /// is not the ticker (nothing applied); [`BatchError::NotStepped`] (with
    /// the results) if the batch was applied but the ticker released, died or
    /// was revoked before its frame was stepped; [`BatchError::Replaying`] if
    /// the world is replaying a recording (nothing applied); and
    /// [`BatchError::Request`] if the batch cannot be sent or is not answered
    /// within the request timeout ([`RequestError::Timeout`],
    /// [`RequestError::ServerGone`], [`RequestError::Full`], ...).
    ///
    /// A command the server refuses is not an error of the batch: it has its
    /// status in [`BatchResponse::results`] (see [`BatchResponse::errors`]).
    ///
    /// # Examples
    ///
    /// A server runs on a thread here, so the example runs as a test:
    ///
    /// ```
    /// use std::time::Duration;
    /// use sim_client::Client;
    /// use shared_types::Command;
    ///
    /// # fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// # use std::sync::{atomic::{AtomicBool, Ordering}, Arc};
    /// # let name = format!("doc-{}-{}", "batch", std::process::id());
    /// # let stop = Arc::new(AtomicBool::new(false));
    /// # let server = {
    /// #     let (stop, world) = (stop.clone(), shared_types::WorldName::new(&name)?);
    /// #     std::thread::spawn(move || {
    /// #         let mut config = sim_server::ServerConfig::new(world);
    /// #         config.settings.fixed_delta_seconds = Some(0.01);
    /// #         config.realtime = true;
    /// #         config.scene = sim_server::Scene::Empty;
    /// #         sim_server::Server::start(config).and_then(|mut s| s.run(&stop))
    /// #     })
    /// # };
    /// let mut client = Client::connect(&name, Duration::from_secs(5))?;
    /// let before = client.wait_for_tick(Duration::from_secs(1))?.actors.len();
    /// let response = client.apply_batch_sync(
    ///     &[
    ///         Command::spawn_box([0.0, 5.0, 0.0], [0.5, 0.5, 0.5]),
    ///         Command::spawn_sphere([3.0, 5.0, 0.0], 0.5),
    ///     ],
    ///     false,
    /// )?;
    /// assert_eq!(response.results.len(), 2);
    /// assert!(response.errors().is_empty());
    /// // `response.frame` is the first frame that shows both.
    /// let snapshot = loop {
    ///     let snapshot = client.wait_for_tick(Duration::from_secs(1))?;
    ///     if snapshot.frame() >= response.frame {
    ///         break snapshot;
    ///     }
    /// };
    /// assert_eq!(snapshot.actors.len(), before + 2);
    /// assert!(snapshot.find(response.results[0].actor).is_some());
    /// # drop(client);
    /// # stop.store(true, Ordering::Relaxed);
    /// # server.join().expect("server thread")?;
    /// # Ok(())
    /// # }
    /// ```
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
        // The response is a slice: read in place, the results copied out.
        let answer = self.batch()?.answer(&pending, self.request_timeout, wait)?;
        let header = answer.header;
        let response = BatchResponse {
            frame: header.frame,
            results: answer.items,
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
            Some(CommandStatus::SpawnCollision) => Err(CommandError::SpawnCollision {
                occupant: result.actor,
            }),
            status => Err(CommandError::Refused {
                actor: command.actor,
                status: status.unwrap_or(CommandStatus::UnknownCommand),
            }),
        }
    }

    /// Spawns an actor (a `Command::spawn_*`) and returns its id.
    ///
    /// # Errors
    ///
    /// Returns [`CommandError::SpawnCollision`] (naming the occupant) if the
    /// new actor's body would overlap another's, [`CommandError::Refused`]
    /// (with the [`CommandStatus`]) if the server refuses the spawn for another
    /// reason, and [`CommandError::Batch`] if the batch fails as in
    /// [`Client::apply_batch_sync`] (a replay running, the request timing out,
    /// ...). Nothing is spawned in any of these cases.
    pub fn spawn_actor(&self, spawn: Command) -> Result<u64, CommandError> {
        self.single(spawn)
    }

    /// Removes actor `id`.
    ///
    /// # Errors
    ///
    /// Returns [`CommandError::Refused`] (with the [`CommandStatus`], such as
    /// an unknown actor) if the server refuses, and [`CommandError::Batch`] if
    /// the batch fails as in [`Client::apply_batch_sync`].
    pub fn destroy(&self, id: u64) -> Result<(), CommandError> {
        self.single(Command::destroy(id)).map(drop)
    }
}
