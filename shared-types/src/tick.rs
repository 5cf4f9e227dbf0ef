//! The tick service: the one channel through which the ticker claims
//! ownership, enters and leaves synchronous mode, and ticks. The service
//! admits a single client, so a second would-be ticker cannot even send.

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

use crate::settings::{SettingsError, WorldSettings};
use crate::settings_wire::{WireSettings, WireSettingsError};
use crate::wire::wire_enum;
use crate::wire::PROTOCOL_VERSION;
use crate::wire::{FixedText, ResponseStatus};

wire_enum! {
    /// What a [`TickRequest`] asks for.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum TickRequestKind {
        /// Become the ticker (or confirm it).
        Claim = 1,
        /// Stop being the ticker.
        Release = 2,
        /// Compute the next frame; answered once its snapshot is published.
        Tick = 3,
        /// Apply settings; unlike the control service this may enter
        /// synchronous mode.
        ApplySettings = 4,
        /// Become the ticker as soon as nobody holds the world: granted at
        /// once when the world is free, otherwise queued (first come, first
        /// served) behind the owner. A queued request is answered twice:
        /// at once with [`ResponseStatus::NotTicker`] naming the owner (an
        /// interim answer), then with [`ResponseStatus::Ok`] at the moment
        /// the owner releases, dies or is revoked. A `Release` from the
        /// same port withdraws it.
        Standby = 5,
    }
}

/// Who holds tick ownership.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::TickerInfo/1")]
pub struct TickerInfo {
    /// 1 when a ticker holds ownership, 0 when nobody does.
    pub active: u32,
    /// The ticker's process id.
    pub pid: u32,
    /// The last frame published before the ticker claimed ownership.
    pub since_frame: u64,
    /// The ticker's iceoryx2 node name.
    pub node_name: FixedText,
}

impl TickerInfo {
    /// Nobody ticks.
    pub fn none() -> Self {
        Self {
            active: 0,
            pid: 0,
            since_frame: 0,
            node_name: FixedText::new(""),
        }
    }

    /// `Some(self)` when a ticker holds ownership.
    pub fn active(self) -> Option<Self> {
        (self.active != 0).then_some(self)
    }
}

impl std::fmt::Display for TickerInfo {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        if self.active == 0 {
            return f.write_str("none");
        }
        write!(
            f,
            "{} (pid {}) since frame {}",
            self.node_name.to_string_lossy(),
            self.pid,
            self.since_frame
        )
    }
}

/// A request on the tick service.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::TickRequest/1")]
pub struct TickRequest {
    /// [`PROTOCOL_VERSION`] of the sender.
    pub protocol_version: u32,
    /// [`TickRequestKind`] as `u32`.
    pub kind: u32,
    /// Process id of the ticker, as it states it (ownership is given to
    /// the process of the sending port instead).
    pub pid: u32,
    /// [`TickRequest::ON_BEHALF`], [`TickRequest::BY_FRAME`], or zero.
    pub flags: u32,
    /// Settings for [`TickRequestKind::ApplySettings`].
    pub settings: WireSettings,
    /// The ticker's node name, for [`TickRequestKind::Claim`].
    pub node_name: FixedText,
}

impl TickRequest {
    /// Flag: a bridge claims for a ticker on another host, named by `pid`
    /// and `node_name`. The bridge's own process holds the ownership (its
    /// death ends it); the world reports the remote ticker as the owner.
    pub const ON_BEHALF: u32 = 1;
    /// Flag on a tick: answered by its frame alone. Once the frame is
    /// published in synchronous mode the server sends this tick no answer;
    /// the ticker reads the frame itself (one wait, on the frame, and one
    /// message less each way). A refusal, a revocation, a held-up notice
    /// and a tick of an asynchronous world (whose frames come whatever
    /// ticks) are still answered.
    pub const BY_FRAME: u32 = 2;

    /// A request of `kind` from this process.
    pub fn new(kind: TickRequestKind, node_name: &str) -> Self {
        Self {
            protocol_version: PROTOCOL_VERSION,
            kind: kind as u32,
            pid: crate::wire::this_process_id(),
            flags: 0,
            settings: WorldSettings::default().into(),
            node_name: FixedText::new(node_name),
        }
    }
}

/// The server's answer on the tick service.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::TickResponse/3")]
pub struct TickResponse {
    /// [`PROTOCOL_VERSION`] of the server.
    pub protocol_version: u32,
    /// [`ResponseStatus`] as `u32`.
    pub status: u32,
    /// For a tick: the frame computed and published. Otherwise the current frame.
    pub frame: u64,
    /// Simulation time of `frame`, in nanoseconds.
    pub elapsed_ns: u64,
    /// For settings: the first frame computed with them.
    pub effective_frame: u64,
    /// With [`ResponseStatus::InvalidSettings`]: why the settings were
    /// refused (see [`TickResponse::settings_error`]).
    pub settings_error: WireSettingsError,
    /// The ticker after the request.
    pub ticker: TickerInfo,
    /// With [`ResponseStatus::WaitingForParticipants`]: the participant the
    /// tick waits for (`since_frame`: the frame it has not reported done).
    pub waiting_for: TickerInfo,
    /// With [`ResponseStatus::WaitingForParticipants`]: how long the server
    /// waits for a participant before it drops it, in nanoseconds.
    pub lockstep_timeout_ns: u64,
    /// With [`ResponseStatus::Revoked`]: the client that left synchronous
    /// mode (`since_frame`: the frame at which it did).
    pub revoked_by: TickerInfo,
}

crate::wire::responses!(TickResponse);

impl TickResponse {
    /// A response with `status` about `frame`.
    pub fn new(status: ResponseStatus, frame: u64, elapsed_ns: u64, ticker: TickerInfo) -> Self {
        Self {
            protocol_version: PROTOCOL_VERSION,
            status: status as u32,
            frame,
            elapsed_ns,
            effective_frame: 0,
            settings_error: WireSettingsError::NONE,
            ticker,
            waiting_for: TickerInfo::none(),
            lockstep_timeout_ns: 0,
            revoked_by: TickerInfo::none(),
        }
    }

    /// Adds a settings error to a [`ResponseStatus::InvalidSettings`] response.
    pub fn with_settings_error(mut self, error: &SettingsError) -> Self {
        self.settings_error = error.into();
        self
    }

    /// The settings error of an [`ResponseStatus::InvalidSettings`] response.
    pub fn settings_error(&self) -> Option<SettingsError> {
        self.settings_error.error()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn response_layout_is_fixed() {
        // Same bytes as TickResponse/2 (three error fields at offset 32).
        assert_eq!(std::mem::size_of::<TickResponse>(), 336);
        assert_eq!(std::mem::offset_of!(TickResponse, settings_error), 32);
        assert_eq!(std::mem::offset_of!(TickResponse, ticker), 64);
    }

    #[test]
    fn responses_carry_settings_errors() {
        let ok = TickResponse::new(ResponseStatus::Ok, 7, 0, TickerInfo::none());
        assert_eq!(ok.settings_error(), None);
        let error = SettingsError::SubstepRule {
            fixed: 0.5,
            max_dt: 0.01,
            max_substeps: 10,
        };
        let refused = TickResponse::new(ResponseStatus::InvalidSettings, 7, 0, TickerInfo::none())
            .with_settings_error(&error);
        assert_eq!(refused.settings_error(), Some(error));
        assert_eq!(refused.frame, 7);
    }
}
