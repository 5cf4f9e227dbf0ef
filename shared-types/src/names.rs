//! World names and the iceoryx2 service names derived from them.

use std::fmt;

use crate::wire::wire_enum;

/// The name of one simulated world. Every service of a world is prefixed with
/// it, so two servers (or two test runs) on one machine never meet.
///
/// A name is 1 to 64 characters of ASCII letters, digits, `-`, `_` and `.`.
#[derive(Debug, Clone, PartialEq, Eq, Hash)]
pub struct WorldName(String);

/// Why a string is not a valid [`WorldName`].
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
pub enum WorldNameError {
    /// The name is empty.
    #[error("world name is empty")]
    Empty,
    /// The name is longer than [`WorldName::MAX_LEN`].
    #[error("world name '{name}' is {len} characters long; at most {max} are allowed")]
    TooLong {
        /// The rejected name.
        name: String,
        /// Its length.
        len: usize,
        /// The limit.
        max: usize,
    },
    /// The name holds a character outside `[A-Za-z0-9._-]`.
    #[error("world name '{name}' contains '{character}'; use ASCII letters (a-z, A-Z), digits, '-', '_' and '.'")]
    InvalidCharacter {
        /// The rejected name.
        name: String,
        /// The first offending character.
        character: char,
    },
}

impl WorldName {
    /// The longest world name accepted.
    pub const MAX_LEN: usize = 64;

    /// Checks `name` and wraps it.
    ///
    /// # Errors
    ///
    /// Returns [`WorldNameError::Empty`] for an empty name,
    /// [`WorldNameError::TooLong`] for one longer than [`WorldName::MAX_LEN`]
    /// bytes, and [`WorldNameError::InvalidCharacter`] (naming the first
    /// offending character) for one holding a character outside
    /// `[A-Za-z0-9._-]`.
    pub fn new(name: &str) -> Result<Self, WorldNameError> {
        if name.is_empty() {
            return Err(WorldNameError::Empty);
        }
        if name.len() > Self::MAX_LEN {
            return Err(WorldNameError::TooLong {
                name: name.to_owned(),
                len: name.len(),
                max: Self::MAX_LEN,
            });
        }
        if let Some(character) = name
            .chars()
            .find(|c| !(c.is_ascii_alphanumeric() || matches!(c, '-' | '_' | '.')))
        {
            return Err(WorldNameError::InvalidCharacter {
                name: name.to_owned(),
                character,
            });
        }
        Ok(Self(name.to_owned()))
    }

    /// The name as a string.
    pub fn as_str(&self) -> &str {
        &self.0
    }
}

impl fmt::Display for WorldName {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(&self.0)
    }
}

impl std::str::FromStr for WorldName {
    type Err = WorldNameError;
    fn from_str(s: &str) -> Result<Self, Self::Err> {
        Self::new(s)
    }
}

/// The iceoryx2 service names of one world.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct ServiceNames {
    /// Publish-subscribe: one sample per frame, a [`FrameHeader`](crate::frame::FrameHeader) user
    /// header and a slice of [`ActorState`](crate::frame::ActorState).
    pub frames: String,
    /// Event: the server notifies it after every published frame, so clients
    /// block instead of spinning.
    pub frame_ready: String,
    /// Request-response: [`ControlRequest`](crate::control::ControlRequest) → [`ControlResponse`](crate::control::ControlResponse)
    /// (settings, status).
    pub control: String,
    /// Event: clients notify it after sending a control request, so a server
    /// that is idle (paced, or waiting) answers at once.
    pub control_wake: String,
    /// Request-response admitting one client: [`TickRequest`](crate::tick::TickRequest) →
    /// [`TickResponse`](crate::tick::TickResponse). Holding its client port is tick ownership.
    pub tick: String,
    /// Request-response: a slice of [`Command`](crate::command::Command) with a
    /// [`BatchHeader`](crate::command::BatchHeader) → a slice of [`CommandResult`](crate::command::CommandResult).
    pub batch: String,
    /// Request-response: [`LockstepRequest`](crate::lockstep::LockstepRequest) → [`LockstepResponse`](crate::lockstep::LockstepResponse).
    pub lockstep: String,
    /// Request-response: [`SensorRequest`](crate::sensor::SensorRequest) → a slice of [`SensorInfo`](crate::sensor::SensorInfo).
    pub sensors: String,
    /// Request-response: [`RecorderRequest`](crate::recorder::RecorderRequest) → [`RecorderResponse`](crate::recorder::RecorderResponse)
    /// (recorder and replayer).
    pub recorder: String,
    /// Request-response: [`DebugRequest`](crate::debug_shapes::DebugRequest) → a slice of
    /// [`DebugShape`](crate::debug_shapes::DebugShape) (debug drawing).
    pub debug: String,
    prefix: String,
}

wire_enum! {
    /// The event id a client rings on [`ServiceNames::control_wake`] after
    /// sending a request: which service holds it. A server woken by
    /// [`Doorbell::Tick`] takes the tick without looking at the other
    /// services' ports; [`Doorbell::Any`] (what a notifier that rings no id
    /// sends) makes it look at all of them.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
    pub enum Doorbell {
        /// Some service (or unknown): every service is looked at.
        Any = 0,
        /// [`ServiceNames::control`].
        Control = 1,
        /// [`ServiceNames::tick`].
        Tick = 2,
        /// [`ServiceNames::batch`].
        Batch = 3,
        /// [`ServiceNames::lockstep`].
        Lockstep = 4,
        /// [`ServiceNames::sensors`].
        Sensors = 5,
        /// [`ServiceNames::recorder`].
        Recorder = 6,
        /// [`ServiceNames::debug`].
        Debug = 7,
    }
}

impl Doorbell {
    /// The largest event id rung: the wake-up event's `event_id_max_value`.
    pub const MAX_ID: usize = Doorbell::Debug as usize;

    /// The event id this doorbell rings.
    pub fn event_id(self) -> usize {
        self as usize
    }
}

impl ServiceNames {
    /// The service names of `world`.
    pub fn new(world: &WorldName) -> Self {
        let prefix = format!("simbus/{world}");
        Self {
            frames: format!("{prefix}/frames"),
            frame_ready: format!("{prefix}/frames/ready"),
            control: format!("{prefix}/control"),
            control_wake: format!("{prefix}/control/wake"),
            tick: format!("{prefix}/tick"),
            batch: format!("{prefix}/batch"),
            lockstep: format!("{prefix}/lockstep"),
            sensors: format!("{prefix}/sensors"),
            recorder: format!("{prefix}/recorder"),
            debug: format!("{prefix}/debug"),
            prefix,
        }
    }
}

impl ServiceNames {
    /// What every service name of the world starts with (`simbus/<world>`).
    pub fn prefix(&self) -> &str {
        &self.prefix
    }

    /// Publish-subscribe of sensor `id`: a [`SensorHeader`](crate::sensor::SensorHeader) user
    /// header and a slice of its kind's payload.
    pub fn sensor(&self, id: u64) -> String {
        format!("{}/sensor/{id}", self.prefix)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn valid_names_are_accepted() {
        for name in ["default", "t-1.2_x", &"a".repeat(64)] {
            assert_eq!(WorldName::new(name).unwrap().as_str(), name);
        }
    }

    #[test]
    fn invalid_names_are_refused_with_the_reason() {
        assert_eq!(WorldName::new(""), Err(WorldNameError::Empty));
        assert!(matches!(
            WorldName::new(&"a".repeat(65)),
            Err(WorldNameError::TooLong { len: 65, .. })
        ));
        assert!(matches!(
            WorldName::new("a/b"),
            Err(WorldNameError::InvalidCharacter { character: '/', .. })
        ));
        // 'ö' is a letter; ASCII ones are meant (issue 44, item 12).
        assert_eq!(
            WorldName::new("wörld").unwrap_err().to_string(),
            "world name 'wörld' contains 'ö'; use ASCII letters (a-z, A-Z), digits, '-', '_' \
             and '.'"
        );
    }

    #[test]
    fn two_worlds_share_no_service_name() {
        let a = ServiceNames::new(&WorldName::new("a").unwrap());
        let b = ServiceNames::new(&WorldName::new("b").unwrap());
        for (x, y) in [
            (&a.frames, &b.frames),
            (&a.control, &b.control),
            (&a.frame_ready, &b.frame_ready),
            (&a.control_wake, &b.control_wake),
            (&a.tick, &b.tick),
        ] {
            assert_ne!(x, y);
        }
    }
}
