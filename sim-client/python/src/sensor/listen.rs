//! [`Listening`]: `sensor.listen(callback)`, captures handed to a Python
//! callback on a thread of its own, with a client and a subscription of
//! that thread (iceoryx2's ports belong to the thread that opens them).

use std::sync::atomic::{AtomicBool, AtomicU64, Ordering};
use std::sync::{mpsc, Arc, Condvar, Mutex};
use std::thread::{JoinHandle, ThreadId};
use std::time::Duration;

use pyo3::prelude::*;
use sim_client::WaitError;

use super::capture::Capture;
use super::{sensor_error, wait_error};
use crate::args::seconds;
use crate::errors::{self, raise};
use crate::loan::give_back;

/// A running `sensor.listen(callback)`: `stop()` (or the end of a `with`
/// block) ends it; the sensor's end stops it too (`ended` says why).
#[pyclass(module = "simbus")]
#[derive(Debug)]
pub(crate) struct Listening {
    shared: Arc<Shared>,
    thread: Mutex<Option<JoinHandle<()>>>,
    thread_id: ThreadId,
}

/// What the listening thread and its handle share.
#[derive(Debug, Default)]
struct Shared {
    stop: AtomicBool,
    delivered: AtomicU64,
    failed: AtomicU64,
    /// The exception that ended the listening by itself.
    ended: Mutex<Option<PyErr>>,
    /// Set when the thread's loop is over (stopped, or the stream ended).
    finished: Mutex<bool>,
    finishing: Condvar,
}

/// Marks the listening finished when the thread's work ends, however it ends.
struct Finished(Arc<Shared>);

impl Drop for Finished {
    fn drop(&mut self) {
        if let Ok(mut finished) = self.0.finished.lock() {
            *finished = true;
        }
        self.0.finishing.notify_all();
    }
}

/// How long a wait sleeps between two looks at Python's signals.
const SIGNAL_SLICE: Duration = Duration::from_millis(100);

impl Listening {
    /// Starts listening to sensor `id` of `world`, once its subscription is
    /// open, waiting as `mode` says.
    pub(super) fn start(
        py: Python<'_>,
        world: String,
        timeout: Duration,
        id: u64,
        mode: shared_types::WaitMode,
        callback: Py<PyAny>,
    ) -> PyResult<Self> {
        let shared = Arc::new(Shared::default());
        let (ready_tx, ready_rx) = mpsc::channel();
        let state = shared.clone();
        let thread = std::thread::Builder::new()
            .name(format!("simbus-sensor-{id}"))
            .spawn(move || {
                let _finished = Finished(state.clone());
                // A client and a subscription of this thread's own: the
                // ports belong to the thread that opens them.
                let opened = sim_client::Client::builder(world)
                    .timeout(timeout)
                    .request_timeout(timeout)
                    .wait_mode(mode)
                    .connect()
                    .map_err(errors::connect)
                    .and_then(|client| client.sensor(id).map_err(sensor_error))
                    .map(|mut sensor| {
                        sensor.set_wait_mode(mode);
                        sensor
                    });
                match opened {
                    Ok(sensor) => {
                        let _ = ready_tx.send(Ok(()));
                        listen_loop(sensor, &callback, &state);
                    }
                    Err(e) => {
                        let _ = ready_tx.send(Err(e));
                    }
                }
                Python::attach(|_| drop(callback));
            })
            .map_err(|e| {
                raise(
                    "Error",
                    format!("could not start the listening thread: {e}"),
                )
            })?;
        let thread_id = thread.thread().id();
        let started = py.detach(move || ready_rx.recv());
        match started {
            Ok(Ok(())) => Ok(Self {
                shared,
                thread: Mutex::new(Some(thread)),
                thread_id,
            }),
            Ok(Err(e)) => Err(e),
            Err(_) => Err(raise(
                "Error",
                "the listening thread ended before it subscribed",
            )),
        }
    }
}

/// Hands every capture to `callback` until stopped or the stream ends.
fn listen_loop(mut sensor: sim_client::Sensor, callback: &Py<PyAny>, shared: &Shared) {
    while !shared.stop.load(Ordering::Relaxed) {
        match sensor.recv(Duration::from_millis(100)) {
            Ok(capture) => Python::attach(|py| deliver(py, callback, capture, shared)),
            Err(WaitError::NoCapture { .. }) => {}
            Err(e) => {
                let error = wait_error(sensor.id(), e);
                if let Ok(mut ended) = shared.ended.lock() {
                    *ended = Some(error);
                }
                return;
            }
        }
    }
}

/// Calls `callback` with `capture`, printing what it raises; the capture's
/// shared memory goes back once the callback returns (unless arrays of it
/// live on).
fn deliver(py: Python<'_>, callback: &Py<PyAny>, capture: sim_client::Capture, shared: &Shared) {
    let capture = match Capture::lent(py, capture).and_then(|c| Py::new(py, c)) {
        Ok(capture) => capture,
        Err(e) => return e.display(py),
    };
    shared.delivered.fetch_add(1, Ordering::Relaxed);
    if let Err(e) = callback.call1(py, (capture.clone_ref(py),)) {
        shared.failed.fetch_add(1, Ordering::Relaxed);
        e.display(py);
    }
    // Released unless the callback kept arrays over it (those keep the
    // sample; it goes back when they do).
    if let Ok(mut held) = capture.try_borrow_mut(py) {
        let _ = give_back(&mut held.loan, String::new);
    };
}

#[pymethods]
impl Listening {
    /// Stops the callbacks (after the running one returns) and waits for
    /// the thread; the sensor stays in the world. Harmless twice.
    fn stop(&self, py: Python<'_>) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if std::thread::current().id() == self.thread_id {
            return; // from the callback itself: the loop ends after it
        }
        let thread = self.thread.lock().ok().and_then(|mut t| t.take());
        if let Some(thread) = thread {
            let _ = py.detach(|| thread.join());
        }
    }

    /// Waits up to `timeout` seconds (forever with `None`) for the
    /// listening to end by itself (the sensor's end: see `ended`) or by
    /// `stop()`; returns whether it has ended.
    #[pyo3(signature = (timeout = None))]
    fn wait(&self, py: Python<'_>, timeout: Option<f64>) -> PyResult<bool> {
        let timeout = timeout.map(|t| seconds("timeout", t)).transpose()?;
        let deadline = timeout.map(|t| std::time::Instant::now() + t);
        let shared = &self.shared;
        // In slices of 100 ms, Python's signal handlers run between them:
        // Ctrl-C ends the wait.
        loop {
            let slice = deadline.map_or(SIGNAL_SLICE, |d| {
                d.saturating_duration_since(std::time::Instant::now())
                    .min(SIGNAL_SLICE)
            });
            let finished = py
                .detach(|| {
                    let finished = shared.finished.lock().map_err(|_| ())?;
                    let (finished, _) = shared
                        .finishing
                        .wait_timeout_while(finished, slice, |done| !*done)
                        .map_err(|_| ())?;
                    Ok(*finished)
                })
                .map_err(|()| raise("Error", "the listening thread panicked"))?;
            if finished || deadline.is_some_and(|d| std::time::Instant::now() >= d) {
                return Ok(finished);
            }
            py.check_signals()?;
        }
    }

    /// Whether callbacks still come.
    #[getter]
    fn running(&self) -> bool {
        let alive = self
            .thread
            .lock()
            .is_ok_and(|t| t.as_ref().is_some_and(|t| !t.is_finished()));
        alive && !self.shared.stop.load(Ordering::Relaxed)
    }

    /// Captures handed to the callback so far.
    #[getter]
    fn captures(&self) -> u64 {
        self.shared.delivered.load(Ordering::Relaxed)
    }

    /// Exceptions the callback raised (each was printed).
    #[getter]
    fn errors(&self) -> u64 {
        self.shared.failed.load(Ordering::Relaxed)
    }

    /// The exception that ended the listening by itself
    /// (`simbus.SensorEnded`, `simbus.ServerGone`), or `None`.
    #[getter]
    fn ended(&self, py: Python<'_>) -> Option<Py<PyAny>> {
        let ended = self.shared.ended.lock().ok()?;
        ended
            .as_ref()
            .map(|e| e.value(py).clone().into_any().unbind())
    }

    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __exit__(
        &self,
        py: Python<'_>,
        _kind: Option<Bound<'_, PyAny>>,
        _value: Option<Bound<'_, PyAny>>,
        _traceback: Option<Bound<'_, PyAny>>,
    ) {
        self.stop(py);
    }

    fn __repr__(&self) -> String {
        format!(
            "<simbus.Listening {} captures, {}>",
            self.captures(),
            if self.running() { "running" } else { "stopped" }
        )
    }
}

impl Drop for Listening {
    fn drop(&mut self) {
        self.shared.stop.store(true, Ordering::Relaxed);
        if std::thread::current().id() == self.thread_id {
            return;
        }
        let thread = self.thread.get_mut().ok().and_then(Option::take);
        if let Some(thread) = thread {
            // The thread may wait for the GIL to finish a callback.
            Python::attach(|py| py.detach(|| thread.join())).ok();
        }
    }
}
