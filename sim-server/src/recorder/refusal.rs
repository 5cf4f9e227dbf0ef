//! Why the recorder service refuses a request to record or replay: the
//! wire code a client reads, and the words it shows.

use shared_types::RecorderRefusal;

use super::StartError;
use crate::replayer::ReplayError;
use crate::ServerError;

/// Why a request to record or replay was refused (see [`Refused::code`]
/// for the code on the wire; the words are the message).
#[derive(Debug, thiserror::Error)]
pub(crate) enum Refused {
    /// A recording is asked for while a replay of this file is prepared.
    #[error("a replay of {0} is being prepared")]
    PreparingReplay(String),
    /// A replay is asked for while one of this file is prepared.
    #[error("already preparing a replay of {0}")]
    AlreadyPreparing(String),
    /// A recording is asked for while a replay runs.
    #[error("a replay is running; stop it first")]
    ReplayRuns,
    /// A replay is asked for while one of this file runs.
    #[error("already replaying {0}")]
    AlreadyReplaying(String),
    /// A recording is asked for while one to this file runs.
    #[error("already recording to {0}")]
    AlreadyRecording(String),
    /// A replay is asked for while a recording to this file runs.
    #[error("recording to {0}; stop the recorder first")]
    Recording(String),
    /// Stop, and no recording runs.
    #[error("no recording is running")]
    NotRecording,
    /// Stop, and the recording had stopped by itself (the disk filled):
    /// where, why and what the file holds.
    #[error("no recording is running: {0}")]
    StoppedByItself(String),
    /// Stop replay or a time factor, and no replay runs.
    #[error("no replay is running")]
    NotReplaying,
    /// The request names no file.
    #[error("no file path given")]
    NoPath,
    /// The replay mode code is none this server knows.
    #[error("unknown replay mode {0}")]
    UnknownMode(u32),
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
    /// The recording's file cannot be written.
    #[error(transparent)]
    CannotWrite(#[from] StartError),
    /// Stopping the replay failed on the bus.
    #[error(transparent)]
    StopReplay(ServerError),
}

impl Refused {
    /// The refusal's code on the wire.
    pub(crate) fn code(&self) -> RecorderRefusal {
        match self {
            Self::PreparingReplay(_)
            | Self::AlreadyPreparing(_)
            | Self::ReplayRuns
            | Self::AlreadyReplaying(_) => RecorderRefusal::Replaying,
            Self::AlreadyRecording(_) => RecorderRefusal::AlreadyRecording,
            Self::Recording(_) => RecorderRefusal::Recording,
            Self::NotRecording | Self::StoppedByItself(_) => RecorderRefusal::NotRecording,
            Self::NotReplaying | Self::StopReplay(_) => RecorderRefusal::NotReplaying,
            Self::NoPath | Self::UnknownMode(_) | Self::TimeFactor(_) | Self::BadSpan => {
                RecorderRefusal::InvalidArgument
            }
            Self::StartPastEnd { .. } => RecorderRefusal::StartPastEnd,
            Self::UnknownActor(_) => RecorderRefusal::UnknownActor,
            Self::NothingToReplay(_)
            | Self::KeyframeFirst(_)
            | Self::BadFile(_)
            | Self::ReaderThread(_)
            | Self::ReaderPanicked(_) => RecorderRefusal::BadFile,
            Self::CannotWrite(_) => RecorderRefusal::CannotWrite,
        }
    }
}
