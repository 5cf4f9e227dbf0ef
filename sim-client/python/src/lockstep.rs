//! Lockstep participants: `with client.participant(name) as p: p.done(frame)`.

use pyo3::prelude::*;

/// Adds this module's classes and functions to the extension module.
pub(crate) fn register(_m: &Bound<'_, PyModule>) -> PyResult<()> {
    Ok(())
}
