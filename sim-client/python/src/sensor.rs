//! Sensors: spawning them, reading captures as numpy arrays over shared memory, listening on a thread.

use pyo3::prelude::*;

/// Adds this module's classes and functions to the extension module.
pub(crate) fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
