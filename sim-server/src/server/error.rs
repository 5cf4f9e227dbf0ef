//! What starting or running a server can fail with.

use std::path::PathBuf;

use shared_types::SettingsError;

use crate::error::PortError;
use crate::journal::resume::ResumeError;
use crate::journal::JournalError;
use crate::sensors::RenderThreadsError;

/// Why the server could not start or stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    /// A port could not be opened or used (another server owns the world,
    /// the shared directory cannot be used, iceoryx2 refused).
    #[error(transparent)]
    Port(#[from] PortError),
    /// The start settings were refused.
    #[error("invalid settings: {0}")]
    Settings(#[from] SettingsError),
    /// The time between keyframes is not a number of seconds in range.
    #[error("keyframe interval {seconds} s is out of range: it must be in {min}..={max} s (--keyframe-seconds)")]
    KeyframeSeconds {
        /// The refused interval.
        seconds: f64,
        /// The shortest accepted.
        min: f64,
        /// The longest accepted.
        max: f64,
    },
    /// The render threads (`--render-threads`) could not be started.
    #[error(transparent)]
    RenderThreads(#[from] RenderThreadsError),
    /// The journal could not be started.
    #[error(transparent)]
    Journal(#[from] JournalError),
    /// The journal could not be resumed.
    #[error(transparent)]
    Resume(#[from] ResumeError),
    /// A fork was asked to journal into the journal it forks.
    #[error("a fork leaves its journal untouched: journal it into another directory than {dir}")]
    ForkIntoOriginal {
        /// The original journal.
        dir: PathBuf,
    },
    /// A resume named another world than its journal's.
    #[error("the journal in {dir} is world '{journal}', not '{asked}': resume it under its own name, or fork it under a new one with --at FRAME --world NEW")]
    OtherWorld {
        /// The journal.
        dir: PathBuf,
        /// Its world.
        journal: String,
        /// The world asked for.
        asked: String,
    },
}
