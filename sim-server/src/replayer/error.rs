//! Why a recording cannot be replayed, or a replay cannot go on.

use simbus_recording::RecordingError;

use crate::keyframe::KeyframeError;
use crate::scene::SceneError;
use crate::world::Inconsistency;

/// Why a recording cannot be replayed, or a replay cannot go on. Each
/// variant says what failed; the lower error it comes from is its typed
/// source ([`message`](crate::error::message) joins them for a client).
#[derive(Debug, thiserror::Error)]
pub(crate) enum ReplayError {
    /// The file cannot be read, or is not a simbus recording.
    #[error(transparent)]
    Read(#[from] RecordingError),
    /// No keyframe before the end of the file.
    #[error("the recording ended before its keyframe")]
    NoKeyframe,
    /// The keyframe the replay starts from cannot be restored.
    #[error("its keyframe")]
    Keyframe(#[source] KeyframeFault),
    /// The keyframe names a scene this server does not know.
    #[error("the keyframe's scene")]
    KeyframeScene(#[source] SceneError),
    /// A recorded episode names a scene this server does not know.
    #[error("the recording's scene")]
    EpisodeScene(#[source] SceneError),
    /// The file ends before the selected start.
    #[error("the recording ended before the start")]
    EndedBeforeStart,
    /// Re-simulating a recorded frame panicked in the physics engine.
    #[error("physics failed on frame {frame} of the recording (is the file damaged?)")]
    Physics {
        /// The recorded frame.
        frame: u64,
    },
}

/// Why a keyframe cannot be restored.
#[derive(Debug, thiserror::Error)]
pub(crate) enum KeyframeFault {
    /// Its bytes do not decode.
    #[error(transparent)]
    Decode(#[from] KeyframeError),
    /// It decodes to a world that rapier must not be given.
    #[error("the keyframe's world is inconsistent")]
    Inconsistent(#[source] Inconsistency),
}
