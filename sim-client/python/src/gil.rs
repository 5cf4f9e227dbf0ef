//! Waiting without the GIL, and Ctrl-C inside a wait.

use std::cell::RefCell;

use pyo3::prelude::*;

thread_local! {
    /// The exception a signal handler raised during this thread's wait
    /// (`KeyboardInterrupt` for Ctrl-C), raised when the wait returns.
    static PENDING: RefCell<Option<PyErr>> = const { RefCell::new(None) };
}

/// Moves a value across [`Python::detach`], which runs its closure on the
/// calling thread: nothing inside is sent to another thread.
struct SameThread<T>(T);

// SAFETY: `Python::detach` runs the closure synchronously on the thread
// that calls it, so the value never leaves that thread; the closures given
// to `detached` touch no Python object (they run the Rust client).
unsafe impl<T> Send for SameThread<T> {}

/// Runs `wait` (a Rust client call that may block) with the GIL released,
/// so other Python threads run meanwhile. `wait` must not touch Python
/// objects.
pub(crate) fn detached<R>(py: Python<'_>, wait: impl FnOnce() -> R) -> R {
    let wait = SameThread(wait);
    py.detach(move || {
        let wait = wait;
        SameThread((wait.0)())
    })
    .0
}

/// The client's interrupt check ([`sim_client::set_interrupt_check`]):
/// runs Python's signal handlers (on the main thread) and says to stop when
/// one raised, keeping its exception for [`take_pending`].
pub(crate) fn signalled() -> bool {
    Python::attach(|py| match py.check_signals() {
        Ok(()) => false,
        Err(error) => {
            PENDING.with(|pending| *pending.borrow_mut() = Some(error));
            true
        }
    })
}

/// The exception a signal handler raised during this thread's last wait.
pub(crate) fn take_pending() -> Option<PyErr> {
    PENDING.with(|pending| pending.borrow_mut().take())
}
