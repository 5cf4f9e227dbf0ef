//! World settings, their validation rules and their wire form.

use std::fmt;

use crate::wire::wire_enum;
use crate::NANOS_PER_SECOND;

/// The largest `max_substeps` accepted (CARLA's limit).
pub const MAX_SUBSTEPS_LIMIT: u32 = 16;

/// The longest fixed frame or substep accepted: one hour of simulation
/// time (the integer-nanosecond clock and every product of these stay far
/// from overflow).
pub const MAX_DELTA_SECONDS: f64 = 3600.0;

/// The shortest fixed frame or substep accepted: one microsecond. Below it
/// the integer-nanosecond clock would lose the value's meaning.
pub const MIN_DELTA_SECONDS: f64 = 1e-6;

/// Frames longer than this (below 10 FPS) make physics unreliable:
/// [`WorldSettings::warnings`] warns about them, and a frame that was longer
/// is flagged unreliable.
pub const LONG_FRAME_SECONDS: f64 = 0.1;

/// [`LONG_FRAME_SECONDS`] in the clock's integer nanoseconds.
pub const LONG_FRAME_NS: u64 = 100_000_000;

/// Physics substeps longer than this (1/60 s) make physics unreliable:
/// [`WorldSettings::warnings`] warns about them, and a frame computed with
/// longer substeps is flagged unreliable.
pub const LONG_SUBSTEP_SECONDS: f64 = 1.0 / 60.0;

/// [`LONG_SUBSTEP_SECONDS`] in the clock's integer nanoseconds, rounded as
/// [`seconds_to_nanos`] rounds (16 666 666.67 ns becomes 16 666 667), so
/// `seconds_to_nanos(s) > LONG_SUBSTEP_NS` agrees with
/// `s > LONG_SUBSTEP_SECONDS` at the boundary.
pub const LONG_SUBSTEP_NS: u64 = 16_666_667;

/// Converts seconds to the integer nanoseconds the clock keeps, rounding to
/// the nearest nanosecond (0.1 s is exactly 100 000 000 ns).
pub fn seconds_to_nanos(seconds: f64) -> u64 {
    (seconds * NANOS_PER_SECOND as f64).round() as u64
}

/// How the world's time moves, as CARLA's `WorldSettings` has it.
///
/// The four configurations are `synchronous_mode` × (`fixed_delta_seconds`
/// set or not). The default is asynchronous with a variable step, with
/// physics substepping on (0.01 s, at most 10 substeps).
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct WorldSettings {
    /// The server computes a frame only after a tick from the ticker.
    pub synchronous_mode: bool,
    /// `Some(dt)`: every frame advances exactly `dt` seconds.
    /// `None` (or `Some(0.0)`): variable step, dt is the wall time since the
    /// previous frame.
    pub fixed_delta_seconds: Option<f64>,
    /// Split each frame into physics substeps of at most
    /// `max_substep_delta_time`.
    pub substepping: bool,
    /// The longest physics substep, in seconds.
    pub max_substep_delta_time: f64,
    /// The most physics substeps per frame, 1 to [`MAX_SUBSTEPS_LIMIT`].
    pub max_substeps: u32,
}

impl Default for WorldSettings {
    fn default() -> Self {
        Self {
            synchronous_mode: false,
            fixed_delta_seconds: None,
            substepping: true,
            max_substep_delta_time: 0.01,
            max_substeps: 10,
        }
    }
}

/// One line for logs: `sync, fixed step 0.05 s, substepping <= 0.01 s x 10`
/// or `async, variable step, no substepping`. A fixed step of 0 reads as
/// the variable step it means.
impl fmt::Display for WorldSettings {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        let settings = self.normalized();
        f.write_str(if settings.synchronous_mode {
            "sync"
        } else {
            "async"
        })?;
        match settings.fixed_delta_seconds {
            Some(dt) => write!(f, ", fixed step {dt} s")?,
            None => f.write_str(", variable step")?,
        }
        if settings.substepping {
            write!(
                f,
                ", substepping <= {} s x {}",
                settings.max_substep_delta_time, settings.max_substeps
            )
        } else {
            f.write_str(", no substepping")
        }
    }
}

wire_enum! {
    /// A setting, as named in errors and on the command line.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum SettingsField {
        /// `fixed_delta_seconds`.
        FixedDeltaSeconds = 1,
        /// `max_substep_delta_time`.
        MaxSubstepDeltaTime = 2,
        /// `max_substeps`.
        MaxSubsteps = 3,
        /// `fps` (fixed_delta_seconds = 1 / fps).
        Fps = 4,
    }
}

impl SettingsField {
    /// What sign the field must have, in words.
    fn sign_rule(self) -> &'static str {
        match self {
            Self::FixedDeltaSeconds | Self::Fps => "it must be >= 0 (0 means variable step)",
            Self::MaxSubstepDeltaTime | Self::MaxSubsteps => "it must be positive",
        }
    }
}

impl fmt::Display for SettingsField {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        f.write_str(match self {
            Self::FixedDeltaSeconds => "fixed_delta_seconds",
            Self::MaxSubstepDeltaTime => "max_substep_delta_time",
            Self::MaxSubsteps => "max_substeps",
            Self::Fps => "fps",
        })
    }
}

/// Why settings were refused. Refused settings change nothing.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum SettingsError {
    /// A value is NaN or infinite.
    #[error("{field} = {} is not a finite number", crate::Exact(*value))]
    NotFinite {
        /// The setting.
        field: SettingsField,
        /// The value given.
        value: f64,
    },
    /// A value is negative.
    #[error("{field} = {} is negative; {}", crate::Exact(*value), field.sign_rule())]
    Negative {
        /// The setting.
        field: SettingsField,
        /// The value given.
        value: f64,
    },
    /// A time is shorter than [`MIN_DELTA_SECONDS`].
    #[error(
        "{field} = {} s is shorter than the minimum of {} s",
        crate::Exact(*value),
        crate::Exact(*min)
    )]
    TooSmall {
        /// The setting.
        field: SettingsField,
        /// The value given.
        value: f64,
        /// The minimum.
        min: f64,
    },
    /// A time is longer than [`MAX_DELTA_SECONDS`].
    #[error(
        "{field} = {} s is longer than the maximum of {} s",
        crate::Exact(*value),
        crate::Exact(*max)
    )]
    TooLarge {
        /// The setting.
        field: SettingsField,
        /// The value given.
        value: f64,
        /// The maximum.
        max: f64,
    },
    /// `max_substeps` is outside `1..=16`.
    #[error("max_substeps = {value} is outside the allowed range 1..={max}")]
    MaxSubstepsOutOfRange {
        /// The value given.
        value: u32,
        /// The largest allowed value.
        max: u32,
    },
    /// The substep rule `fixed_delta_seconds <= max_substep_delta_time * max_substeps`
    /// does not hold.
    #[error(
        "substep rule violated: fixed_delta_seconds ({fixed} s) must be <= \
         max_substep_delta_time ({max_dt} s) * max_substeps ({max_substeps}) = {limit} s",
        limit = max_dt * f64::from(*max_substeps)
    )]
    SubstepRule {
        /// The requested fixed frame time.
        fixed: f64,
        /// The requested longest substep.
        max_dt: f64,
        /// The requested most substeps.
        max_substeps: u32,
    },
}

/// A setting that is accepted but makes physics unreliable.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum SettingsWarning {
    /// Frames longer than 0.1 s (below 10 FPS).
    LongFrame {
        /// The frame time.
        delta_seconds: f64,
    },
    /// Physics substeps longer than 1/60 s.
    LongSubstep {
        /// The longest substep the settings allow.
        substep_seconds: f64,
    },
}

impl fmt::Display for SettingsWarning {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::LongFrame { delta_seconds } => write!(
                f,
                "frame delta {delta_seconds} s is above 0.1 s (below 10 FPS): physics is unreliable"
            ),
            Self::LongSubstep { substep_seconds } => write!(
                f,
                "physics substep {substep_seconds} s is above 1/60 s: physics may be unreliable"
            ),
        }
    }
}

fn check_time(field: SettingsField, value: f64) -> Result<(), SettingsError> {
    if !value.is_finite() {
        return Err(SettingsError::NotFinite { field, value });
    }
    if value < 0.0 {
        return Err(SettingsError::Negative { field, value });
    }
    if value < MIN_DELTA_SECONDS {
        return Err(SettingsError::TooSmall {
            field,
            value,
            min: MIN_DELTA_SECONDS,
        });
    }
    if value > MAX_DELTA_SECONDS {
        return Err(SettingsError::TooLarge {
            field,
            value,
            max: MAX_DELTA_SECONDS,
        });
    }
    Ok(())
}

impl WorldSettings {
    /// Converts a frame rate to a fixed delta: `fps = 0` means variable step.
    pub fn delta_from_fps(fps: f64) -> Result<Option<f64>, SettingsError> {
        let field = SettingsField::Fps;
        if !fps.is_finite() {
            return Err(SettingsError::NotFinite { field, value: fps });
        }
        if fps < 0.0 {
            return Err(SettingsError::Negative { field, value: fps });
        }
        Ok((fps > 0.0).then(|| 1.0 / fps))
    }

    /// The same settings with `Some(0.0)` written as `None` (variable step).
    pub fn normalized(mut self) -> Self {
        if self.fixed_delta_seconds == Some(0.0) {
            self.fixed_delta_seconds = None;
        }
        self
    }

    /// The fixed frame time in integer nanoseconds, `None` for variable step.
    pub fn fixed_delta_nanos(&self) -> Option<u64> {
        self.normalized().fixed_delta_seconds.map(seconds_to_nanos)
    }

    /// The longest substep in integer nanoseconds.
    pub fn max_substep_nanos(&self) -> u64 {
        seconds_to_nanos(self.max_substep_delta_time)
    }

    /// Checks every rule; the first broken one is returned.
    ///
    /// Rules: times are finite, not negative and at least 1 µs (a fixed delta
    /// of 0 means variable step); `max_substeps` is in `1..=16`; with
    /// substepping on, `fixed_delta_seconds <= max_substep_delta_time *
    /// max_substeps` (compared in integer nanoseconds, so 0.1 = 0.01 × 10
    /// holds exactly).
    pub fn validate(&self) -> Result<(), SettingsError> {
        let settings = self.normalized();
        if let Some(dt) = settings.fixed_delta_seconds {
            check_time(SettingsField::FixedDeltaSeconds, dt)?;
        }
        check_time(
            SettingsField::MaxSubstepDeltaTime,
            settings.max_substep_delta_time,
        )?;
        if !(1..=MAX_SUBSTEPS_LIMIT).contains(&settings.max_substeps) {
            return Err(SettingsError::MaxSubstepsOutOfRange {
                value: settings.max_substeps,
                max: MAX_SUBSTEPS_LIMIT,
            });
        }
        if let (true, Some(fixed)) = (settings.substepping, settings.fixed_delta_seconds) {
            let limit = settings
                .max_substep_nanos()
                .saturating_mul(u64::from(settings.max_substeps));
            if seconds_to_nanos(fixed) > limit {
                return Err(SettingsError::SubstepRule {
                    fixed,
                    max_dt: settings.max_substep_delta_time,
                    max_substeps: settings.max_substeps,
                });
            }
        }
        Ok(())
    }

    /// What is accepted but unwise in these (valid) settings.
    pub fn warnings(&self) -> Vec<SettingsWarning> {
        let mut warnings = Vec::new();
        let fixed = self.normalized().fixed_delta_seconds;
        if let Some(delta_seconds) = fixed.filter(|dt| *dt > LONG_FRAME_SECONDS) {
            warnings.push(SettingsWarning::LongFrame { delta_seconds });
        }
        let substep_seconds = match (self.substepping, fixed) {
            (true, Some(dt)) => dt / (dt / self.max_substep_delta_time).ceil().max(1.0),
            (true, None) => self.max_substep_delta_time,
            (false, Some(dt)) => dt,
            (false, None) => 0.0,
        };
        if substep_seconds > LONG_SUBSTEP_SECONDS {
            warnings.push(SettingsWarning::LongSubstep { substep_seconds });
        }
        warnings
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::{WireSettings, WireSettingsError};

    fn fixed(dt: f64) -> WorldSettings {
        WorldSettings {
            fixed_delta_seconds: Some(dt),
            ..Default::default()
        }
    }

    #[test]
    fn defaults_are_carla_defaults_and_valid() {
        let s = WorldSettings::default();
        assert!(!s.synchronous_mode);
        assert_eq!(s.fixed_delta_seconds, None);
        assert!(s.substepping);
        assert_eq!(s.max_substep_delta_time, 0.01);
        assert_eq!(s.max_substeps, 10);
        assert_eq!(s.validate(), Ok(()));
    }

    #[test]
    fn non_finite_and_negative_values_are_refused() {
        let field = SettingsField::FixedDeltaSeconds;
        assert!(matches!(
            fixed(f64::NAN).validate(),
            Err(SettingsError::NotFinite { field: f, .. }) if f == field
        ));
        assert!(matches!(
            fixed(f64::INFINITY).validate(),
            Err(SettingsError::NotFinite { .. })
        ));
        assert_eq!(
            fixed(-0.1).validate(),
            Err(SettingsError::Negative { field, value: -0.1 })
        );
        let s = WorldSettings {
            max_substep_delta_time: -1.0,
            ..Default::default()
        };
        assert!(matches!(
            s.validate(),
            Err(SettingsError::Negative {
                field: SettingsField::MaxSubstepDeltaTime,
                ..
            })
        ));
        assert!(matches!(
            fixed(1e-9).validate(),
            Err(SettingsError::TooSmall { .. })
        ));
    }

    #[test]
    fn zero_fixed_delta_means_variable_step() {
        assert_eq!(fixed(0.0).validate(), Ok(()));
        assert_eq!(fixed(0.0).normalized().fixed_delta_seconds, None);
        assert_eq!(fixed(0.0).fixed_delta_nanos(), None);
        assert_eq!(WorldSettings::delta_from_fps(0.0), Ok(None));
        assert_eq!(WorldSettings::delta_from_fps(20.0), Ok(Some(0.05)));
        assert!(WorldSettings::delta_from_fps(-1.0).is_err());
        assert!(WorldSettings::delta_from_fps(f64::NAN).is_err());
    }

    #[test]
    fn max_substeps_must_be_within_1_to_16() {
        for (n, ok) in [(0, false), (1, true), (16, true), (17, false)] {
            let s = WorldSettings {
                max_substeps: n,
                fixed_delta_seconds: Some(0.001),
                ..Default::default()
            };
            assert_eq!(s.validate().is_ok(), ok, "max_substeps = {n}");
        }
    }

    #[test]
    fn substep_rule_is_checked_exactly_and_named() {
        assert_eq!(fixed(0.1).validate(), Ok(()), "0.1 = 0.01 * 10 holds");
        let err = fixed(0.100_000_001).validate().unwrap_err();
        assert_eq!(
            err,
            SettingsError::SubstepRule {
                fixed: 0.100_000_001,
                max_dt: 0.01,
                max_substeps: 10
            }
        );
        assert!(err.to_string().contains("substep rule"));
        assert!(err
            .to_string()
            .contains("max_substep_delta_time (0.01 s) * max_substeps (10)"));
        let off = WorldSettings {
            substepping: false,
            ..fixed(0.5)
        };
        assert_eq!(
            off.validate(),
            Ok(()),
            "the rule binds only with substepping"
        );
    }

    #[test]
    fn warnings_follow_the_limits() {
        assert!(fixed(0.05).warnings().is_empty());
        assert!(matches!(
            fixed(0.12).warnings()[..],
            [SettingsWarning::LongFrame { .. }]
        ));
        let coarse = WorldSettings {
            substepping: false,
            ..fixed(0.05)
        };
        assert!(matches!(
            coarse.warnings()[..],
            [SettingsWarning::LongSubstep { .. }]
        ));
    }

    #[test]
    fn errors_survive_the_wire() {
        let errors = [
            SettingsError::NotFinite {
                field: SettingsField::Fps,
                value: f64::INFINITY,
            },
            SettingsError::Negative {
                field: SettingsField::FixedDeltaSeconds,
                value: -2.0,
            },
            SettingsError::TooSmall {
                field: SettingsField::MaxSubstepDeltaTime,
                value: 1e-9,
                min: MIN_DELTA_SECONDS,
            },
            SettingsError::MaxSubstepsOutOfRange { value: 17, max: 16 },
            SettingsError::SubstepRule {
                fixed: 0.5,
                max_dt: 0.01,
                max_substeps: 10,
            },
        ];
        for e in errors {
            let (c, f, v) = e.to_wire();
            assert_eq!(SettingsError::from_wire(c, f, v), Some(e));
            assert_eq!(WireSettingsError::from(&e).error(), Some(e));
        }
        assert_eq!(SettingsError::from_wire(99, 0, [0.0; 3]), None);
        assert_eq!(WireSettingsError::NONE.error(), None);
        assert_eq!(WireSettingsError::default(), WireSettingsError::NONE);
        let unknown_field = WireSettingsError {
            field: 99,
            ..WireSettingsError::from(&errors[0])
        };
        assert_eq!(unknown_field.error(), None);
    }

    #[test]
    fn wire_settings_error_layout_is_fixed() {
        assert_eq!(std::mem::size_of::<WireSettingsError>(), 32);
        assert_eq!(std::mem::align_of::<WireSettingsError>(), 8);
    }

    #[test]
    fn long_thresholds_agree_in_seconds_and_nanoseconds() {
        assert_eq!(seconds_to_nanos(LONG_FRAME_SECONDS), LONG_FRAME_NS);
        assert_eq!(seconds_to_nanos(LONG_SUBSTEP_SECONDS), LONG_SUBSTEP_NS);
        // A frame of exactly 0.1 s is not long; one nanosecond more is.
        assert!(fixed(0.1).warnings().is_empty());
        assert!(seconds_to_nanos(0.1) <= LONG_FRAME_NS);
        assert!(seconds_to_nanos(0.100_000_001) > LONG_FRAME_NS);
        assert!(!fixed(0.100_000_001).warnings().is_empty());
    }

    #[test]
    fn settings_display_as_one_line() {
        assert_eq!(
            WorldSettings::default().to_string(),
            "async, variable step, substepping <= 0.01 s x 10"
        );
        let sync = WorldSettings {
            synchronous_mode: true,
            ..fixed(0.05)
        };
        assert_eq!(
            sync.to_string(),
            "sync, fixed step 0.05 s, substepping <= 0.01 s x 10"
        );
        let coarse = WorldSettings {
            substepping: false,
            ..fixed(0.0)
        };
        assert_eq!(coarse.to_string(), "async, variable step, no substepping");
    }

    #[test]
    fn settings_survive_the_wire() {
        let s = WorldSettings {
            synchronous_mode: true,
            fixed_delta_seconds: Some(0.05),
            substepping: false,
            max_substep_delta_time: 0.002,
            max_substeps: 3,
        };
        assert_eq!(WorldSettings::from(WireSettings::from(s)), s);
        assert_eq!(
            WorldSettings::from(WireSettings::from(WorldSettings::default())),
            WorldSettings::default()
        );
    }
}
