//! Actors and batches: spawning, destroying, and command batches with one result per command.

use pyo3::prelude::*;

/// Adds this module's classes and functions to the extension module.
pub(crate) fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
