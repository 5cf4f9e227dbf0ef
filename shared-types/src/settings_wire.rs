//! [`WorldSettings`] and their errors as they travel in shared memory.

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

use crate::settings::WorldSettings;
use crate::settings::{SettingsError, SettingsField};
use crate::substep_rule::SubstepRule;

/// [`WorldSettings`] as they travel in shared memory.
///
/// Version 2 gave the first of version 1's two zero bytes to
/// [`WireSettings::substep_rule`]; the layout (size, offsets) is unchanged,
/// and the zero that every version 1 peer and recording holds there reads
/// as [`SubstepRule::Refuse`], version 1's only behaviour.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::WireSettings/2")]
pub struct WireSettings {
    /// Fixed frame time in seconds; 0 means variable step.
    pub fixed_delta_seconds: f64,
    /// Longest substep in seconds.
    pub max_substep_delta_time: f64,
    /// Most substeps per frame.
    pub max_substeps: u32,
    /// 1 = synchronous mode.
    pub synchronous_mode: u8,
    /// 1 = substepping on.
    pub substepping: u8,
    /// The [`SubstepRule`] as its `u32` wire value (which fits a byte);
    /// read it with [`WireSettings::substep_rule`].
    pub substep_rule: u8,
    /// Zero.
    pub reserved: u8,
}

impl WireSettings {
    /// The substep rule carried, refused with an error naming the value
    /// when this version does not know it.
    ///
    /// # Errors
    ///
    /// Returns [`SettingsError::UnknownSubstepRule`] (with the value read) if
    /// the byte is not the wire value of a [`SubstepRule`] this version knows.
    pub fn substep_rule(&self) -> Result<SubstepRule, SettingsError> {
        SubstepRule::try_from(u32::from(self.substep_rule))
            .map_err(|e| SettingsError::UnknownSubstepRule { value: e.value })
    }

    /// The settings carried, checked.
    ///
    /// An unknown substep rule from another process is an error, never a
    /// guess. (The [`From`] conversion, for settings this process's own server
    /// wrote, reads an unknown rule as [`SubstepRule::Refuse`].)
    ///
    /// # Errors
    ///
    /// Returns [`SettingsError::UnknownSubstepRule`] if the substep rule
    /// carried is not one this version knows (see
    /// [`WireSettings::substep_rule`]); the other fields are not checked here
    /// (see [`WorldSettings::validate`]).
    pub fn settings(&self) -> Result<WorldSettings, SettingsError> {
        Ok(WorldSettings {
            substep_rule: self.substep_rule()?,
            ..WorldSettings::from(*self)
        })
    }
}

impl From<WorldSettings> for WireSettings {
    fn from(s: WorldSettings) -> Self {
        Self {
            fixed_delta_seconds: s.fixed_delta_seconds.unwrap_or(0.0),
            max_substep_delta_time: s.max_substep_delta_time,
            max_substeps: s.max_substeps,
            synchronous_mode: u8::from(s.synchronous_mode),
            substepping: u8::from(s.substepping),
            // Every rule's wire value is below 256 (see the layout test).
            substep_rule: u32::from(s.substep_rule) as u8,
            reserved: 0,
        }
    }
}

impl From<WireSettings> for WorldSettings {
    fn from(w: WireSettings) -> Self {
        Self {
            synchronous_mode: w.synchronous_mode != 0,
            fixed_delta_seconds: (w.fixed_delta_seconds != 0.0).then_some(w.fixed_delta_seconds),
            substepping: w.substepping != 0,
            max_substep_delta_time: w.max_substep_delta_time,
            max_substeps: w.max_substeps,
            substep_rule: w.substep_rule().unwrap_or_default(),
        }
    }
}

/// A [`SettingsError`] as it travels in a response (all zero: no error).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::WireSettingsError/1")]
pub struct WireSettingsError {
    /// Which error (0: none); see [`SettingsError::to_wire`].
    pub code: u32,
    /// The [`SettingsField`] the error names, as `u32`.
    pub field: u32,
    /// The values the error names.
    pub values: [f64; 3],
}

impl WireSettingsError {
    /// No error.
    pub const NONE: Self = Self {
        code: 0,
        field: 0,
        values: [0.0; 3],
    };

    /// The error, if one is carried and this version knows its code.
    pub fn error(&self) -> Option<SettingsError> {
        SettingsError::from_wire(self.code, self.field, self.values)
    }
}

impl From<&SettingsError> for WireSettingsError {
    fn from(error: &SettingsError) -> Self {
        let (code, field, values) = error.to_wire();
        Self {
            code,
            field,
            values,
        }
    }
}

/// Wire codes of [`SettingsError`] variants.
mod code {
    pub(super) const NOT_FINITE: u32 = 1;
    pub(super) const NEGATIVE: u32 = 2;
    pub(super) const TOO_SMALL: u32 = 3;
    pub(super) const MAX_SUBSTEPS: u32 = 4;
    pub(super) const SUBSTEP_RULE: u32 = 5;
    pub(super) const TOO_LARGE: u32 = 6;
    pub(super) const UNKNOWN_SUBSTEP_RULE: u32 = 7;
}

impl SettingsError {
    /// Encodes the error as `(code, field, values)`: the fields of a
    /// [`WireSettingsError`]. Codes start at 1; 0 means no error.
    pub fn to_wire(&self) -> (u32, u32, [f64; 3]) {
        match *self {
            Self::NotFinite { field, value } => (code::NOT_FINITE, field as u32, [value, 0.0, 0.0]),
            Self::Negative { field, value } => (code::NEGATIVE, field as u32, [value, 0.0, 0.0]),
            Self::TooSmall { field, value, min } => {
                (code::TOO_SMALL, field as u32, [value, min, 0.0])
            }
            Self::TooLarge { field, value, max } => {
                (code::TOO_LARGE, field as u32, [value, max, 0.0])
            }
            Self::MaxSubstepsOutOfRange { value, max } => (
                code::MAX_SUBSTEPS,
                SettingsField::MaxSubsteps as u32,
                [f64::from(value), f64::from(max), 0.0],
            ),
            Self::SubstepRule {
                fixed,
                max_dt,
                max_substeps,
            } => (
                code::SUBSTEP_RULE,
                SettingsField::FixedDeltaSeconds as u32,
                [fixed, max_dt, f64::from(max_substeps)],
            ),
            Self::UnknownSubstepRule { value } => (
                code::UNKNOWN_SUBSTEP_RULE,
                SettingsField::SubstepRule as u32,
                [f64::from(value), 0.0, 0.0],
            ),
        }
    }

    /// Decodes an error encoded by [`SettingsError::to_wire`]; `None` for
    /// code 0 (no error) and codes this version does not know.
    pub fn from_wire(code: u32, field: u32, values: [f64; 3]) -> Option<Self> {
        let field = SettingsField::from_u32(field);
        let [a, b, c] = values;
        Some(match code {
            code::NOT_FINITE => Self::NotFinite {
                field: field?,
                value: a,
            },
            code::NEGATIVE => Self::Negative {
                field: field?,
                value: a,
            },
            code::TOO_SMALL => Self::TooSmall {
                field: field?,
                value: a,
                min: b,
            },
            code::TOO_LARGE => Self::TooLarge {
                field: field?,
                value: a,
                max: b,
            },
            code::MAX_SUBSTEPS => Self::MaxSubstepsOutOfRange {
                value: a as u32,
                max: b as u32,
            },
            code::SUBSTEP_RULE => Self::SubstepRule {
                fixed: a,
                max_dt: b,
                max_substeps: c as u32,
            },
            code::UNKNOWN_SUBSTEP_RULE => Self::UnknownSubstepRule { value: a as u32 },
            _ => return None,
        })
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_substep_rule_takes_a_byte_version_1_left_zero() {
        // Version 1's layout: 24 bytes, the flags at 20 and 21.
        assert_eq!(std::mem::size_of::<WireSettings>(), 24);
        assert_eq!(std::mem::offset_of!(WireSettings, substepping), 21);
        assert_eq!(std::mem::offset_of!(WireSettings, substep_rule), 22);
        assert!(SubstepRule::ALL.iter().all(|&r| u32::from(r) < 256));
        // A version 1 peer's zero reads as refuse.
        let mut wire = WireSettings::from(WorldSettings::default());
        assert_eq!(wire.substep_rule, 0);
        assert_eq!(wire.substep_rule(), Ok(SubstepRule::Refuse));
        for rule in SubstepRule::ALL {
            let s = WorldSettings {
                substep_rule: rule,
                ..WorldSettings::default()
            };
            assert_eq!(WireSettings::from(s).settings(), Ok(s));
        }
        // An unknown value is an error naming it, never a panic.
        wire.substep_rule = 9;
        let error = wire.settings().unwrap_err();
        assert_eq!(error, SettingsError::UnknownSubstepRule { value: 9 });
        assert!(error
            .to_string()
            .contains("substep_rule = 9 is not a substep rule"));
        assert_eq!(WorldSettings::from(wire).substep_rule, SubstepRule::Refuse);
    }
}
