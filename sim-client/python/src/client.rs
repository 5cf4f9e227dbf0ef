//! [`Client`]: a connection to one world, `simbus.connect(...)`.

use pyo3::prelude::*;
use shared_types::WaitMode;

use crate::args::seconds;
use crate::frame::Frame;
use crate::gil::detached;
use crate::settings::{Changes, Settings, Status};
use crate::{args, errors};

/// Connects to the server of `world`, waiting up to `timeout` seconds for
/// it. `wait_mode` says how this client waits for frames and answers:
/// `"hybrid"` (poll 100 µs, then sleep: the default), `"block"` (sleep at
/// once) or `"spin"` (poll: lowest latency, a core busy).
#[pyfunction]
#[pyo3(signature = (world = "default", timeout = 5.0, wait_mode = "hybrid"))]
pub(crate) fn connect(
    py: Python<'_>,
    world: &str,
    timeout: f64,
    wait_mode: &str,
) -> PyResult<Client> {
    let mode = args::wait_mode(wait_mode)?;
    let builder = sim_client::Client::builder(world)
        .timeout(seconds("timeout", timeout)?)
        .wait_mode(mode);
    let client = detached(py, (), |()| builder.connect()).map_err(errors::connect)?;
    Ok(Client {
        inner: client,
        wait_mode: mode,
    })
}

/// A connection to one world: settings, frames, the ticker, actors,
/// sensors, lockstep and the recorder. Bound to the thread that connected
/// (its shared-memory ports are); use one client per thread.
#[pyclass(module = "simbus", unsendable)]
#[derive(Debug)]
pub(crate) struct Client {
    pub(crate) inner: sim_client::Client,
    /// How every wait of this client, its ticker's and its sensors' waits.
    pub(crate) wait_mode: WaitMode,
}

#[pymethods]
impl Client {
    /// The world's name.
    #[getter]
    fn world(&self) -> String {
        self.inner.world().to_string()
    }

    /// How this client's waits wait: `"hybrid"`, `"block"` or `"spin"`
    /// (its ticker's and sensors' too).
    #[getter]
    fn wait_mode(&self) -> &'static str {
        self.wait_mode.name()
    }

    /// The server's process id.
    #[getter]
    fn server_pid(&self) -> u32 {
        self.inner.server_pid()
    }

    /// The world's state now.
    fn status(&self, py: Python<'_>) -> PyResult<Status> {
        let status = detached(py, &self.inner, |c| c.status()).map_err(errors::request)?;
        Ok(status.into())
    }

    /// The settings in force for the next frame.
    fn settings(&self, py: Python<'_>) -> PyResult<Settings> {
        let settings = detached(py, &self.inner, |c| c.get_settings()).map_err(errors::request)?;
        Ok(settings.into())
    }

    /// Changes the given settings (the others are kept) and returns the
    /// first frame computed with them. Synchronous mode is entered by a
    /// ticker (`client.ticker(...)`), not here; invalid settings raise
    /// `simbus.SettingsError` and change nothing.
    #[pyo3(signature = (*, synchronous_mode = None, fixed_delta_seconds = None, substepping = None, max_substep_delta_time = None, max_substeps = None, substep_rule = None))]
    #[allow(clippy::too_many_arguments)]
    fn apply_settings(
        &self,
        py: Python<'_>,
        synchronous_mode: Option<bool>,
        fixed_delta_seconds: Option<f64>,
        substepping: Option<bool>,
        max_substep_delta_time: Option<f64>,
        max_substeps: Option<u32>,
        substep_rule: Option<&str>,
    ) -> PyResult<u64> {
        let changes = Changes {
            synchronous_mode,
            fixed_delta_seconds,
            substepping,
            max_substep_delta_time,
            max_substeps,
            substep_rule: crate::settings::substep_rule(substep_rule)?,
        };
        detached(py, &self.inner, |c| {
            let current = c.get_settings()?;
            c.apply_settings(changes.applied_to(current))
        })
        .map_err(errors::settings)
    }

    /// Restores the scene's initial state as a new episode (the settings
    /// too when `reset_settings`).
    #[pyo3(signature = (*, reset_settings = false))]
    fn reload_world(&self, py: Python<'_>, reset_settings: bool) -> PyResult<Status> {
        let status =
            detached(py, &self.inner, |c| c.reload_world(reset_settings)).map_err(errors::load)?;
        Ok(status.into())
    }

    /// Loads `scene` (`"default"`, `"empty"`, `"boxes:10"`, ...) as a new
    /// episode.
    #[pyo3(signature = (scene, *, reset_settings = false))]
    fn load_world(&self, py: Python<'_>, scene: &str, reset_settings: bool) -> PyResult<Status> {
        let status = detached(py, &self.inner, |c| c.load_world(scene, reset_settings))
            .map_err(errors::load)?;
        Ok(status.into())
    }

    /// The next frame (a newer one than the last this client took),
    /// waiting up to `timeout` seconds. Its actors view shared memory
    /// until the frame is released.
    #[pyo3(signature = (timeout = 5.0))]
    fn wait_for_frame(&mut self, py: Python<'_>, timeout: f64) -> PyResult<Frame> {
        let timeout = seconds("timeout", timeout)?;
        let inner = &mut self.inner;
        let view = detached(py, inner, |c| c.wait_for_frame(timeout)).map_err(errors::wait)?;
        Frame::lent(py, view)
    }

    /// The frames as they come: an iterator of `wait_for_frame(timeout)`.
    #[pyo3(signature = (timeout = 5.0))]
    fn frames(slf: Py<Self>, timeout: f64) -> PyResult<Frames> {
        seconds("timeout", timeout)?;
        Ok(Frames {
            client: slf,
            timeout,
        })
    }

    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __exit__(
        &self,
        _kind: Option<Bound<'_, PyAny>>,
        _value: Option<Bound<'_, PyAny>>,
        _traceback: Option<Bound<'_, PyAny>>,
    ) {
    }

    fn __repr__(&self) -> String {
        format!(
            "<simbus.Client world={:?} server_pid={}>",
            self.inner.world().as_str(),
            self.inner.server_pid()
        )
    }
}

/// The frames of a client as they come (`client.frames()`).
#[pyclass(module = "simbus", unsendable)]
#[derive(Debug)]
pub(crate) struct Frames {
    client: Py<Client>,
    timeout: f64,
}

#[pymethods]
impl Frames {
    fn __iter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __next__(&self, py: Python<'_>) -> PyResult<Frame> {
        self.client.borrow_mut(py).wait_for_frame(py, self.timeout)
    }
}
