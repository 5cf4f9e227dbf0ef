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
pub(crate) mod describe;
pub(crate) mod failure;
#[cfg(feature = "foxglove")]
pub(crate) mod foxglove;
pub(crate) mod interrupt;
pub(crate) mod output;
pub(crate) mod parse;
pub(crate) mod pictures;
pub(crate) mod recorder;
#[cfg(feature = "ros2")]
pub(crate) mod ros2;
pub(crate) mod sensor;
mod sensor_capture;
mod sensor_save;
mod sensor_text;
pub(crate) mod session;
pub(crate) mod snapshot;
pub(crate) mod stall;
pub(crate) mod status;
pub(crate) mod tick;
mod tick_restarts;
pub(crate) mod top;
pub(crate) mod watch;
pub(crate) mod words;
