//! Why the recorder service refuses a request to record or replay: the
//! wire code a client reads, and the words it shows.

use shared_types::RecorderRefusal;

use super::StartError;
use crate::error::PortError;
use crate::replayer::ReplayRefused;

/// Why a request to record or replay was refused (see [`Refused::code`]
/// for the code on the wire; the words are the message).
#[derive(Debug, thiserror::Error)]
pub(crate) enum Refused {
    /// A recording is asked for while a replay of this file is prepared.
    #[error("a replay of {0} is being prepared")]
    PreparingReplay(String),
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
    /// The request names no file.
    #[error("no file path given")]
    NoPath,
    /// The replay mode code is none this server knows.
    #[error("unknown replay mode {0}")]
    UnknownMode(u32),
    /// The recording's file cannot be written.
    #[error(transparent)]
    CannotWrite(#[from] StartError),
    /// Stopping the replay failed on the bus.
    #[error(transparent)]
    StopReplay(PortError),
    /// The replayer refused the request.
    #[error(transparent)]
    Replay(#[from] ReplayRefused),
}

impl Refused {
    /// The refusal's code on the wire.
    pub(crate) fn code(&self) -> RecorderRefusal {
        match self {
            Self::PreparingReplay(_) | Self::ReplayRuns | Self::AlreadyReplaying(_) => {
                RecorderRefusal::Replaying
            }
            Self::AlreadyRecording(_) => RecorderRefusal::AlreadyRecording,
            Self::Recording(_) => RecorderRefusal::Recording,
            Self::NotRecording | Self::StoppedByItself(_) => RecorderRefusal::NotRecording,
            Self::StopReplay(_) => RecorderRefusal::NotReplaying,
            Self::NoPath | Self::UnknownMode(_) => RecorderRefusal::InvalidArgument,
            Self::CannotWrite(_) => RecorderRefusal::CannotWrite,
            Self::Replay(refused) => refused.code(),
        }
    }
}
