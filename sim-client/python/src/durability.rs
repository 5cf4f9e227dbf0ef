//! Riding through a server restart (`client.next_event()`,
//! `client.reconnect()`, `ticker.follow_restarts()`) and snapshots
//! (`client.save_snapshot()`, `client.restore_snapshot(id)`).

use std::time::{Duration, Instant};

use pyo3::prelude::*;
use sim_client::{SnapshotError, SnapshotId, WaitError};

use crate::args::seconds;
use crate::client::Client;
use crate::errors::{self, message, raise};
use crate::frame::Frame;
use crate::gil::detached;

/// The server exited and another came back on the world
/// (`sim-server --resume`); the client now reads its frames.
#[pyclass(module = "simbus", frozen, get_all)]
#[derive(Debug, Clone)]
pub(crate) struct Reconnected {
    /// The frame the world resumed at (the next tick computes the one after).
    resumed_at: u64,
    /// Its episode.
    episode: u64,
    /// The new server's process id.
    server_pid: u32,
    /// The process id of the server that exited.
    previous_pid: u32,
}

#[pymethods]
impl Reconnected {
    fn __repr__(&self) -> String {
        format!(
            "<simbus.Reconnected resumed_at={} episode={} server_pid={} previous_pid={}>",
            self.resumed_at, self.episode, self.server_pid, self.previous_pid
        )
    }
}

impl From<sim_client::Reconnected> for Reconnected {
    fn from(r: sim_client::Reconnected) -> Self {
        Self {
            resumed_at: r.resumed_at,
            episode: r.episode,
            server_pid: r.server_pid,
            previous_pid: r.previous_pid,
        }
    }
}

/// A snapshot the server holds.
#[pyclass(module = "simbus", frozen, get_all)]
#[derive(Debug, Clone)]
pub(crate) struct SnapshotInfo {
    /// Its id.
    id: u64,
    /// The frame it was saved at.
    frame: u64,
    /// That frame's id in its own line of frames.
    source_frame: u64,
    /// The episode it was saved in.
    episode: u64,
    /// The simulation time it was saved at, in seconds.
    elapsed_seconds: f64,
    /// Its actors.
    actors: u32,
    /// Its sensors.
    sensors: u32,
}

#[pymethods]
impl SnapshotInfo {
    fn __repr__(&self) -> String {
        format!(
            "<simbus.SnapshotInfo id={} frame={} actors={} sensors={}>",
            self.id, self.frame, self.actors, self.sensors
        )
    }
}

/// A snapshot error as its exception.
pub(crate) fn snapshot_error(error: SnapshotError) -> PyErr {
    match error {
        SnapshotError::Request(e) => errors::request(e),
        SnapshotError::NotTicker { .. } => raise("NotTickerError", message(&error)),
        SnapshotError::Full { .. } => raise("Full", message(&error)),
        SnapshotError::Unknown { .. } => pyo3::exceptions::PyKeyError::new_err(message(&error)),
        _ => raise("Error", message(&error)),
    }
}

#[pymethods]
impl Client {
    /// Waits up to `timeout` seconds for a server to come back on this
    /// world after the one this client knew exited, and talks to it from
    /// now on. Raises `simbus.ServerGone` when none came back in time.
    #[pyo3(signature = (timeout = 30.0))]
    fn reconnect(&mut self, py: Python<'_>, timeout: f64) -> PyResult<Reconnected> {
        let timeout = seconds("timeout", timeout)?;
        let inner = &mut self.inner;
        let r = detached(py, inner, |c| c.reconnect(timeout)).map_err(errors::connect)?;
        Ok(r.into())
    }

    /// `wait_for_frame` that rides through a server restart: the next
    /// frame, or a `simbus.Reconnected` when the server exited and another
    /// came back within `timeout` seconds (its frames follow).
    #[pyo3(signature = (timeout = 5.0))]
    fn next_event(&mut self, py: Python<'_>, timeout: f64) -> PyResult<Py<PyAny>> {
        let timeout = seconds("timeout", timeout)?;
        let deadline = Instant::now() + timeout;
        let inner = &mut self.inner;
        match detached(py, &mut *inner, |c| c.wait_for_frame(timeout)) {
            Ok(view) => Ok(Py::new(py, Frame::lent(py, view)?)?.into_any()),
            Err(WaitError::ServerGone { .. }) => {
                let remaining = deadline.saturating_duration_since(Instant::now());
                let r = detached(py, inner, |c| c.reconnect(remaining.max(Duration::ZERO)))
                    .map_err(errors::connect)?;
                Ok(Py::new(py, Reconnected::from(r))?.into_any())
            }
            Err(e) => Err(errors::wait(e)),
        }
    }

    /// Saves the whole world (actors, ids, physics, time, settings,
    /// sensors) in the server's memory after the current frame; returns
    /// its id. While a ticker holds the world only its process may.
    fn save_snapshot(&self, py: Python<'_>) -> PyResult<u64> {
        detached(py, &self.inner, |c| c.save_snapshot())
            .map(|id| id.0)
            .map_err(snapshot_error)
    }

    /// Restores snapshot `id` as a new episode, published at once as the
    /// next frame (whose id it returns): the same commands then give the
    /// digests they gave after the save.
    fn restore_snapshot(&self, py: Python<'_>, id: u64) -> PyResult<u64> {
        detached(py, &self.inner, |c| c.restore_snapshot(SnapshotId(id))).map_err(snapshot_error)
    }

    /// Forgets snapshot `id`.
    fn drop_snapshot(&self, py: Python<'_>, id: u64) -> PyResult<()> {
        detached(py, &self.inner, |c| c.drop_snapshot(SnapshotId(id))).map_err(snapshot_error)
    }

    /// The snapshots the server holds, oldest first.
    fn snapshots(&self, py: Python<'_>) -> PyResult<Vec<SnapshotInfo>> {
        let list = detached(py, &self.inner, |c| c.snapshots()).map_err(errors::request)?;
        Ok(list
            .into_iter()
            .map(|s| SnapshotInfo {
                id: s.id,
                frame: s.frame,
                source_frame: s.source_frame,
                episode: s.episode,
                elapsed_seconds: shared_types::nanos_to_seconds(s.elapsed_ns),
                actors: s.actors,
                sensors: s.sensors,
            })
            .collect())
    }
}

/// The classes of this module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Reconnected>()?;
    m.add_class::<SnapshotInfo>()?;
    Ok(())
}
