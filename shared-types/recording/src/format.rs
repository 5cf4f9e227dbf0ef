//! The recording file's format: its channels (topics and schemas), the
//! layouts of what they carry, the header, and why a file cannot be read.

use bytemuck::{Pod, Zeroable};
use serde::{Deserialize, Serialize};

use shared_types::{
    Command, CommandResult, SensorSpec, SubstepRule, WireSettings, WorldSettings,
    LEGACY_SENSOR_PARAMS, SENSOR_PARAMS,
};

use crate::json_f64;

/// The version of the recording format as a whole (the header's layout and
/// the set of channels a replay needs).
pub const RECORDING_VERSION: u32 = 1;

/// MCAP profile name of simbus recordings.
pub const PROFILE: &str = "simbus";
/// Message encoding of the wire-layout channels.
pub const WIRE_ENCODING: &str = "simbus-wire";

/// Topic of the header message.
pub const HEADER_TOPIC: &str = "/simbus/header";
/// Topic of the frames.
pub const FRAMES_TOPIC: &str = "/simbus/frames";
/// Topic of the applied commands.
pub const COMMANDS_TOPIC: &str = "/simbus/commands";
/// Topic of the events.
pub const EVENTS_TOPIC: &str = "/simbus/events";
/// Topic of the collisions.
pub const COLLISIONS_TOPIC: &str = "/simbus/collisions";
/// Topic of the sensor spawns.
pub const SENSORS_TOPIC: &str = "/simbus/sensors";
/// Topic prefix of each sensor's captures (`/simbus/sensor/{id}`).
pub const SENSOR_TOPIC_PREFIX: &str = "/simbus/sensor/";
/// Topic of the keyframes.
pub const KEYFRAMES_TOPIC: &str = "/simbus/keyframes";
/// Topic of the Foxglove scene.
pub const SCENE_TOPIC: &str = "/foxglove/scene";

/// Schema of [`HEADER_TOPIC`].
pub const HEADER_SCHEMA: &str = "simbus::RecordingHeader/1";
/// Schema of [`FRAMES_TOPIC`]: the frame header's own type name.
pub const FRAME_SCHEMA: &str = "simbus::FrameHeader/3";
/// The frame schema of recordings made before the header had its
/// `recorded_frame` fields: read with those fields zero.
pub const LEGACY_FRAME_SCHEMA: &str = "simbus::FrameHeader/2";
/// The size of a [`LEGACY_FRAME_SCHEMA`] frame header, in bytes.
pub const LEGACY_FRAME_HEADER_BYTES: usize = 96;
/// Schema of [`COMMANDS_TOPIC`].
pub const COMMAND_SCHEMA: &str = "simbus::RecordedCommand/1";
/// Schema of [`EVENTS_TOPIC`].
pub const EVENT_SCHEMA: &str = "simbus::RecordedEvent/1";
/// Schema of [`COLLISIONS_TOPIC`].
pub const COLLISION_SCHEMA: &str = "simbus::RecordedCollision/1";
/// Schema of [`SENSORS_TOPIC`].
pub const SENSOR_SPAWN_SCHEMA: &str = "simbus::RecordedSensor/2";
/// The sensor schema of recordings made before a spec carried
/// [`shared_types::SENSOR_PARAMS`] parameters (protocol 3: eight): read
/// with the later parameters zero.
pub const LEGACY_SENSOR_SPAWN_SCHEMA: &str = "simbus::RecordedSensor/1";
/// The size of a [`LEGACY_SENSOR_SPAWN_SCHEMA`] sensor, in bytes.
pub const LEGACY_SENSOR_SPAWN_BYTES: usize =
    std::mem::size_of::<RecordedSensor>() - 4 * (SENSOR_PARAMS - LEGACY_SENSOR_PARAMS);
/// Schema of each sensor's captures: the capture header's own type name.
pub const CAPTURE_SCHEMA: &str = "simbus::SensorHeader/2";
/// Schema of [`KEYFRAMES_TOPIC`].
pub const KEYFRAME_SCHEMA: &str = "simbus::Keyframe/2";
/// Schema of [`KEYFRAMES_TOPIC`] before layout 2 (msgpack): read, and its
/// keyframes refused by their layout version when restored.
pub const LEGACY_KEYFRAME_SCHEMA: &str = "simbus::Keyframe/1";
/// Schema of [`SCENE_TOPIC`] (Foxglove's).
pub const SCENE_SCHEMA: &str = "foxglove.SceneUpdate";

/// Every simbus schema this version writes, for the version check.
pub const SCHEMAS: [&str; 9] = [
    HEADER_SCHEMA,
    FRAME_SCHEMA,
    COMMAND_SCHEMA,
    EVENT_SCHEMA,
    COLLISION_SCHEMA,
    SENSOR_SPAWN_SCHEMA,
    CAPTURE_SCHEMA,
    KEYFRAME_SCHEMA,
    SCENE_SCHEMA,
];

/// The keyframe interval's default and bounds (defined with the recorder
/// service, whose `--keyframe-seconds` input they check).
pub use shared_types::{DEFAULT_KEYFRAME_SECONDS, MAX_KEYFRAME_SECONDS, MIN_KEYFRAME_SECONDS};

/// The first message of a recording (also written as MCAP metadata `simbus`).
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
pub struct RecordingHeader {
    /// [`RECORDING_VERSION`] of the writer.
    pub recording_version: u32,
    /// The simbus version that wrote it (`CARGO_PKG_VERSION`).
    pub simbus_version: String,
    /// [`shared_types::PROTOCOL_VERSION`] of the writer.
    pub protocol_version: u32,
    /// The world name.
    pub world: String,
    /// The scene of the episode the recording started in.
    pub scene: String,
    /// The seed the scene was built with.
    pub seed: u64,
    /// The settings in force when the recording started.
    pub settings: RecordedSettings,
    /// The frame the recording starts at.
    pub start_frame: u64,
    /// Its simulation time, nanoseconds.
    pub start_elapsed_ns: u64,
    /// Its episode.
    pub episode: u64,
    /// Wall-clock seconds since the Unix epoch at the start.
    #[serde(with = "json_f64")]
    pub start_platform_timestamp: f64,
    /// Whether sensor captures are recorded.
    pub sensors: bool,
    /// Simulation seconds between keyframes.
    #[serde(with = "json_f64")]
    pub keyframe_seconds: f64,
    /// A journal's segment: how many frames at most lie between two syncs
    /// (`--journal-sync frames:N`), so a resume can say what a crash may
    /// have lost. 0: a recording, not a journal.
    #[serde(default)]
    pub journal_sync_frames: u64,
    /// The process id of the server that began the run this recording is
    /// part of: a journal resumed (`--resume DIR`) goes on under it, so
    /// clients that follow the restart see the same run. 0: not known
    /// (written before it was recorded).
    #[serde(default)]
    pub run_pid: u32,
}

/// [`WorldSettings`] as JSON.
#[derive(Debug, Clone, Copy, PartialEq, Serialize, Deserialize)]
pub struct RecordedSettings {
    /// See [`WorldSettings::synchronous_mode`].
    pub synchronous_mode: bool,
    /// See [`WorldSettings::fixed_delta_seconds`]; absent reads as `None`
    /// (variable step), as a plain `Option` would.
    #[serde(default, with = "json_f64::option")]
    pub fixed_delta_seconds: Option<f64>,
    /// See [`WorldSettings::substepping`].
    pub substepping: bool,
    /// See [`WorldSettings::max_substep_delta_time`].
    #[serde(with = "json_f64")]
    pub max_substep_delta_time: f64,
    /// See [`WorldSettings::max_substeps`].
    pub max_substeps: u32,
    /// See [`WorldSettings::substep_rule`]; absent (a recording made before
    /// the rule existed) reads as `refuse`, the only behaviour then.
    #[serde(default)]
    pub substep_rule: SubstepRule,
}

impl From<WorldSettings> for RecordedSettings {
    fn from(s: WorldSettings) -> Self {
        Self {
            synchronous_mode: s.synchronous_mode,
            fixed_delta_seconds: s.fixed_delta_seconds,
            substepping: s.substepping,
            max_substep_delta_time: s.max_substep_delta_time,
            max_substeps: s.max_substeps,
            substep_rule: s.substep_rule,
        }
    }
}

impl From<RecordedSettings> for WorldSettings {
    fn from(s: RecordedSettings) -> Self {
        Self {
            synchronous_mode: s.synchronous_mode,
            fixed_delta_seconds: s.fixed_delta_seconds,
            substepping: s.substepping,
            max_substep_delta_time: s.max_substep_delta_time,
            max_substeps: s.max_substeps,
            substep_rule: s.substep_rule,
        }
    }
}

impl From<WireSettings> for RecordedSettings {
    fn from(s: WireSettings) -> Self {
        WorldSettings::from(s).into()
    }
}

/// A command the server applied: before computing `frame` of `episode`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct RecordedCommand {
    /// The frame the command applied before (the next frame when it arrived).
    pub frame: u64,
    /// Its episode.
    pub episode: u64,
    /// The command as sent.
    pub command: Command,
    /// What it did.
    pub result: CommandResult,
}

/// Two actors started touching during `frame`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct RecordedCollision {
    /// The frame in which the contact started.
    pub frame: u64,
    /// Its simulation time, nanoseconds.
    pub elapsed_ns: u64,
    /// One actor (the lower id).
    pub actor_a: u64,
    /// The other.
    pub actor_b: u64,
    /// The contact's total normal impulse at the end of the step, N·s.
    pub impulse: f32,
    /// [`shared_types::ActorKind`] of `actor_a` as `u32`.
    pub kind_a: u32,
    /// [`shared_types::ActorKind`] of `actor_b` as `u32`.
    pub kind_b: u32,
    /// Zero.
    pub reserved: u32,
}

/// A sensor spawned at `frame` with `spec`; its captures are on
/// `/simbus/sensor/{id}`.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable)]
pub struct RecordedSensor {
    /// The frame at which it was spawned.
    pub frame: u64,
    /// The sensor's id.
    pub id: u64,
    /// What it is and where it rides.
    pub spec: SensorSpec,
}

/// Something that changed the world other than a command.
#[derive(Debug, Clone, PartialEq, Serialize, Deserialize)]
#[serde(tag = "event", rename_all = "snake_case")]
pub enum RecordedEvent {
    /// The settings changed; they hold from `frame` on.
    Settings {
        /// The first frame computed with them.
        frame: u64,
        /// The new settings.
        settings: RecordedSettings,
    },
    /// A new episode began (load or reload) at its frame 0.
    Episode {
        /// The new episode.
        episode: u64,
        /// Its scene.
        scene: String,
        /// Its first actor id.
        first_actor_id: u64,
        /// Whether the settings were reset to the defaults.
        reset_settings: bool,
    },
    /// A sensor was destroyed (or ended with its parent or episode).
    SensorEnded {
        /// The last frame it saw.
        frame: u64,
        /// The sensor.
        id: u64,
    },
    /// The recorder was stopped: the last message of a cleanly closed file.
    Stopped {
        /// The last frame recorded.
        frame: u64,
        /// Why (`stop`, `signal`, `load`).
        reason: String,
    },
}

/// Why a recording cannot be read.
#[derive(Debug, thiserror::Error)]
pub enum RecordingError {
    /// The file cannot be opened or read.
    // `error` is in the message and deliberately not the `source()`: a
    // chain printer (`{:#}`) would say it twice.
    #[error("cannot read {path}: {error}")]
    Io {
        /// The file.
        path: String,
        /// Why.
        error: std::io::Error,
    },
    /// The path is a directory.
    #[error("{path} is a directory, not a recording")]
    Directory {
        /// The path.
        path: String,
    },
    /// Not an MCAP file: empty, text, or bytes that do not begin with
    /// MCAP's magic.
    #[error("{path} is not an MCAP file: {found}")]
    NotMcap {
        /// The file.
        path: String,
        /// What it holds instead.
        found: NotMcap,
    },
    /// A chunk's CRC does not match, or a record is broken: the file is damaged.
    #[error("{path} is damaged: {error}")]
    Corrupt {
        /// The file.
        path: String,
        /// What the MCAP reader said.
        error: mcap::McapError,
    },
    /// An MCAP file that ends before its first complete chunk: it is still
    /// being recorded (a chunk is written once 1 MiB is gathered), or it
    /// was never closed (its server was killed right after it started
    /// recording, or the copy is cut short).
    #[error("{path} is still being recorded, or was not closed (its server was killed or the copy is cut short): it ends before its first complete chunk, so nothing in it can be read yet")]
    Truncated {
        /// The file.
        path: String,
    },
    /// An MCAP file, but not a simbus recording (another program's).
    #[error("{path} is an MCAP file but not a simbus recording (no {HEADER_TOPIC} header first)")]
    NotSimbus {
        /// The file.
        path: String,
    },
    /// A simbus schema of a newer version than this build reads.
    #[error("{path} was recorded with schema {found}; this simbus reads {known} (upgrade simbus to read it)")]
    FutureSchema {
        /// The file.
        path: String,
        /// The schema in the file.
        found: String,
        /// The version this build knows.
        known: &'static str,
    },
    /// A message does not have the layout its schema says.
    #[error("{path}: a {topic} message is malformed: {reason}")]
    Malformed {
        /// The file.
        path: String,
        /// The channel.
        topic: String,
        /// What is wrong.
        reason: String,
    },
}

impl RecordingError {
    /// A short machine-readable name of the error, for `--json`.
    pub fn code(&self) -> &'static str {
        match self {
            Self::Io { .. } => "io",
            Self::Directory { .. } => "directory",
            Self::NotMcap { .. } => "not_mcap",
            Self::Corrupt { .. } => "corrupt",
            Self::Truncated { .. } => "truncated",
            Self::NotSimbus { .. } => "not_simbus",
            Self::FutureSchema { .. } => "future_schema",
            Self::Malformed { .. } => "malformed",
        }
    }
}

/// What a file that is not MCAP holds instead ([`RecordingError::NotMcap`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum NotMcap {
    /// Nothing: the file is empty.
    Empty,
    /// Text (its first bytes are printable UTF-8).
    Text,
    /// Other bytes, not MCAP's magic.
    OtherBytes,
}

impl std::fmt::Display for NotMcap {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.write_str(match self {
            Self::Empty => "it is empty",
            Self::Text => "it holds text",
            Self::OtherBytes => "it does not begin with MCAP's magic bytes",
        })
    }
}

/// Checks a schema name against the versions this build knows.
///
/// `Ok(true)` for one of [`SCHEMAS`], `Ok(false)` for a schema this build
/// does not know at all (a later version's new channel, skipped), an error
/// for a known schema of a newer version.
///
/// # Errors
///
/// Returns `Err(known)`, the schema name this build knows (of an older
/// version), if `name` is a newer version of one of the [`SCHEMAS`] (same name
/// before the `/`, higher version after it, or no readable version).
pub fn check_schema(name: &str) -> Result<bool, &'static str> {
    let legacy = [
        LEGACY_FRAME_SCHEMA,
        LEGACY_SENSOR_SPAWN_SCHEMA,
        LEGACY_KEYFRAME_SCHEMA,
    ];
    if SCHEMAS.contains(&name) || legacy.contains(&name) {
        return Ok(true);
    }
    let (base, version) = match name.rsplit_once('/') {
        Some((base, v)) => (base, v.parse::<u32>().ok()),
        None => (name, None),
    };
    for known in SCHEMAS {
        if let Some((known_base, known_version)) = known.rsplit_once('/') {
            if known_base == base {
                let known_version: u32 = known_version.parse().unwrap_or(0);
                return match version {
                    Some(v) if v < known_version => Ok(false),
                    _ => Err(known),
                };
            }
        }
    }
    Ok(false)
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn newer_schemas_are_refused_and_unknown_ones_skipped() {
        assert_eq!(check_schema(FRAME_SCHEMA), Ok(true));
        assert_eq!(check_schema("simbus::FrameHeader/4"), Err(FRAME_SCHEMA));
        assert_eq!(check_schema(LEGACY_FRAME_SCHEMA), Ok(true));
        assert_eq!(check_schema("simbus::Weather/1"), Ok(false));
        assert_eq!(check_schema("simbus::FrameHeader/1"), Ok(false));
        assert_eq!(check_schema(LEGACY_SENSOR_SPAWN_SCHEMA), Ok(true));
        assert_eq!(
            check_schema("simbus::RecordedSensor/3"),
            Err(SENSOR_SPAWN_SCHEMA)
        );
        assert_eq!(LEGACY_SENSOR_SPAWN_BYTES, 104);
    }

    #[test]
    fn the_substep_rule_is_recorded_by_name_and_defaults_to_refuse() {
        let clamp = WorldSettings {
            fixed_delta_seconds: Some(0.2),
            substep_rule: SubstepRule::Clamp,
            ..WorldSettings::default()
        };
        let json = serde_json::to_string(&RecordedSettings::from(clamp)).unwrap();
        assert!(json.contains("\"substep_rule\":\"clamp\""), "{json}");
        let back: RecordedSettings = serde_json::from_str(&json).unwrap();
        assert_eq!(WorldSettings::from(back), clamp);
        // A header written before the rule existed reads as refuse.
        let old = json.replace(",\"substep_rule\":\"clamp\"", "");
        let back: RecordedSettings = serde_json::from_str(&old).unwrap();
        assert_eq!(back.substep_rule, SubstepRule::Refuse);
        // A rule this version does not know is an error, not a guess.
        let unknown = json.replace("\"clamp\"", "\"bend\"");
        assert!(serde_json::from_str::<RecordedSettings>(&unknown).is_err());
    }

    #[test]
    fn recorded_layouts_have_fixed_sizes() {
        assert_eq!(std::mem::size_of::<RecordedCollision>(), 48);
        assert_eq!(
            std::mem::size_of::<RecordedCommand>(),
            16 + std::mem::size_of::<Command>() + std::mem::size_of::<CommandResult>()
        );
    }
}
