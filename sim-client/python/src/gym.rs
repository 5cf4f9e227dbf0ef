//! The hot path of `simbus.gym` (the Python package's Gymnasium and
//! PettingZoo environments): one world of the driving task stepped from
//! Rust, its observations written into the caller's batch arrays.

use pyo3::prelude::*;

mod task;
mod world;

/// Adds the module's classes.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<world::DrivingWorld>()?;
    m.add(
        "DRIVING_REWARD_TERMS",
        ["progress", "collision", "lane", "off_road", "red_light"],
    )?;
    m.add("DRIVING_EGO_VALUES", task::EGO_VALUES)?;
    m.add("DRIVING_ACTOR_VALUES", task::ACTOR_VALUES)?;
    Ok(())
}
