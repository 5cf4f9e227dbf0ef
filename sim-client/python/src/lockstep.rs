//! Lockstep participants: `with client.participant(name) as p: p.done(frame)`.

use pyo3::exceptions::PyTypeError;
use pyo3::prelude::*;
use pyo3::types::PyInt;

use crate::client::Client;
use crate::errors::{raise, request};
use crate::gil::detached;

/// A lockstep participant (CARLA's Traffic Manager, kept in step by the
/// bus): in synchronous mode the server steps past frame N only once the
/// ticker ticked **and** every participant called `done` for frame N.
/// Send the frame's commands before `done`, so they land in the next step.
/// A participant that keeps a tick waiting past the server's
/// `--lockstep-timeout` is dropped: its next `done` or `check` raises
/// `simbus.Error`. Leaving the `with` block (or `leave()`) leaves.
/// Bound to the thread that joined.
#[pyclass(module = "simbus", unsendable)]
#[derive(Debug)]
pub(crate) struct Participant {
    /// The membership; `None` once left.
    inner: Option<sim_client::Participant>,
    name: String,
    world: String,
    /// The episode `done(frame)` reports for: the one at the join, then
    /// the last one a frame or `episode=` named.
    episode: u64,
}

impl Participant {
    fn joined(&self) -> PyResult<&sim_client::Participant> {
        self.inner.as_ref().ok_or_else(|| {
            raise(
                "Error",
                format!(
                    "lockstep participant {:?} left the lockstep of world '{}'; join again with client.participant()",
                    self.name, self.world
                ),
            )
        })
    }
}

/// `frame` as (episode, frame): an int (with the given or known episode)
/// or a `simbus.Frame` (its own episode).
fn frame_of(frame: &Bound<'_, PyAny>, episode: Option<u64>, known: u64) -> PyResult<(u64, u64)> {
    if frame.is_instance_of::<PyInt>() {
        let id = frame.extract::<u64>()?;
        return Ok((episode.unwrap_or(known), id));
    }
    let (Ok(id), Ok(own)) = (frame.getattr("frame"), frame.getattr("episode")) else {
        return Err(PyTypeError::new_err(
            "frame must be a frame id (int) or a simbus.Frame",
        ));
    };
    Ok((episode.unwrap_or(own.extract()?), id.extract()?))
}

#[pymethods]
impl Participant {
    /// Done with `frame` (a frame id, or a `simbus.Frame`, which also
    /// says its episode): the server may step past it once the tick is
    /// there and every other participant is done. `episode` defaults to
    /// the frame's, else the last one known (the join's); name it after a
    /// reload when passing an int. Does not wait. Raises `simbus.Error`
    /// when the server answered an earlier `done` saying it dropped this
    /// participant.
    #[pyo3(signature = (frame, *, episode = None))]
    fn done(&mut self, frame: &Bound<'_, PyAny>, episode: Option<u64>) -> PyResult<()> {
        let (episode, frame) = frame_of(frame, episode, self.episode)?;
        self.joined()?.done(episode, frame).map_err(request)?;
        self.episode = episode;
        Ok(())
    }

    /// Raises `simbus.Error` if the server said (answering the last
    /// `done`) that it no longer waits for this participant; does not wait.
    fn check(&self) -> PyResult<()> {
        self.joined()?.check().map_err(request)
    }

    /// Leaves the lockstep: the server stops waiting for this participant.
    /// Harmless twice.
    fn leave(&mut self) {
        self.inner.take();
    }

    /// The participant's name.
    #[getter]
    fn name(&self) -> &str {
        &self.name
    }

    /// (episode, frame) current at the join: the first frame the server
    /// waits for this participant's `done`.
    #[getter]
    fn joined_at(&self) -> PyResult<(u64, u64)> {
        Ok(self.joined()?.joined_at())
    }

    /// Whether this handle still takes part (it has not left; the server
    /// may have dropped it: see `check`).
    #[getter]
    fn active(&self) -> bool {
        self.inner.is_some()
    }

    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __exit__(
        &mut self,
        _kind: Option<Bound<'_, PyAny>>,
        _value: Option<Bound<'_, PyAny>>,
        _traceback: Option<Bound<'_, PyAny>>,
    ) {
        self.leave();
    }

    fn __repr__(&self) -> String {
        let state = if self.inner.is_some() { "" } else { " left" };
        format!(
            "<simbus.Participant {:?} world={:?}{state}>",
            self.name, self.world
        )
    }
}

#[pymethods]
impl Client {
    /// Joins the world's lockstep as `name`: in synchronous mode the server
    /// then waits for this participant's `done(frame)` every frame — with
    /// `window=W`, for its `done` of the frame W before (CARLA's
    /// per-participant windows: it may fall W frames behind without
    /// holding the ticker). Use it as a context manager (leaving the block
    /// leaves the lockstep).
    #[pyo3(signature = (name, *, window = 0))]
    fn participant(&self, py: Python<'_>, name: &str, window: u32) -> PyResult<Participant> {
        let inner = detached(py, &self.inner, |c| {
            c.join_lockstep_with_window(name, window)
        })
        .map_err(request)?;
        Ok(Participant {
            episode: inner.joined_at().0,
            inner: Some(inner),
            name: name.to_owned(),
            world: self.inner.world().to_string(),
        })
    }
}

/// Adds this module's classes to the extension module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Participant>()
}
