//! The hybrid wait on one listener, for a process that waits on a single
//! event for everything (the Zenoh bridges): look at the event's counter,
//! yielding the CPU between looks, for a short window, then sleep on it.
//!
//! A wake-up of a sleeping process costs a `futex` call on each side and,
//! on an idle CPU, the time the CPU takes to come out of its idle state
//! (5–25 µs on a virtual machine); an answer that comes within the window
//! costs neither. Between looks the waiter yields (`sched_yield`), so a
//! peer that shares its CPU still runs: the same rule as a client's
//! `WaitMode::Hybrid` and the server's `--hybrid-window-us`.
//!
//! ```
//! use std::time::Duration;
//! use simbus_transport::hybrid;
//!
//! simbus_transport::environment::prepare().unwrap();
//! let node = simbus_transport::node("hybrid-doc").unwrap();
//! let name = format!("hybrid-doc-{}/event", std::process::id());
//! let event = node
//!     .service_builder(&name.as_str().try_into().unwrap())
//!     .event()
//!     .open_or_create()
//!     .unwrap();
//! let listener = event.listener_builder().create().unwrap();
//! let notifier = event.notifier_builder().create().unwrap();
//!
//! // Nothing rang: the window, then the sleep, pass.
//! let rang = hybrid::wait(&listener, Duration::from_micros(50), Duration::from_millis(1));
//! assert!(!rang.unwrap());
//! // A ring is found by a look, without a sleep.
//! notifier.notify().unwrap();
//! let rang = hybrid::wait(&listener, Duration::from_micros(50), Duration::from_secs(1));
//! assert!(rang.unwrap());
//! ```

use std::time::{Duration, Instant};

use iceoryx2::port::listener::{Listener, ListenerWaitError};

use crate::bus::Bus;

/// Waits until `listener` is rung or `timeout` passes; whether it was rung.
///
/// For the first `poll_for` (at most `timeout`) it looks at the event's
/// counter, yielding the CPU between looks; then it sleeps on the event for
/// what is left. `poll_for` zero is a plain sleeping wait. Every ring that
/// came is consumed.
///
/// # Errors
///
/// Returns the [`ListenerWaitError`] iceoryx2 reports if looking at or waiting
/// on the event fails (`InternalFailure`, `ContractViolation`). A signal that
/// interrupts the sleeping wait is not an error: the wait ends and says whether
/// the event was rung meanwhile.
pub fn wait(
    listener: &Listener<Bus>,
    poll_for: Duration,
    timeout: Duration,
) -> Result<bool, ListenerWaitError> {
    let start = Instant::now();
    let mut rang = false;
    if !poll_for.is_zero() {
        let poll_for = poll_for.min(timeout);
        loop {
            let notifications = listener.try_wait(|_| rang = true)?;
            if rang || notifications > 0 {
                return Ok(true);
            }
            if start.elapsed() >= poll_for {
                break;
            }
            std::thread::yield_now();
        }
    }
    let left = timeout.saturating_sub(start.elapsed());
    match listener.timed_wait(|_| rang = true, left) {
        Ok(notifications) => Ok(rang || notifications > 0),
        Err(ListenerWaitError::InterruptSignal) => Ok(rang),
        Err(e) => Err(e),
    }
}
