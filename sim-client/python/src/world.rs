//! Actors and batches: `client.spawn(kind, at=...)`, `client.destroy(id)`,
//! and command batches (`apply_batch`, `apply_batch_sync`) with one result
//! per command. The commands themselves are in [`commands`].

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use shared_types::{Command as Wire, CommandStatus};
use sim_client::{BatchError, BatchResponse, CommandError};

use crate::client::Client;
use crate::errors::{message, raise, request};
use crate::gil::detached;

use commands::{actor_id, describe, spawn_command, Command};

mod commands;
mod control_commands;
mod light_commands;

/// How one command of `apply_batch_sync` ended.
#[pyclass(module = "simbus", name = "CommandResult", frozen, get_all)]
#[derive(Debug, Clone)]
pub(crate) struct BatchResult {
    /// `"ok"`, `"unknown_actor"`, `"invalid_argument"`, `"not_a_vehicle"`,
    /// `"unknown_command"` or `"static_actor"`.
    status: &'static str,
    /// Whether the command was executed.
    ok: bool,
    /// The actor it concerned (the new id for a spawn; 0 when a spawn failed).
    actor_id: u64,
    /// What went wrong, in words naming the actor (`None` when ok).
    error: Option<String>,
    /// The first frame that shows the batch's effects.
    frame: u64,
}

#[pymethods]
impl BatchResult {
    fn __repr__(&self) -> String {
        let error = self
            .error
            .as_ref()
            .map_or("None".to_owned(), |e| format!("'{e}'"));
        format!(
            "CommandResult(status='{}', actor_id={}, error={error}, frame={})",
            self.status, self.actor_id, self.frame
        )
    }
}

fn status_name(status: CommandStatus) -> &'static str {
    match status {
        CommandStatus::Ok => "ok",
        CommandStatus::UnknownActor => "unknown_actor",
        CommandStatus::InvalidArgument => "invalid_argument",
        CommandStatus::NotAVehicle => "not_a_vehicle",
        CommandStatus::UnknownCommand => "unknown_command",
        CommandStatus::StaticActor => "static_actor",
        CommandStatus::SpawnCollision => "spawn_collision",
        CommandStatus::NotAWalker => "not_a_walker",
        CommandStatus::NotATrafficLight => "not_a_traffic_light",
    }
}

/// One result per command of `response`, in order.
fn results(response: &BatchResponse) -> Vec<BatchResult> {
    response
        .results
        .iter()
        .map(|r| {
            let status = CommandStatus::from_u32(r.status).unwrap_or(CommandStatus::UnknownCommand);
            let ok = status == CommandStatus::Ok;
            BatchResult {
                status: status_name(status),
                ok,
                actor_id: r.actor,
                error: (!ok).then(|| match status {
                    CommandStatus::SpawnCollision => {
                        format!("{status}: actor {} is there", r.actor)
                    }
                    status => format!("actor {}: {status}", r.actor),
                }),
                frame: response.frame,
            }
        })
        .collect()
}

/// The commands of a Python iterable, each a `simbus.Command`.
fn wire_commands(commands: &Bound<'_, PyAny>) -> PyResult<Vec<Wire>> {
    let mut wire = Vec::new();
    for (i, item) in commands.try_iter()?.enumerate() {
        let item = item?;
        let command = item.cast::<Command>().map_err(|_| {
            PyTypeError::new_err(format!(
                "commands[{i}] must be a simbus command (simbus.SpawnActor, simbus.SetTargetVelocity, ...), got {}",
                item.get_type().name().map_or_else(|_| "?".to_owned(), |n| n.to_string())
            ))
        })?;
        wire.push(command.get().wire);
    }
    Ok(wire)
}

/// A batch error as its exception.
fn batch_error(error: BatchError) -> PyErr {
    match error {
        BatchError::Request(e) => request(e),
        BatchError::NotTicker | BatchError::NotStepped(_) => {
            raise("NotTickerError", message(&error))
        }
        BatchError::Replaying => raise("CommandError", message(&error)),
    }
}

/// A single command's error as its exception.
fn command_error(error: CommandError) -> PyErr {
    match error {
        CommandError::Batch(e) => batch_error(e),
        CommandError::Refused { .. } | CommandError::SpawnCollision { .. } => {
            raise("CommandError", message(&error))
        }
    }
}

#[pymethods]
impl Client {
    /// Spawns an actor and returns its id (it shows in the next frame).
    /// `kind` is `"box"`, `"sphere"`, `"capsule"`, `"vehicle"` or
    /// `"walker"`; the other arguments are `simbus.SpawnActor`'s. A refused spawn (a size or
    /// position out of range, or a body already there) raises
    /// `simbus.CommandError`.
    #[pyo3(signature = (kind, *, at = None, rotation = None, half_extents = None, radius = None, half_height = None))]
    #[allow(clippy::too_many_arguments)]
    fn spawn(
        &self,
        py: Python<'_>,
        kind: &str,
        at: Option<&Bound<'_, PyAny>>,
        rotation: Option<&Bound<'_, PyAny>>,
        half_extents: Option<&Bound<'_, PyAny>>,
        radius: Option<f64>,
        half_height: Option<f64>,
    ) -> PyResult<u64> {
        let wire = spawn_command(kind, at, rotation, half_extents, radius, half_height)?;
        detached(py, &self.inner, |c| c.spawn_actor(wire)).map_err(|e| match e {
            CommandError::Refused { status, .. } => raise(
                "CommandError",
                format!("spawning {} was refused: {status}", describe(&wire)),
            ),
            CommandError::SpawnCollision { occupant } => raise(
                "CommandError",
                format!(
                    "spawning {} was refused: {}: actor {occupant} is there",
                    describe(&wire),
                    CommandStatus::SpawnCollision
                ),
            ),
            e => command_error(e),
        })
    }

    /// Removes actor `actor_id`; an unknown one raises `simbus.CommandError`
    /// naming it.
    fn destroy(&self, py: Python<'_>, actor_id: &Bound<'_, PyAny>) -> PyResult<()> {
        let id = self::actor_id(actor_id)?;
        detached(py, &self.inner, |c| c.destroy(id)).map_err(command_error)
    }

    /// Sends `commands` (an iterable of `simbus.Command`s) to be applied, in
    /// order, at the next frame boundary, and returns without waiting
    /// (CARLA's `apply_batch`): a command that fails does so silently.
    fn apply_batch(&self, py: Python<'_>, commands: &Bound<'_, PyAny>) -> PyResult<()> {
        let wire = wire_commands(commands)?;
        detached(py, &self.inner, |c| c.apply_batch(&wire)).map_err(request)
    }

    /// Applies `commands` (an iterable of `simbus.Command`s) at the next
    /// frame boundary, in order, and returns one `simbus.CommandResult` per
    /// command (a failed one changes nothing and says why). With `tick`,
    /// one frame is then stepped: only the ticker's process may ask
    /// (`simbus.NotTickerError` otherwise, nothing applied).
    #[pyo3(signature = (commands, tick = false))]
    fn apply_batch_sync(
        &self,
        py: Python<'_>,
        commands: &Bound<'_, PyAny>,
        tick: bool,
    ) -> PyResult<Vec<BatchResult>> {
        let wire = wire_commands(commands)?;
        let response =
            detached(py, &self.inner, |c| c.apply_batch_sync(&wire, tick)).map_err(batch_error)?;
        Ok(results(&response))
    }
}

/// Adds this module's classes to the extension module.
/// Adds this module's classes to the extension module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    commands::register(m)?;
    control_commands::register(m)?;
    light_commands::register(m)?;
    m.add_class::<BatchResult>()?;
    Ok(())
}
