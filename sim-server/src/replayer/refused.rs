//! Why the replayer refuses a request to replay: the wire code a client
//! reads, and the words it shows. The recorder service answers with it
//! (its `Refused` wraps this one).

use shared_types::RecorderRefusal;

use super::ReplayError;

/// Why a request to replay, or to change a replay, was refused (see
/// [`ReplayRefused::code`] for the code on the wire; the words are the
/// message).
#[derive(Debug, thiserror::Error)]
pub(crate) enum ReplayRefused {
    /// A replay is asked for while one of this file is prepared.
    #[error("already preparing a replay of {0}")]
    AlreadyPreparing(String),
    /// Stop replay or a time factor, and no replay runs.
    #[error("no replay is running")]
    NotReplaying,
    /// The time factor is not a positive number.
    #[error("time factor {0} must be a positive number")]
    TimeFactor(f64),
    /// The start or the duration is not a number, or the duration is negative.
    #[error("start must be a number and duration a number of seconds, 0 or more")]
    BadSpan,
    /// The start lies past the end of the recording.
    #[error("start {start} s is past the end of the recording ({length:.3} s long)")]
    StartPastEnd {
        /// The start asked for, in seconds.
        start: f64,
        /// The recording's length, in seconds.
        length: f64,
    },
    /// The actor to follow is not in the recording.
    #[error("actor {0} is not in the recording")]
    UnknownActor(u64),
    /// The file has no frame or no keyframe to replay.
    #[error("{0} holds no frame (or no keyframe) to replay")]
    NothingToReplay(String),
    /// The file has a keyframe before its first frame.
    #[error("{0}: a keyframe before any frame")]
    KeyframeFirst(String),
    /// The recording cannot be replayed.
    #[error(transparent)]
    BadFile(#[from] ReplayError),
    /// The thread that reads the recording could not start.
    #[error("cannot start reading")]
    ReaderThread(#[source] std::io::Error),
    /// The thread that read the recording panicked.
    #[error("reading {0} failed unexpectedly")]
    ReaderPanicked(String),
}

impl ReplayRefused {
    /// The refusal's code on the wire.
    pub(crate) fn code(&self) -> RecorderRefusal {
        match self {
            Self::AlreadyPreparing(_) => RecorderRefusal::Replaying,
            Self::NotReplaying => RecorderRefusal::NotReplaying,
            Self::TimeFactor(_) | Self::BadSpan => RecorderRefusal::InvalidArgument,
            Self::StartPastEnd { .. } => RecorderRefusal::StartPastEnd,
            Self::UnknownActor(_) => RecorderRefusal::UnknownActor,
            Self::NothingToReplay(_)
            | Self::KeyframeFirst(_)
            | Self::BadFile(_)
            | Self::ReaderThread(_)
            | Self::ReaderPanicked(_) => RecorderRefusal::BadFile,
        }
    }
}
