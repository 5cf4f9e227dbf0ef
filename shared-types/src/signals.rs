//! Traffic lights and signs on the wire: what a light shows and what a
//! sign says, packed into their [`ActorState`]'s `flags` (the code, bits 8
//! to 15) and `detail`.

use crate::frame::{ActorKind, ActorState};
use crate::wire::wire_enum;

wire_enum! {
    /// What a traffic light shows: CARLA's `TrafficLightState`, with its
    /// values.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
    pub enum LightState {
        /// Stop.
        Red = 0,
        /// Stop if you can.
        Yellow = 1,
        /// Go.
        Green = 2,
        /// Dark: the junction is unsignalled.
        Off = 3,
    }
}

impl LightState {
    /// Its lower-case name (`red`, `yellow`, `green`, `off`).
    pub fn name(&self) -> &'static str {
        match self {
            Self::Red => "red",
            Self::Yellow => "yellow",
            Self::Green => "green",
            Self::Off => "off",
        }
    }

    /// The state named `name` (as [`LightState::name`] prints it).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|s| s.name() == name)
    }
}

wire_enum! {
    /// What a traffic sign says.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
    pub enum SignKind {
        /// Stop, then give way (OpenDRIVE type 206, CARLA's `traffic.stop`).
        Stop = 1,
        /// The speed limit is the sign's value in km/h (OpenDRIVE type
        /// 274, CARLA's `traffic.speed_limit.<km/h>`).
        SpeedLimit = 2,
    }
}

/// A traffic light as a frame carries it.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct LightReading {
    /// What it shows.
    pub state: LightState,
    /// How long it has shown it, seconds (to the millisecond).
    pub elapsed_seconds: f64,
    /// Whether its time is frozen.
    pub frozen: bool,
}

/// A traffic sign as a frame carries it.
#[derive(Debug, Clone, Copy, PartialEq, Eq, serde::Serialize, serde::Deserialize)]
pub struct SignReading {
    /// What it says.
    pub kind: SignKind,
    /// A speed limit's km/h; zero for a stop sign.
    pub value: u32,
}

impl ActorState {
    /// The kind's code in `flags` (bits 8 to 15).
    fn code(&self) -> u32 {
        (self.flags >> Self::CODE_SHIFT) & 0xff
    }

    /// `flags` with `code` in bits 8 to 15.
    fn with_code(flags: u32, code: u32) -> u32 {
        (flags & !(0xff << Self::CODE_SHIFT)) | ((code & 0xff) << Self::CODE_SHIFT)
    }

    /// What a traffic light shows, how long it has and whether it is
    /// frozen; `None` for any other actor (or a state this version does
    /// not know).
    pub fn light(&self) -> Option<LightReading> {
        if self.actor_kind() != Some(ActorKind::TrafficLight) {
            return None;
        }
        Some(LightReading {
            state: LightState::from_u32(self.code())?,
            elapsed_seconds: f64::from(self.detail) / 1000.0,
            frozen: self.flags & Self::LIGHT_FROZEN != 0,
        })
    }

    /// Writes `light` into a traffic light's `flags` and `detail` (the
    /// elapsed time to the millisecond, at most `u32::MAX` ms).
    pub fn set_light(&mut self, light: LightReading) {
        let mut flags = Self::with_code(self.flags, light.state as u32);
        flags &= !Self::LIGHT_FROZEN;
        if light.frozen {
            flags |= Self::LIGHT_FROZEN;
        }
        self.flags = flags;
        self.detail = (light.elapsed_seconds * 1000.0)
            .round()
            .clamp(0.0, u32::MAX as f64) as u32;
    }

    /// What a traffic sign says; `None` for any other actor.
    pub fn sign(&self) -> Option<SignReading> {
        if self.actor_kind() != Some(ActorKind::TrafficSign) {
            return None;
        }
        Some(SignReading {
            kind: SignKind::from_u32(self.code())?,
            value: self.detail,
        })
    }

    /// Writes `sign` into a traffic sign's `flags` and `detail`.
    pub fn set_sign(&mut self, sign: SignReading) {
        self.flags = Self::with_code(self.flags, sign.kind as u32);
        self.detail = sign.value;
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_lights_reading_round_trips_beside_the_other_flags() {
        let mut state = ActorState {
            kind: ActorKind::TrafficLight as u32,
            flags: ActorState::SLEEPING,
            ..ActorState::default()
        };
        let reading = LightReading {
            state: LightState::Yellow,
            elapsed_seconds: 2.35,
            frozen: true,
        };
        state.set_light(reading);
        assert_eq!(state.light(), Some(reading));
        assert_eq!(state.flags & ActorState::SLEEPING, ActorState::SLEEPING);
        assert_eq!(state.detail, 2350);
        state.set_light(LightReading {
            frozen: false,
            ..reading
        });
        assert!(!state.light().unwrap().frozen);
        // Not a light: no reading, whatever the bits say.
        state.kind = ActorKind::Box as u32;
        assert_eq!(state.light(), None);
    }

    #[test]
    fn a_signs_reading_round_trips_and_unknown_codes_read_as_none() {
        let mut state = ActorState {
            kind: ActorKind::TrafficSign as u32,
            ..ActorState::default()
        };
        let limit = SignReading {
            kind: SignKind::SpeedLimit,
            value: 30,
        };
        state.set_sign(limit);
        assert_eq!(state.sign(), Some(limit));
        state.flags = 0xff << ActorState::CODE_SHIFT;
        assert_eq!(state.sign(), None);
        assert_eq!(LightState::from_name("green"), Some(LightState::Green));
        assert_eq!(LightState::from_name("blue"), None);
    }
}
