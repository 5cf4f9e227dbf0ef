//! Where the commands' `println!` / `print!` / `eprintln!` go.
//!
//! `cli/mod.rs` shadows those std macros for every subcommand with ones
//! that call [`stdout`] and [`stderr`] here, so a command's printing is
//! safe without each command doing anything:
//!
//! - A closed stdout (`sim-client watch | head -1`) does not panic: the
//!   write unwinds the command with a [`StdoutClosed`] payload (no panic
//!   message: `resume_unwind` skips the panic hook), so every guard on the
//!   way runs — a ticker gives the world back, a lockstep participant
//!   leaves, a child is reaped — and `main` then exits 0, quietly.
//!   SIGPIPE stays ignored (Rust's default), so the process is never killed
//!   before that cleanup.
//! - Another stdout failure (a full disk) unwinds the same way with the
//!   error, and `main` reports it and exits 1.
//! - A closed stderr is ignored: a message nobody can read is dropped, it
//!   never ends a command halfway.

use std::fmt;
use std::io::Write;
use std::sync::atomic::Ordering;

/// The unwind payload of a write to a closed stdout.
#[derive(Debug)]
pub(crate) struct StdoutClosed;

/// The unwind payload of a write to stdout that failed otherwise.
#[derive(Debug)]
pub(crate) struct StdoutFailed(pub(crate) std::io::Error);

/// Writes `args` to stdout. On failure it stops the command: it sets
/// [`super::interrupt::interrupted`] (so other threads stop at their next check) and
/// unwinds this thread with [`StdoutClosed`] or [`StdoutFailed`].
pub(crate) fn stdout(args: fmt::Arguments<'_>) {
    let result = std::io::stdout().lock().write_fmt(args);
    if let Err(e) = result {
        super::interrupt::interrupted().store(true, Ordering::Relaxed);
        if e.kind() == std::io::ErrorKind::BrokenPipe {
            std::panic::resume_unwind(Box::new(StdoutClosed));
        }
        std::panic::resume_unwind(Box::new(StdoutFailed(e)));
    }
}

/// Writes `args` to stderr; a failed write (stderr closed) is ignored.
pub(crate) fn stderr(args: fmt::Arguments<'_>) {
    let _ = std::io::stderr().lock().write_fmt(args);
}

/// How a command run by [`run`] ended.
#[derive(Debug)]
pub(crate) enum Ended<T> {
    /// It returned.
    Returned(T),
    /// It wrote to a closed stdout and stopped there.
    StdoutClosed,
    /// A write to stdout failed otherwise.
    StdoutFailed(std::io::Error),
}

/// Runs `command`, turning the unwinds of [`stdout`] into an [`Ended`];
/// everything the command held was dropped by then. Any other panic
/// continues.
pub(crate) fn run<T>(command: impl FnOnce() -> T) -> Ended<T> {
    match std::panic::catch_unwind(std::panic::AssertUnwindSafe(command)) {
        Ok(result) => Ended::Returned(result),
        Err(payload) => {
            if payload.is::<StdoutClosed>() {
                return Ended::StdoutClosed;
            }
            match payload.downcast::<StdoutFailed>() {
                Ok(failed) => Ended::StdoutFailed(failed.0),
                Err(payload) => std::panic::resume_unwind(payload),
            }
        }
    }
}
