//! The tick service: the one channel through which the ticker claims
//! ownership, enters and leaves synchronous mode, and ticks. The service
//! admits a single client, so a second would-be ticker cannot even send.

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

use crate::{
    FixedText, ResponseStatus, SettingsError, WireSettings, WorldSettings, PROTOCOL_VERSION,
};

/// What a [`TickRequest`] asks for.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u32)]
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
}

impl TickRequestKind {
    /// The kind with wire value `value`, if this version knows it.
    pub fn from_u32(value: u32) -> Option<Self> {
        Some(match value {
            1 => Self::Claim,
            2 => Self::Release,
            3 => Self::Tick,
            4 => Self::ApplySettings,
            _ => return None,
        })
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
    /// Process id of the ticker.
    pub pid: u32,
    /// Zero.
    pub reserved: u32,
    /// Settings for [`TickRequestKind::ApplySettings`].
    pub settings: WireSettings,
    /// The ticker's node name, for [`TickRequestKind::Claim`].
    pub node_name: FixedText,
}

impl TickRequest {
    /// A request of `kind` from this process.
    pub fn new(kind: TickRequestKind, node_name: &str) -> Self {
        Self {
            protocol_version: PROTOCOL_VERSION,
            kind: kind as u32,
            pid: std::process::id(),
            reserved: 0,
            settings: WorldSettings::default().into(),
            node_name: FixedText::new(node_name),
        }
    }
}

/// The server's answer on the tick service.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::TickResponse/2")]
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
    /// With [`ResponseStatus::InvalidSettings`]: see [`SettingsError::to_wire`].
    pub error_code: u32,
    /// The field the error names.
    pub error_field: u32,
    /// The values the error names.
    pub error_values: [f64; 3],
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

impl TickResponse {
    /// A response with `status` about `frame`.
    pub fn new(status: ResponseStatus, frame: u64, elapsed_ns: u64, ticker: TickerInfo) -> Self {
        Self {
            protocol_version: PROTOCOL_VERSION,
            status: status as u32,
            frame,
            elapsed_ns,
            effective_frame: 0,
            error_code: 0,
            error_field: 0,
            error_values: [0.0; 3],
            ticker,
            waiting_for: TickerInfo::none(),
            lockstep_timeout_ns: 0,
            revoked_by: TickerInfo::none(),
        }
    }

    /// Adds a settings error to a [`ResponseStatus::InvalidSettings`] response.
    pub fn with_settings_error(mut self, error: &SettingsError) -> Self {
        (self.error_code, self.error_field, self.error_values) = error.to_wire();
        self
    }

    /// The settings error of an [`ResponseStatus::InvalidSettings`] response.
    pub fn settings_error(&self) -> Option<SettingsError> {
        SettingsError::from_wire(self.error_code, self.error_field, self.error_values)
    }
}
