//! The `sim-client` subcommands.

// Every subcommand prints through these, not std's macros of the same
// names (they shadow them in every module below and, through
// `#[macro_use]`, in main.rs): a closed stdout ends the command quietly,
// after its guards ran, instead of panicking. See [`output`].

/// `println!` that stops the command quietly when stdout is closed.
macro_rules! println {
    () => {
        $crate::cli::output::stdout(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::cli::output::stdout(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `print!` that stops the command quietly when stdout is closed.
macro_rules! print {
    ($($arg:tt)*) => {
        $crate::cli::output::stdout(format_args!($($arg)*))
    };
}

/// `eprintln!` that drops the message when stderr is closed.
macro_rules! eprintln {
    () => {
        $crate::cli::output::stderr(format_args!("\n"))
    };
    ($($arg:tt)*) => {
        $crate::cli::output::stderr(format_args!("{}\n", format_args!($($arg)*)))
    };
}

/// `eprint!` that drops the message when stderr is closed.
#[allow(unused_macros)]
macro_rules! eprint {
    ($($arg:tt)*) => {
        $crate::cli::output::stderr(format_args!($($arg)*))
    };
}

pub(crate) mod actors;
pub(crate) mod autopilot;
#[cfg(feature = "zenoh")]
pub(crate) mod bridge;
#[cfg(feature = "carla")]
pub(crate) mod carla;
pub(crate) mod config;
pub(crate) mod demo;
#[cfg(feature = "foxglove")]
pub(crate) mod foxglove;
pub(crate) mod output;
pub(crate) mod pictures;
pub(crate) mod recorder;
pub(crate) mod sensor;
mod sensor_capture;
mod sensor_save;
mod sensor_text;
pub(crate) mod snapshot;
pub(crate) mod stall;
pub(crate) mod status;
pub(crate) mod tick;
mod tick_restarts;
pub(crate) mod top;
pub(crate) mod watch;
pub(crate) mod words;

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};

use anyhow::anyhow;
use shared_types::WorldSettings;
use simbus_input::Readable;

use crate::Failure;

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

/// [`sim_client::Client::connect`] that Ctrl-C and SIGTERM end
/// ([`Failure::Interrupted`]; [`sim_client::connect_until_stopped`] looks
/// at [`interrupted`] every 200 ms): a world whose server is not up used to
/// hold the command for its whole `--timeout`, whatever the user pressed.
pub(crate) fn connect(
    world: &str,
    timeout: std::time::Duration,
) -> Result<sim_client::Client, Failure> {
    sim_client::connect_until_stopped(timeout, interrupted(), |slice| {
        sim_client::Client::connect(world, slice)
    })?
    .ok_or_else(|| Failure::Interrupted(anyhow!("before the server of world '{world}' answered")))
}

/// A settings refusal is refused input (exit 2); a failed request is a
/// runtime failure (exit 1).
pub(crate) fn refused_or_runtime(e: sim_client::ApplySettingsError) -> Failure {
    match e {
        sim_client::ApplySettingsError::Request(e) => Failure::Runtime(e.into()),
        e => Failure::Refused(e.into()),
    }
}

/// `N` comma-separated finite numbers, as a flag like `--at x,y,z` takes them.
pub(crate) fn numbers<const N: usize>(text: &str, flag: &str) -> Result<[f32; N], Failure> {
    let values: Vec<f32> = text
        .split(',')
        .map(|p| {
            p.trim()
                .parse::<f32>()
                .ok()
                .filter(|v| v.is_finite())
                .ok_or(())
        })
        .collect::<Result<_, _>>()
        .map_err(|_| {
            Failure::Refused(anyhow!(
                "{flag} takes {N} comma-separated finite numbers, got '{text}'"
            ))
        })?;
    values.try_into().map_err(|_| {
        Failure::Refused(anyhow!(
            "{flag} takes {N} comma-separated finite numbers, got '{text}'"
        ))
    })
}

/// A lockstep participant as `status` and `top` print it: its window,
/// how far behind the world it is, and how long it made its last frame
/// wait.
pub(crate) fn participant_line(p: &sim_client::ParticipantStatus) -> String {
    let behind = match p.lag {
        None => "no report in this episode yet".to_owned(),
        Some(0) => format!("done with frame {}, the latest", p.done_frame),
        Some(lag) => format!(
            "done with frame {}, {} behind",
            p.done_frame,
            words::count(lag, "frame")
        ),
    };
    let wait = p.done_after.map_or_else(String::new, |d| {
        format!(" ({:.0} µs after it was published)", d.as_secs_f64() * 1e6)
    });
    format!(
        "{} (pid {}): window {}, {behind}{wait}",
        p.name, p.pid, p.window
    )
}

/// A lockstep participant as `status --json` and `top --json` print it.
pub(crate) fn participant_json(p: &sim_client::ParticipantStatus) -> serde_json::Value {
    serde_json::json!({
        "name": p.name,
        "pid": p.pid,
        "window": p.window,
        "done_frame": p.done_frame,
        // Frames the world is ahead of its last "done" (null: none yet).
        "lag": p.lag,
        // How long after that frame's publication its "done" came (µs):
        // how long it made that step wait at most.
        "done_after_us": p.done_after.map(|d| d.as_secs_f64() * 1e6),
    })
}

/// The settings as the JSON object `status` and `config --json` print.
pub(crate) fn settings_json(settings: &WorldSettings) -> serde_json::Value {
    serde_json::json!({
        "synchronous_mode": settings.synchronous_mode,
        "fixed_delta_seconds": settings.fixed_delta_seconds,
        "substepping": settings.substepping,
        "max_substep_delta_time": settings.max_substep_delta_time,
        "max_substeps": settings.max_substeps,
        "substep_rule": settings.substep_rule.name(),
    })
}

/// The settings as readable lines (seconds to six significant digits;
/// `--json` has them exact).
pub(crate) fn settings_lines(settings: &WorldSettings) -> Vec<(&'static str, String)> {
    vec![
        (
            "mode",
            if settings.synchronous_mode {
                "synchronous (the ticker rules time)".to_owned()
            } else {
                "asynchronous".to_owned()
            },
        ),
        (
            "step",
            match settings.fixed_delta_seconds {
                // Readably: 0.0333333 s (30 FPS), not 0.03333333333333333.
                Some(dt) => format!("fixed {} s ({} FPS)", Readable(dt), Readable(1.0 / dt)),
                None => "variable (follows wall time)".to_owned(),
            },
        ),
        (
            "substeps",
            if settings.substepping {
                format!(
                    "on: at most {} of {} s",
                    settings.max_substeps,
                    Readable(settings.max_substep_delta_time)
                )
            } else {
                "off: one physics step per frame".to_owned()
            },
        ),
        ("rule", config::substep_rule_line(settings)),
    ]
}
