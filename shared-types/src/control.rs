//! The control service: requests from clients, responses from the server.

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

use crate::settings::{SettingsError, WorldSettings};
use crate::settings_wire::{WireSettings, WireSettingsError};
use crate::tick::TickerInfo;
use crate::wire::{wire_enum, FixedText, ResponseStatus, PROTOCOL_VERSION};

wire_enum! {
    /// What a [`ControlRequest`] asks for.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum RequestKind {
        /// Handshake on connect: checks the protocol version, returns the status.
        Hello = 1,
        /// Returns the status (which holds the settings).
        GetSettings = 2,
        /// Applies `settings`; returns the frame from which they hold.
        ApplySettings = 3,
        /// Returns the status.
        Status = 4,
        /// Loads `scene` as a new episode (settings kept unless
        /// [`ControlRequest::RESET_SETTINGS`]).
        LoadWorld = 5,
        /// Restores the current scene's initial state as a new episode.
        ReloadWorld = 6,
        /// Saves the whole world in the server's memory; the answer's
        /// [`ControlResponse::snapshot`] is its id.
        SaveSnapshot = 7,
        /// Restores snapshot [`ControlRequest::snapshot`] as a new episode.
        RestoreSnapshot = 8,
        /// Lists the snapshots ([`ControlResponse::snapshots`]).
        ListSnapshots = 9,
        /// Forgets snapshot [`ControlRequest::snapshot`].
        DropSnapshot = 10,
    }
}

/// A request to the world's server.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::ControlRequest/3")]
pub struct ControlRequest {
    /// [`PROTOCOL_VERSION`] of the sender.
    pub protocol_version: u32,
    /// [`RequestKind`] as `u32`.
    pub kind: u32,
    /// Process id of the sender, for the server's log.
    pub client_pid: u32,
    /// [`ControlRequest::RESET_SETTINGS`] and future flags.
    pub flags: u32,
    /// The settings to apply (for [`RequestKind::ApplySettings`]).
    pub settings: WireSettings,
    /// The scene to load (for [`RequestKind::LoadWorld`]).
    pub scene: FixedText,
    /// The sender's name (its executable), for logs and for telling a
    /// ticker who ended synchronous mode.
    pub client_name: FixedText,
    /// The snapshot to restore or drop.
    pub snapshot: u64,
}

impl ControlRequest {
    /// A request of `kind` from this process.
    pub fn new(kind: RequestKind) -> Self {
        Self {
            protocol_version: PROTOCOL_VERSION,
            kind: kind as u32,
            client_pid: crate::wire::this_process_id(),
            flags: 0,
            settings: WorldSettings::default().into(),
            scene: FixedText::new(""),
            client_name: FixedText::new(""),
            snapshot: 0,
        }
    }

    /// A request of `kind` about snapshot `id`.
    pub fn snapshot(kind: RequestKind, id: u64) -> Self {
        Self {
            snapshot: id,
            ..Self::new(kind)
        }
    }

    /// Flag for load and reload: reset the settings to the defaults.
    pub const RESET_SETTINGS: u32 = 1;

    /// A request to load `scene` (`None`: reload the current one).
    pub fn load_world(scene: Option<&str>, reset_settings: bool) -> Self {
        let kind = if scene.is_some() {
            RequestKind::LoadWorld
        } else {
            RequestKind::ReloadWorld
        };
        Self {
            flags: if reset_settings {
                Self::RESET_SETTINGS
            } else {
                0
            },
            scene: FixedText::new(scene.unwrap_or("")),
            ..Self::new(kind)
        }
    }

    /// A request to apply `settings`.
    pub fn apply_settings(settings: WorldSettings) -> Self {
        Self {
            settings: settings.into(),
            ..Self::new(RequestKind::ApplySettings)
        }
    }
}

/// Lockstep participants a [`StatusReport`] describes one by one (the
/// count covers them all).
pub const REPORTED_PARTICIPANTS: usize = 8;

/// One lockstep participant in a [`StatusReport`].
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::ParticipantStatus/2")]
pub struct ParticipantStatus {
    /// Its process (the joining port's).
    pub pid: u32,
    /// Its window: how many frames the world may run ahead of its last
    /// "done" (0: none, every frame waits for it).
    pub window: u32,
    /// The last frame it reported done.
    pub done_frame: u64,
    /// How many frames the world is ahead of its last "done" (the latest
    /// published frame minus `done_frame`); [`ParticipantStatus::NOT_YET`]
    /// before its first report in this episode.
    pub lag: u64,
    /// How long after that frame's publication its "done" came: how long it
    /// made that frame's step wait at most. [`ParticipantStatus::NOT_YET`]
    /// before its first report (or when the report was for an older frame).
    pub done_after_ns: u64,
    /// Its name.
    pub name: FixedText,
}

impl ParticipantStatus {
    /// `done_after_ns` before a "done" for the current frame came, and
    /// `lag` before any "done" came.
    pub const NOT_YET: u64 = u64::MAX;

    /// How many frames the world is ahead of its last "done", if it
    /// reported one in this episode.
    pub fn lag(&self) -> Option<u64> {
        (self.lag != Self::NOT_YET).then_some(self.lag)
    }

    /// How long it made its last frame wait, if it reported one.
    pub fn done_after(&self) -> Option<std::time::Duration> {
        (self.done_after_ns != Self::NOT_YET)
            .then(|| std::time::Duration::from_nanos(self.done_after_ns))
    }
}

/// The world's state as the server reports it.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::StatusReport/5")]
pub struct StatusReport {
    /// The latest published frame.
    pub frame: u64,
    /// Its simulation time in nanoseconds.
    pub elapsed_ns: u64,
    /// The current episode.
    pub episode: u64,
    /// The server's process id.
    pub server_pid: u32,
    /// Actors in the world.
    pub actor_count: u32,
    /// The settings in force for the next frame.
    pub settings: WireSettings,
    /// The scene the world was loaded from.
    pub scene: FixedText,
    /// Who holds tick ownership.
    pub ticker: TickerInfo,
    /// The seed the scene was built with (0: none).
    pub seed: u64,
    /// Lockstep participants the server waits for in synchronous mode.
    pub participants: u32,
    /// Clients of each kind the world admits (`--max-clients`).
    pub max_clients: u32,
    /// Readers each sensor admits (`--max-sensor-readers`).
    pub max_sensor_readers: u32,
    /// The journal: [`StatusReport::NO_JOURNAL`], [`StatusReport::JOURNALING`]
    /// or [`StatusReport::JOURNAL_STOPPED`] (`journal_note` says why).
    pub journal: u32,
    /// The last frame the journal made durable.
    pub journal_durable_frame: u64,
    /// The journal's directory, or why it stopped.
    pub journal_note: FixedText,
    /// Snapshots held in the server's memory.
    pub snapshots: u32,
    /// The run this server continues: the process id of the server that
    /// began it, its own unless it resumed a journal (`sim-server
    /// --resume DIR`: the pid the journal names). A client that follows a
    /// restart keys what it built on the world by it (the CARLA gateway's
    /// episode ids); zero from a server that does not say.
    pub run_pid: u32,
    /// The first [`REPORTED_PARTICIPANTS`] participants in joining order
    /// (`participants` says how many of these are filled, at most all).
    pub lockstep: [ParticipantStatus; REPORTED_PARTICIPANTS],
}

impl StatusReport {
    /// [`StatusReport::journal`]: the server keeps no journal.
    pub const NO_JOURNAL: u32 = 0;
    /// [`StatusReport::journal`]: the journal is being written.
    pub const JOURNALING: u32 = 1;
    /// [`StatusReport::journal`]: the journal stopped (the disk is full,
    /// the file cannot be written); the world runs on.
    pub const JOURNAL_STOPPED: u32 = 2;
}

/// Snapshots a server keeps in memory at most.
pub const MAX_SNAPSHOTS: usize = 16;

/// One snapshot a server holds.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::SnapshotInfo/1")]
pub struct SnapshotInfo {
    /// Its id (from 1, never reused within a server's life).
    pub id: u64,
    /// The frame it was saved at.
    pub frame: u64,
    /// The frame's id in its own line (the same unless the world was
    /// itself restored from a snapshot since its episode began).
    pub source_frame: u64,
    /// The episode it was saved in.
    pub episode: u64,
    /// The simulation time it was saved at.
    pub elapsed_ns: u64,
    /// Its actors.
    pub actors: u32,
    /// Its sensors.
    pub sensors: u32,
}

/// The snapshots a [`ControlResponse`] lists.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Eq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::SnapshotList/1")]
pub struct SnapshotList {
    /// How many of `items` are filled.
    pub count: u32,
    /// Zero.
    pub reserved: u32,
    /// The snapshots, oldest first.
    pub items: [SnapshotInfo; MAX_SNAPSHOTS],
}

impl SnapshotList {
    /// The filled items (a count from another process is bounded).
    pub fn as_slice(&self) -> &[SnapshotInfo] {
        &self.items[..(self.count as usize).min(MAX_SNAPSHOTS)]
    }
}

/// The server's answer to one [`ControlRequest`].
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::ControlResponse/5")]
pub struct ControlResponse {
    /// [`PROTOCOL_VERSION`] of the server.
    pub protocol_version: u32,
    /// [`ResponseStatus`] as `u32`.
    pub status: u32,
    /// For [`RequestKind::ApplySettings`]: the first frame computed with the
    /// new settings.
    pub effective_frame: u64,
    /// With [`ResponseStatus::InvalidSettings`]: why the settings were
    /// refused (see [`ControlResponse::settings_error`]).
    pub settings_error: WireSettingsError,
    /// The world's state after the request.
    pub report: StatusReport,
    /// The snapshot saved or restored (its id), 0 otherwise.
    pub snapshot: u64,
    /// For [`RequestKind::ListSnapshots`]: the snapshots.
    pub snapshots: SnapshotList,
}

crate::wire::responses!(ControlResponse);

impl ControlResponse {
    /// A successful response carrying `report`.
    pub fn ok(report: StatusReport) -> Self {
        Self {
            protocol_version: PROTOCOL_VERSION,
            status: ResponseStatus::Ok as u32,
            effective_frame: 0,
            settings_error: WireSettingsError::NONE,
            report,
            snapshot: 0,
            snapshots: SnapshotList::zeroed(),
        }
    }

    /// A response with `status` and nothing done.
    pub fn refused(status: ResponseStatus, report: StatusReport) -> Self {
        Self {
            status: status as u32,
            ..Self::ok(report)
        }
    }

    /// A response refusing settings with `error`.
    pub fn invalid_settings(error: &SettingsError, report: StatusReport) -> Self {
        Self {
            settings_error: error.into(),
            ..Self::refused(ResponseStatus::InvalidSettings, report)
        }
    }

    /// The settings error carried by an [`ResponseStatus::InvalidSettings`] response.
    pub fn settings_error(&self) -> Option<SettingsError> {
        self.settings_error.error()
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn fixed_text_cuts_at_char_boundaries() {
        assert_eq!(FixedText::new("boxes:10").to_string_lossy(), "boxes:10");
        let long = "é".repeat(40); // 80 bytes
        let cut = FixedText::new(&long).to_string_lossy();
        assert_eq!(cut, "é".repeat(32));
        let garbage = FixedText {
            len: 1000,
            reserved: 0,
            bytes: [0xff; 64],
        };
        assert_eq!(garbage.to_string_lossy().chars().count(), 64);
    }

    #[test]
    fn response_layout_is_fixed() {
        // The error fields at offset 16 as in ControlResponse/1; /3 adds the
        // eight participant statuses at the report's end (104 bytes each
        // since /4: their window and lag).
        assert_eq!(std::mem::size_of::<ParticipantStatus>(), 104);
        // /5: the journal's state and the snapshots.
        assert_eq!(
            std::mem::size_of::<ControlResponse>(),
            288 + 8 * 104 + 88 + 8 + 8 + 16 * 48
        );
        assert_eq!(std::mem::offset_of!(ControlResponse, settings_error), 16);
        assert_eq!(std::mem::offset_of!(ControlResponse, report), 48);
        assert_eq!(std::mem::offset_of!(StatusReport, lockstep), 328);
    }

    #[test]
    fn responses_carry_settings_errors() {
        let report = StatusReport::zeroed();
        assert_eq!(ControlResponse::ok(report).settings_error(), None);
        let error = SettingsError::MaxSubstepsOutOfRange { value: 17, max: 16 };
        let refused = ControlResponse::invalid_settings(&error, report);
        assert_eq!(refused.status, ResponseStatus::InvalidSettings as u32);
        assert_eq!(refused.settings_error(), Some(error));
    }
}
