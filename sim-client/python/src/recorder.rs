//! The recorder and the replayer, and `simbus.recording.info(path)` without a server.

use pyo3::prelude::*;

/// Adds this module's classes and functions to the extension module.
pub(crate) fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
