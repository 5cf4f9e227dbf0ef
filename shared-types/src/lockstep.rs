//! The lockstep service: participants that the server waits for, frame by
//! frame, in synchronous mode.

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

use crate::wire::wire_enum;
use crate::wire::FixedText;
use crate::wire::PROTOCOL_VERSION;

wire_enum! {
    /// What a [`LockstepRequest`] asks for.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum LockstepKind {
        /// Become a participant. The server then waits for its `Done` for the
        /// current frame before stepping (with a window of W frames: for the
        /// frame W before the one it is to step past).
        Join = 1,
        /// Stop being a participant.
        Leave = 2,
        /// Done with `frame` of `episode` (its commands for the next frame are sent).
        Done = 3,
    }
}

/// A request on the lockstep service.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::LockstepRequest/2")]
pub struct LockstepRequest {
    /// [`PROTOCOL_VERSION`] of the sender.
    pub protocol_version: u32,
    /// [`LockstepKind`] as `u32`.
    pub kind: u32,
    /// The participant's process id, as it states it (the server watches
    /// the process of the sending port instead).
    pub pid: u32,
    /// For `Join`: the participant's window, how many frames the world may
    /// run ahead of its last `Done` — in synchronous mode the server steps
    /// past frame N only when it is done with frame N − window. 0 (every
    /// frame waits for it) up to [`MAX_LOCKSTEP_WINDOW`].
    pub window: u32,
    /// For `Done`: the frame finished.
    pub frame: u64,
    /// For `Done`: the episode of that frame.
    pub episode: u64,
    /// The participant's name, for logs and status.
    pub name: FixedText,
}

/// The largest lockstep window a participant may ask for, in frames.
pub const MAX_LOCKSTEP_WINDOW: u32 = 1000;

impl LockstepRequest {
    /// A request of `kind` from this process (a window of 0).
    pub fn new(kind: LockstepKind, name: &str, episode: u64, frame: u64) -> Self {
        Self {
            protocol_version: PROTOCOL_VERSION,
            kind: kind as u32,
            pid: crate::wire::this_process_id(),
            window: 0,
            frame,
            episode,
            name: FixedText::new(name),
        }
    }
}

/// The server's answer on the lockstep service.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::LockstepResponse/1")]
pub struct LockstepResponse {
    /// [`PROTOCOL_VERSION`] of the server.
    pub protocol_version: u32,
    /// [`ResponseStatus`](crate::wire::ResponseStatus) as `u32`.
    pub status: u32,
    /// The current frame (for `Join`: the frame to report `Done` for first).
    pub frame: u64,
    /// The current episode.
    pub episode: u64,
}

crate::wire::responses!(LockstepResponse);
