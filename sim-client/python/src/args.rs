//! Arguments from Python, checked into the Rust client's values: a bad
//! one raises `ValueError` naming the argument, before anything is sent.

use std::time::Duration;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use shared_types::WaitMode;

/// A number of seconds from Python: finite and not negative.
pub(crate) fn seconds(name: &str, value: f64) -> PyResult<Duration> {
    Duration::try_from_secs_f64(value).map_err(|_| {
        PyValueError::new_err(format!(
            "{name} must be a finite number of seconds >= 0, got {value}"
        ))
    })
}

/// A wait mode from its name: `"hybrid"`, `"block"` or `"spin"`.
pub(crate) fn wait_mode(text: &str) -> PyResult<WaitMode> {
    text.parse().map_err(|_| {
        PyValueError::new_err(format!(
            "wait_mode must be 'hybrid', 'block' or 'spin', got {text:?}"
        ))
    })
}
