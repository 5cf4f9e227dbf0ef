//! The recorder service: start and stop a recording, start, steer and stop
//! a replay, and ask how they are going. One request and one response type;
//! the file paths travel as [`PathText`].

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

use crate::wire::wire_enum;
use crate::wire::PROTOCOL_VERSION;

/// Default simulation time between two keyframes of a recording.
pub const DEFAULT_KEYFRAME_SECONDS: f64 = 10.0;
/// The shortest simulation time between two keyframes a server accepts.
pub const MIN_KEYFRAME_SECONDS: f64 = 1e-3;
/// The longest simulation time between two keyframes a server accepts
/// (one keyframe, at the start, for any run shorter than ~31 years).
pub const MAX_KEYFRAME_SECONDS: f64 = 1e9;

wire_enum! {
    /// What a [`RecorderRequest`] asks for.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum RecorderKind {
        /// Start recording to `path` ([`RecorderRequest::SENSORS`]: with captures).
        Start = 1,
        /// Stop recording; the answer says what was written.
        Stop = 2,
        /// Replay the recording at `path` (`start`, `duration`, `follow_id`,
        /// `mode`, `time_factor`, [`RecorderRequest::REPLAY_SENSORS`]).
        Replay = 3,
        /// Stop the replay ([`RecorderRequest::KEEP_ACTORS`]: keep the
        /// replayed world, else restore the one from before the replay).
        StopReplay = 4,
        /// Set the replay's time factor.
        TimeFactor = 5,
        /// How the recorder and the replayer are doing.
        Status = 6,
    }
}

wire_enum! {
    /// How a replay turns a recording into frames.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum ReplayMode {
        /// The recorded deltas one by one; actors set to their recorded states.
        Exact = 1,
        /// The server's own step; actors take the recorded states interpolated
        /// at the server's simulation time.
        Interpolate = 2,
        /// The recorded commands re-applied to real physics, each frame's
        /// state compared with the recording.
        Resimulate = 3,
    }
}

impl ReplayMode {
    /// The name used on the command line.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Exact => "exact",
            Self::Interpolate => "interpolate",
            Self::Resimulate => "resimulate",
        }
    }
}

impl std::str::FromStr for ReplayMode {
    type Err = String;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::ALL
            .into_iter()
            .find(|m| m.name() == s)
            .ok_or_else(|| {
                format!("unknown replay mode {s:?}: use exact, interpolate or resimulate")
            })
    }
}

wire_enum! {
    /// Where a replay is.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum ReplayState {
        /// No replay has run.
        Idle = 0,
        /// Started; in synchronous mode it waits for the next tick.
        Running = 1,
        /// Replayed every selected frame.
        Finished = 2,
        /// Stopped by a client before the end.
        Stopped = 3,
        /// The file turned out unreadable part way (the message says why).
        Failed = 4,
    }
}

wire_enum! {
    /// Why the recorder refused a request ([`RecorderResponse::refusal`];
    /// [`RecorderResponse::message`] says it in words).
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum RecorderRefusal {
        /// Not refused.
        None = 0,
        /// A recording is already running.
        AlreadyRecording = 1,
        /// No recording is running.
        NotRecording = 2,
        /// The server cannot create or write the file.
        CannotWrite = 3,
        /// A replay is running (no recording or second replay meanwhile).
        Replaying = 4,
        /// No replay is running.
        NotReplaying = 5,
        /// The file is not a readable recording.
        BadFile = 6,
        /// `start` is past the recording's end.
        StartPastEnd = 7,
        /// `follow_id` names no recorded actor.
        UnknownActor = 8,
        /// A value is out of range (time factor, duration, mode, path).
        InvalidArgument = 9,
        /// A recording is running (no replay meanwhile).
        Recording = 10,
    }
}

/// Up to 1024 bytes of UTF-8 text (paths, error messages).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::PathText/1")]
pub struct PathText {
    /// Bytes in use.
    pub len: u32,
    /// Zero.
    pub reserved: u32,
    /// The text, zero-padded.
    pub bytes: [u8; 1024],
}

impl PathText {
    /// The most bytes a [`PathText`] holds.
    pub const CAPACITY: usize = 1024;

    /// `text`, or `None` if it is longer than [`PathText::CAPACITY`].
    pub fn exact(text: &str) -> Option<Self> {
        (text.len() <= Self::CAPACITY).then(|| Self::cut(text))
    }

    /// `text` cut to at most 1024 bytes at a character boundary.
    pub fn cut(text: &str) -> Self {
        let (len, bytes) = crate::wire::text_field(text);
        Self {
            len,
            reserved: 0,
            bytes,
        }
    }

    /// The text; invalid bytes from a misbehaving peer read as `?`.
    pub fn to_string_lossy(&self) -> String {
        crate::wire::text_of(self.len, &self.bytes)
    }
}

/// A request to the recorder service.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::RecorderRequest/1")]
pub struct RecorderRequest {
    /// [`PROTOCOL_VERSION`] of the sender.
    pub protocol_version: u32,
    /// [`RecorderKind`] as `u32`.
    pub kind: u32,
    /// Process id of the sender.
    pub client_pid: u32,
    /// [`RecorderRequest::SENSORS`], [`RecorderRequest::KEEP_ACTORS`],
    /// [`RecorderRequest::REPLAY_SENSORS`].
    pub flags: u32,
    /// [`ReplayMode`] as `u32` (0: exact for fixed-step recordings,
    /// interpolate for variable-step ones).
    pub mode: u32,
    /// Zero.
    pub reserved: u32,
    /// Replay: seconds from the recording's start (negative: from its end).
    pub start_seconds: f64,
    /// Replay: seconds to replay (0: to the end).
    pub duration_seconds: f64,
    /// Replay and [`RecorderKind::TimeFactor`]: simulation speed relative
    /// to the recording (asynchronous mode).
    pub time_factor: f64,
    /// Replay: sensors spawned without a parent during the replay ride on
    /// this recorded actor (0: none).
    pub follow_id: u64,
    /// The recording's path (as the server sees it).
    pub path: PathText,
}

impl RecorderRequest {
    /// Flag for [`RecorderKind::Start`]: record every sensor capture.
    pub const SENSORS: u32 = 1;
    /// Flag for [`RecorderKind::StopReplay`] and [`RecorderKind::Replay`]:
    /// keep the replayed world when the replay stops or ends (else the world
    /// from before the replay comes back).
    pub const KEEP_ACTORS: u32 = 2;
    /// Flag for [`RecorderKind::Replay`]: spawn the recorded sensors again.
    pub const REPLAY_SENSORS: u32 = 4;

    /// A request of `kind` from this process.
    pub fn new(kind: RecorderKind) -> Self {
        Self {
            protocol_version: PROTOCOL_VERSION,
            kind: kind as u32,
            client_pid: crate::wire::this_process_id(),
            flags: 0,
            mode: 0,
            reserved: 0,
            start_seconds: 0.0,
            duration_seconds: 0.0,
            time_factor: 1.0,
            follow_id: 0,
            path: PathText::cut(""),
        }
    }
}

/// The recorder service's answer: the status of the request and how the
/// recorder and the replayer are doing.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::RecorderResponse/1")]
pub struct RecorderResponse {
    /// [`PROTOCOL_VERSION`] of the server.
    pub protocol_version: u32,
    /// [`ResponseStatus`](crate::wire::ResponseStatus) as `u32`.
    pub status: u32,
    /// [`RecorderRefusal`] as `u32`.
    pub refusal: u32,
    /// 1 while a recording runs.
    pub recording: u32,
    /// Frames written to the current (or last) recording.
    pub frames_written: u64,
    /// Bytes written to it (the file's size once closed).
    pub bytes_written: u64,
    /// [`ReplayState`] of the current (or last) replay, as `u32`.
    pub replay_state: u32,
    /// Its [`ReplayMode`] as `u32`.
    pub replay_mode: u32,
    /// Frames it replayed so far.
    pub replay_frames: u64,
    /// Frames it will replay in all.
    pub replay_total: u64,
    /// Resimulate: frames whose state matched the recording.
    pub verified_frames: u64,
    /// Resimulate: 1 if a frame differed (the first is below).
    pub mismatch: u32,
    /// [`RecorderResponse::RECORDED`].
    pub flags: u32,
    /// Resimulate: the first frame that differed.
    pub mismatch_frame: u64,
    /// Resimulate: the first actor that differed in it (0: the actor sets differ).
    pub mismatch_actor: u64,
    /// The replay's time factor.
    pub time_factor: f64,
    /// The recording's (or replay's) path.
    pub path: PathText,
    /// Why a request was refused, in words (empty when done).
    pub message: PathText,
}

crate::wire::responses!(RecorderResponse);

impl RecorderResponse {
    /// Flag: this server recorded since it started, and `path`,
    /// `frames_written` and `bytes_written` are its current or last
    /// recording's (without it, `path` is the last replay's file).
    pub const RECORDED: u32 = 1;

    /// An answer with nothing filled in but `status`.
    pub fn new(status: crate::wire::ResponseStatus) -> Self {
        Self {
            protocol_version: PROTOCOL_VERSION,
            status: status as u32,
            refusal: 0,
            recording: 0,
            frames_written: 0,
            bytes_written: 0,
            replay_state: 0,
            replay_mode: 0,
            replay_frames: 0,
            replay_total: 0,
            verified_frames: 0,
            mismatch: 0,
            flags: 0,
            mismatch_frame: 0,
            mismatch_actor: 0,
            time_factor: 1.0,
            path: PathText::cut(""),
            message: PathText::cut(""),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn paths_round_trip_and_long_ones_are_refused() {
        assert_eq!(
            PathText::exact("/tmp/a.mcap").unwrap().to_string_lossy(),
            "/tmp/a.mcap"
        );
        assert!(PathText::exact(&"x".repeat(1025)).is_none());
        assert_eq!(PathText::cut(&"é".repeat(600)).len, 1024);
    }

    #[test]
    fn modes_parse_by_name() {
        for mode in ReplayMode::ALL {
            assert_eq!(mode.name().parse::<ReplayMode>(), Ok(mode));
        }
        assert!("fast".parse::<ReplayMode>().is_err());
    }
}
