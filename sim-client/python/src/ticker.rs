//! [`Ticker`]: tick ownership of a world, `with client.ticker(...)`.

use pyo3::prelude::*;
use shared_types::WorldSettings;

use crate::args::seconds;
use crate::client::Client;
use crate::errors;
use crate::frame::Frame;
use crate::gil::detached;
use crate::settings::{Changes, Settings};

/// The world's single ticker: `tick()` computes the next frame. Leaving
/// the `with` block (or `release()`) puts the settings back as they were
/// before the claim (a world that was synchronous stays synchronous and
/// waits for the next ticker) and gives the world back.
#[pyclass(module = "simbus", unsendable)]
#[derive(Debug)]
pub(crate) struct Ticker {
    inner: Option<sim_client::Ticker>,
    /// The settings to put back on release: the world's before the claim
    /// (put back when they differ from [`Ticker::settings`]).
    restore: WorldSettings,
    /// The settings in force: the world's at the claim, then what this
    /// ticker applied (while it ticks, only it changes them).
    settings: WorldSettings,
    timeout: std::time::Duration,
}

impl Ticker {
    /// Claims `client`'s world (its ticks waiting as `mode` says) and, with
    /// `delta_seconds`, applies a fixed step (and synchronous mode unless
    /// asked otherwise).
    pub(crate) fn claim(
        py: Python<'_>,
        (client, mode): (&sim_client::Client, shared_types::WaitMode),
        delta_seconds: Option<f64>,
        synchronous_mode: bool,
        timeout: f64,
    ) -> PyResult<Self> {
        let timeout = seconds("timeout", timeout)?;
        let (mut ticker, before) = detached(py, client, |c| {
            let ticker = c.claim_ticker()?;
            // Read once this ticker holds the world: what is put back.
            let before = c.get_settings().map_err(sim_client::TickError::from)?;
            Ok((ticker, before))
        })
        .map_err(errors::tick)?;
        ticker.set_wait_mode(mode);
        let mut held = Ticker {
            inner: Some(ticker),
            restore: before,
            settings: before,
            timeout,
        };
        if let Some(delta) = delta_seconds {
            let wanted = Changes {
                synchronous_mode: Some(synchronous_mode),
                fixed_delta_seconds: Some(delta),
                ..Changes::default()
            }
            .applied_to(before);
            held.apply(py, wanted)?;
        }
        Ok(held)
    }

    fn held(&mut self) -> PyResult<&mut sim_client::Ticker> {
        self.inner.as_mut().ok_or_else(|| {
            errors::raise(
                "NotTickerError",
                "this ticker was released; claim the world again with client.ticker()",
            )
        })
    }

    fn apply(&mut self, py: Python<'_>, settings: WorldSettings) -> PyResult<u64> {
        let ticker = self.held()?;
        let frame =
            detached(py, ticker, |t| t.apply_settings(settings)).map_err(errors::settings)?;
        self.settings = settings;
        Ok(frame)
    }
}

#[pymethods]
impl Ticker {
    /// Computes the next frame and returns its id once its snapshot is
    /// published (a `wait_for_frame` after it sees it). Waits up to
    /// `timeout` seconds (the claim's by default); a tick held up by a
    /// lockstep participant waits for the server to drop it.
    /// When the server exits, wait up to `timeout` seconds for one to
    /// come back on the world (`sim-server --resume`) and claim it again:
    /// the tick that noticed raises `simbus.Restarted` (saying where the
    /// world resumed) and the next tick computes the frame after it.
    /// `None` (the default): a server that exits ends the ticker.
    #[pyo3(signature = (timeout = 30.0))]
    fn follow_restarts(&mut self, timeout: Option<f64>) -> PyResult<()> {
        let timeout = timeout.map(|t| seconds("timeout", t)).transpose()?;
        self.held()?.set_follow_restarts(timeout);
        Ok(())
    }

    #[pyo3(signature = (timeout = None))]
    fn tick(&mut self, py: Python<'_>, timeout: Option<f64>) -> PyResult<u64> {
        let timeout = match timeout {
            Some(t) => seconds("timeout", t)?,
            None => self.timeout,
        };
        let ticker = self.held()?;
        detached(py, ticker, |t| t.tick(timeout)).map_err(errors::tick)
    }

    /// Computes the next frame and returns it, read in place from
    /// `client`'s frames: one wait, on the frame itself (in synchronous
    /// mode the server sends the tick no other answer). Frames `client` had
    /// queued are skipped. Release it (`with`) as any `Frame`.
    #[pyo3(signature = (client, timeout = None))]
    fn tick_and_read(
        &mut self,
        py: Python<'_>,
        client: &Bound<'_, Client>,
        timeout: Option<f64>,
    ) -> PyResult<Frame> {
        let timeout = match timeout {
            Some(t) => seconds("timeout", t)?,
            None => self.timeout,
        };
        let mut client = client.try_borrow_mut()?;
        let ticker = self.held()?;
        let view = detached(py, (ticker, &mut client.inner), |(t, c)| {
            t.tick_and_read(c, timeout)
        })
        .map_err(errors::tick)?;
        Frame::lent(py, view)
    }

    /// The last frame this ticker produced (or saw when claiming).
    #[getter]
    fn last_frame(&self) -> Option<u64> {
        self.inner.as_ref()?.last_frame().map(|(frame, _)| frame)
    }

    /// Changes the given settings as the ticker (which may enter or leave
    /// synchronous mode); returns the first frame computed with them.
    #[pyo3(signature = (*, synchronous_mode = None, fixed_delta_seconds = None, substepping = None, max_substep_delta_time = None, max_substeps = None, substep_rule = None))]
    #[allow(clippy::too_many_arguments)]
    fn apply_settings(
        &mut self,
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
        self.apply(py, changes.applied_to(self.settings))
    }

    /// The settings in force (the ticker's own view: only it changes them).
    #[getter]
    fn settings(&self) -> Settings {
        self.settings.into()
    }

    /// Puts the settings back as they were before the claim (synchronous
    /// mode too: a world started synchronous waits for the next ticker)
    /// and gives the world back. Called by the end of a `with` block;
    /// harmless twice.
    /// If putting the settings back fails (the server is gone, Ctrl-C), it
    /// raises and this ticker still holds the world: `release()` again.
    fn release(&mut self, py: Python<'_>) -> PyResult<()> {
        if self.inner.is_none() {
            return Ok(());
        }
        if self.settings != self.restore {
            self.apply(py, self.restore)?;
        }
        match self.inner.take() {
            Some(ticker) => detached(py, ticker, |t| t.release()).map_err(errors::tick),
            None => Ok(()),
        }
    }

    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __exit__(
        &mut self,
        py: Python<'_>,
        _kind: Option<Bound<'_, PyAny>>,
        _value: Option<Bound<'_, PyAny>>,
        _traceback: Option<Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        self.release(py)
    }

    fn __repr__(&self) -> String {
        match &self.inner {
            Some(t) => format!(
                "<simbus.Ticker world={:?} last_frame={:?}>",
                t.world().as_str(),
                self.last_frame()
            ),
            None => "<simbus.Ticker released>".to_owned(),
        }
    }
}

impl Drop for Ticker {
    fn drop(&mut self) {
        // Dropped without release (garbage collected): the settings still
        // go back; the Rust ticker releases ownership as it drops.
        if let Some(ticker) = self.inner.as_mut() {
            if self.settings != self.restore {
                let _ = ticker.apply_settings(self.restore);
            }
        }
    }
}

#[pymethods]
impl Client {
    /// Claims tick ownership (`simbus.NotTickerError` names the owner when
    /// another client ticks) and, with `delta_seconds`, enters synchronous
    /// mode with that fixed step. Leaving the `with` block (or `release()`)
    /// puts the world's settings back as they were before the claim (a
    /// world that was synchronous stays so, waiting for the next ticker)
    /// and gives the world back.
    #[pyo3(signature = (delta_seconds = None, *, synchronous_mode = true, timeout = 5.0))]
    fn ticker(
        &self,
        py: Python<'_>,
        delta_seconds: Option<f64>,
        synchronous_mode: bool,
        timeout: f64,
    ) -> PyResult<Ticker> {
        let claimed = (&self.inner, self.wait_mode);
        Ticker::claim(py, claimed, delta_seconds, synchronous_mode, timeout)
    }
}
