//! Ctrl-C and SIGTERM: the flag every command checks, the wake-ups of
//! commands that block on an event of their own, and waits in slices.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

/// What Ctrl-C / SIGTERM call besides setting [`interrupted`].
type Wake = Box<dyn Fn() + Send>;

/// The [`Wake`]s given to [`on_interrupt`].
fn wakes() -> &'static std::sync::Mutex<Vec<Wake>> {
    static WAKES: OnceLock<std::sync::Mutex<Vec<Wake>>> = OnceLock::new();
    WAKES.get_or_init(Default::default)
}

/// Set by Ctrl-C / SIGTERM; commands stop at their next check.
pub(crate) fn interrupted() -> &'static AtomicBool {
    static FLAG: OnceLock<Arc<AtomicBool>> = OnceLock::new();
    FLAG.get_or_init(|| {
        let flag = Arc::new(AtomicBool::new(false));
        let handler_flag = flag.clone();
        let handler = move || {
            handler_flag.store(true, Ordering::Relaxed);
            let wakes = wakes().lock().unwrap_or_else(|e| e.into_inner());
            wakes.iter().for_each(|wake| wake());
        };
        if let Err(e) = ctrlc::set_handler(handler) {
            tracing::warn!("could not install the Ctrl-C handler: {e}");
        }
        flag
    })
}

/// Calls `wake` on Ctrl-C / SIGTERM (at once if one came already): for a
/// command that blocks on an event of its own instead of reading
/// [`interrupted`] (the CARLA gateway).
#[cfg(feature = "carla")]
pub(crate) fn on_interrupt(wake: impl Fn() + Send + Sync + 'static) {
    let flag = interrupted();
    let wake = Arc::new(wake);
    let registered = wake.clone();
    wakes()
        .lock()
        .unwrap_or_else(|e| e.into_inner())
        .push(Box::new(move || registered()));
    if flag.load(Ordering::Relaxed) {
        wake();
    }
}

/// Waits up to `timeout` with `wait` called in slices of at most 200 ms,
/// so Ctrl-C is noticed promptly; `Ok(None)` when interrupted. A slice that
/// times out (`timed_out`) before the deadline is waited again; the last
/// one's error is returned with the whole `timeout` in it.
pub(crate) fn in_slices<T>(
    timeout: std::time::Duration,
    mut wait: impl FnMut(std::time::Duration) -> Result<T, sim_client::WaitError>,
) -> Result<Option<T>, sim_client::WaitError> {
    use sim_client::WaitError;
    let deadline = std::time::Instant::now() + timeout;
    loop {
        if interrupted().load(Ordering::Relaxed) {
            return Ok(None);
        }
        let slice = deadline
            .saturating_duration_since(std::time::Instant::now())
            .min(std::time::Duration::from_millis(200));
        match wait(slice) {
            Err(WaitError::Timeout { .. } | WaitError::NoCapture { .. })
                if std::time::Instant::now() < deadline => {}
            Err(WaitError::Timeout {
                world, last_frame, ..
            }) => {
                return Err(WaitError::Timeout {
                    world,
                    timeout,
                    last_frame,
                })
            }
            Err(WaitError::NoCapture {
                sensor,
                world,
                last_frame,
                ..
            }) => {
                return Err(WaitError::NoCapture {
                    sensor,
                    world,
                    timeout,
                    last_frame,
                })
            }
            other => return other.map(Some),
        }
    }
}
