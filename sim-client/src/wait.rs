//! The one deadline-and-liveness wait of the client. Frames, sensor
//! captures and answers to requests all wait here: poll, and between polls
//! block on an event, back off, or spin, until the deadline — and end early
//! when the server process is gone.

use std::sync::atomic::{AtomicPtr, Ordering};
use std::time::{Duration, Instant};

use iceoryx2::port::listener::{Listener, ListenerWaitError};

use crate::WaitMode;
use simbus_transport::Bus;

/// Whether the process `pid` still runs (a zombie does not): how a client
/// notices that its server died. Linux reads `/proc`; elsewhere every
/// process is assumed alive and timeouts decide.
pub fn process_alive(pid: u32) -> bool {
    if !cfg!(target_os = "linux") {
        return true;
    }
    match std::fs::read_to_string(format!("/proc/{pid}/stat")) {
        // The state is the first field after the parenthesised command name.
        Ok(stat) => stat
            .rfind(')')
            .and_then(|i| stat[i + 1..].split_whitespace().next())
            .is_some_and(|state| state != "Z" && state != "X"),
        Err(_) => false,
    }
}

/// How long [`WaitMode::Hybrid`] (and [`Wait::Backoff`]) polls before it sleeps.
pub(crate) const HYBRID_SPIN: Duration = Duration::from_micros(100);

/// How often a waiting client checks that the server process still lives.
pub(crate) const LIVENESS_PERIOD: Duration = Duration::from_millis(100);

/// The interrupt check, a `fn() -> bool` stored as a pointer (null: none).
static INTERRUPT: AtomicPtr<()> = AtomicPtr::new(std::ptr::null_mut());

/// Makes every wait of this process's clients (a tick, a frame, a capture,
/// an answer) call `check` at least every 100 ms, and end with an
/// `Interrupted` error when it returns true: how a host language delivers
/// Ctrl-C to a wait (the Python package checks its signals there). `None`
/// removes it. A wait checks nothing else and costs nothing without one.
pub fn set_interrupt_check(check: Option<fn() -> bool>) {
    let pointer = check.map_or(std::ptr::null_mut(), |f| f as *mut ());
    INTERRUPT.store(pointer, Ordering::Release);
}

/// Whether the interrupt check, if any, says to stop.
pub(crate) fn interrupted() -> bool {
    let pointer = INTERRUPT.load(Ordering::Acquire);
    if pointer.is_null() {
        return false;
    }
    // SAFETY: a non-null value was stored by `set_interrupt_check` from a
    // `fn() -> bool` cast to a pointer (the same size on every platform
    // Rust supports, provenance kept); the function stays loaded while it
    // is stored here (it is this process's code).
    let check: fn() -> bool = unsafe { std::mem::transmute::<*mut (), fn() -> bool>(pointer) };
    check()
}

/// How to pass the time between polls.
#[derive(Debug, Clone, Copy)]
pub(crate) enum Wait<'a> {
    /// Poll for [`HYBRID_SPIN`], then sleep 10 µs, doubling up to 1 ms (for
    /// answers without an event).
    Backoff,
    /// Sleep on an event the server notifies right after it publishes.
    Event(&'a Listener<Bus>),
    /// Poll in a tight loop.
    Spin,
    /// Poll for [`HYBRID_SPIN`], then sleep on the event.
    Hybrid(&'a Listener<Bus>),
}

impl<'a> Wait<'a> {
    /// The wait for something announced by `listener`, as `mode` says.
    pub(crate) fn for_mode(mode: WaitMode, listener: &'a Listener<Bus>) -> Self {
        match mode {
            WaitMode::Block => Wait::Event(listener),
            WaitMode::Spin => Wait::Spin,
            WaitMode::Hybrid => Wait::Hybrid(listener),
        }
    }
}

/// Why [`until`] ended without a value.
#[derive(Debug)]
pub(crate) enum Stop<E> {
    /// The poll failed.
    Failed(E),
    /// The deadline passed.
    TimedOut,
    /// The server process is gone.
    ServerGone,
    /// The event could not be waited on.
    Event(ListenerWaitError),
    /// The interrupt check ([`set_interrupt_check`]) said to stop.
    Interrupted,
}

/// Calls `poll` until it yields, waiting between calls as `wait` says,
/// until `deadline`; checks every [`LIVENESS_PERIOD`] that `server_pid`
/// (when non-zero) still lives and that the interrupt check, if any, does
/// not say to stop.
pub(crate) fn until<T, E>(
    deadline: Instant,
    server_pid: u32,
    wait: Wait<'_>,
    mut poll: impl FnMut() -> Result<Option<T>, E>,
) -> Result<T, Stop<E>> {
    let start = Instant::now();
    let mut backoff = Duration::from_micros(10);
    let mut next_liveness_check = start + LIVENESS_PERIOD;
    loop {
        if let Some(value) = poll().map_err(Stop::Failed)? {
            return Ok(value);
        }
        let now = Instant::now();
        if now >= deadline {
            return Err(Stop::TimedOut);
        }
        if now >= next_liveness_check {
            if server_pid != 0 && !process_alive(server_pid) {
                return Err(Stop::ServerGone);
            }
            if interrupted() {
                return Err(Stop::Interrupted);
            }
            next_liveness_check = now + LIVENESS_PERIOD;
        }
        let remaining = (deadline - now).min(next_liveness_check - now);
        let polling = now - start < HYBRID_SPIN;
        match wait {
            Wait::Spin => std::hint::spin_loop(),
            // Hybrid polls yielding the CPU: on a CPU it shares with the
            // server, a spin would keep the server from answering for the
            // whole window.
            Wait::Hybrid(_) if polling => std::thread::yield_now(),
            Wait::Backoff if polling => std::hint::spin_loop(),
            Wait::Backoff => {
                std::thread::sleep(backoff.min(remaining));
                backoff = (backoff * 2).min(Duration::from_millis(1));
            }
            Wait::Event(listener) | Wait::Hybrid(listener) => {
                let waited = listener.timed_wait(|_| {}, remaining);
                simbus_transport::stamps::woke();
                match waited {
                    Ok(_) | Err(ListenerWaitError::InterruptSignal) => {}
                    Err(e) => return Err(Stop::Event(e)),
                }
            }
        }
    }
}
