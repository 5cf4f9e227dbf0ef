//! simbus for Python: the Rust client library (`sim_client`) as the
//! extension module `simbus._simbus`, re-exported by the `simbus` package.
//!
//! A thin layer: every call goes to the Rust client (no second
//! implementation of the protocol), the GIL is released around every wait
//! ([`gil::detached`]), Ctrl-C reaches a wait within 100 ms
//! ([`sim_client::set_interrupt_check`]), errors become the exceptions of
//! `simbus/_errors.py` ([`errors`]), and frames and captures are numpy
//! arrays over the shared memory itself whose base object holds the loan
//! ([`loan`]).

use pyo3::prelude::*;

mod args;
mod client;
mod debug;
mod durability;
mod errors;
mod frame;
mod gil;
mod gym;
mod loan;
mod lockstep;
mod recorder;
mod sensor;
mod settings;
mod ticker;
mod world;

/// The extension module: classes and functions the `simbus` package
/// re-exports.
#[pymodule]
fn _simbus(m: &Bound<'_, PyModule>) -> PyResult<()> {
    sim_client::set_interrupt_check(Some(gil::signalled));
    m.add_function(wrap_pyfunction!(client::connect, m)?)?;
    m.add_class::<client::Client>()?;
    m.add_class::<client::Frames>()?;
    m.add_class::<settings::Settings>()?;
    m.add_class::<settings::Status>()?;
    m.add_class::<settings::TickerInfo>()?;
    m.add_class::<settings::ParticipantStatus>()?;
    m.add_class::<settings::JournalStatus>()?;
    m.add_class::<frame::Frame>()?;
    m.add_class::<ticker::Ticker>()?;
    m.add_class::<loan::Loan>()?;
    sensor::register(m)?;
    world::register(m)?;
    durability::register(m)?;
    lockstep::register(m)?;
    recorder::register(m)?;
    gym::register(m)?;
    m.add("PROTOCOL_VERSION", shared_types::PROTOCOL_VERSION)?;
    Ok(())
}
