//! Waiting without the GIL, and Ctrl-C inside a wait.

use std::cell::RefCell;

use pyo3::prelude::*;

thread_local! {
    /// The exception a signal handler raised during this thread's wait
    /// (`KeyboardInterrupt` for Ctrl-C), raised when the wait returns.
    static PENDING: RefCell<Option<PyErr>> = const { RefCell::new(None) };
}

/// The values [`detached`] may hand to its closure: the Rust client's, which
/// are bound to the thread that opened them (iceoryx2's ports are) and hold
/// no Python object. Sealed: nothing else crosses.
pub(crate) trait ThreadBound: sealed::Sealed {}

mod sealed {
    pub(crate) trait Sealed {}
}

/// Marks each type as [`ThreadBound`] (and sealed: nothing else is).
macro_rules! thread_bound {
    ($($t:ty),* $(,)?) => {$(
        impl sealed::Sealed for $t {}
        impl ThreadBound for $t {}
    )*};
}

thread_bound!(
    (),
    &sim_client::Client,
    &mut sim_client::Client,
    &mut sim_client::Ticker,
    (&mut sim_client::Ticker, &mut sim_client::Client),
    (&mut sim_client::Ticker, sim_client::TickInFlight),
    sim_client::Ticker,
    &mut sim_client::Sensor,
);

/// Carries a value into and out of [`Python::detach`], which runs its
/// closure synchronously on the calling thread: the value never leaves
/// this thread. Private to this module, used only by [`detached`].
struct SameThread<T>(T);

// SAFETY: a `SameThread` is made only in `detached`, around a
// `ThreadBound` value (no Python object) going into `Python::detach` and
// the closure's result coming out; `detach` runs the closure on the thread
// that calls it and returns before `detached` does, so neither value is
// ever used by another thread.
unsafe impl<T> Send for SameThread<T> {}

/// Runs `wait(value)` with the GIL released, so other Python threads run
/// while a Rust client call blocks. `value` is the Rust client's thread-bound
/// port (see [`ThreadBound`]); `wait` must be `Send`, which keeps Python
/// objects (and the `Python` token that makes them) out of it, as PyO3's
/// `detach` requires.
pub(crate) fn detached<T: ThreadBound, R>(
    py: Python<'_>,
    value: T,
    wait: impl FnOnce(T) -> R + Send,
) -> R {
    let value = SameThread(value);
    py.detach(move || {
        let value = value;
        SameThread(wait(value.0))
    })
    .0
}

/// The client's interrupt check ([`sim_client::set_interrupt_check`]):
/// runs Python's signal handlers (on the main thread) and says to stop when
/// one raised, keeping its exception for [`take_pending`].
pub(crate) fn signalled() -> bool {
    // Not at all while the interpreter shuts down (a listening thread may
    // still wait then); Python runs signal handlers on its main thread only.
    Python::try_attach(|py| match py.check_signals() {
        Ok(()) => false,
        Err(error) => {
            PENDING.with(|pending| *pending.borrow_mut() = Some(error));
            true
        }
    })
    .unwrap_or(false)
}

/// The exception a signal handler raised during this thread's last wait.
pub(crate) fn take_pending() -> Option<PyErr> {
    PENDING.with(|pending| pending.borrow_mut().take())
}
