//! World settings, their validation rules and their wire form.

use std::fmt;

use crate::substep_rule::SubstepRule;
use crate::wire::wire_enum;

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

/// Nanoseconds in one second: simulation time is kept as integer nanoseconds.
pub const NANOS_PER_SECOND: u64 = 1_000_000_000;

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
    /// What a fixed delta longer than `max_substep_delta_time *
    /// max_substeps` does: refused ([`SubstepRule::Refuse`], the default),
    /// physics clamped as CARLA does, or substeps stretched.
    pub substep_rule: SubstepRule,
}

impl Default for WorldSettings {
    fn default() -> Self {
        Self {
            synchronous_mode: false,
            fixed_delta_seconds: None,
            substepping: true,
            max_substep_delta_time: 0.01,
            max_substeps: 10,
            substep_rule: SubstepRule::Refuse,
        }
    }
}

/// One line for logs: `sync, fixed step 0.05 s, substepping <= 0.01 s x 10`
/// or `async, variable step, no substepping`, then `, substep rule clamp`
/// for a rule other than the default. A fixed step of 0 reads as the
/// variable step it means.
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
            )?;
        } else {
            f.write_str(", no substepping")?;
        }
        match settings.substep_rule {
            SubstepRule::Refuse => Ok(()),
            rule => write!(f, ", substep rule {rule}"),
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
        /// `substep_rule`.
        SubstepRule = 5,
    }
}

impl SettingsField {
    /// What sign the field must have, in words.
    fn sign_rule(self) -> &'static str {
        match self {
            Self::FixedDeltaSeconds | Self::Fps => "it must be >= 0 (0 means variable step)",
            Self::MaxSubstepDeltaTime | Self::MaxSubsteps => "it must be positive",
            Self::SubstepRule => "it must be refuse, clamp or stretch",
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
            Self::SubstepRule => "substep_rule",
        })
    }
}

/// Why settings were refused. Refused settings change nothing.
#[derive(Debug, Clone, Copy, PartialEq, thiserror::Error)]
pub enum SettingsError {
    /// A value is NaN or infinite.
    #[error("{field} = {} is not a finite number", crate::number::Exact(*value))]
    NotFinite {
        /// The setting.
        field: SettingsField,
        /// The value given.
        value: f64,
    },
    /// A value is negative.
    #[error("{field} = {} is negative; {}", crate::number::Exact(*value), field.sign_rule())]
    Negative {
        /// The setting.
        field: SettingsField,
        /// The value given.
        value: f64,
    },
    /// A time is shorter than [`MIN_DELTA_SECONDS`].
    #[error(
        "{field} = {} s is shorter than the minimum of {} s",
        crate::number::Exact(*value),
        crate::number::Exact(*min)
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
        crate::number::Exact(*value),
        crate::number::Exact(*max)
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
    /// does not hold (under [`SubstepRule::Refuse`]; the message names the
    /// other rules and what each would do with these values).
    #[error(
        "substep rule violated: fixed_delta_seconds ({fixed} s) must be <= \
         max_substep_delta_time ({max_dt} s) * max_substeps ({max_substeps}) = {limit} s \
         (substep rule 'refuse'; 'clamp' runs CARLA's way: physics advances {limit} s per \
         {fixed} s frame; 'stretch' lengthens the substeps to {stretched} s)",
        limit = max_dt * f64::from(*max_substeps),
        stretched = fixed / f64::from((*max_substeps).max(1))
    )]
    SubstepRule {
        /// The requested fixed frame time.
        fixed: f64,
        /// The requested longest substep.
        max_dt: f64,
        /// The requested most substeps.
        max_substeps: u32,
    },
    /// A `substep_rule` wire value this version does not know (a peer of a
    /// newer or broken protocol).
    #[error("substep_rule = {value} is not a substep rule known to this version of simbus (0 refuse, 1 clamp, 2 stretch)")]
    UnknownSubstepRule {
        /// The value given.
        value: u32,
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
    /// Under [`SubstepRule::Clamp`], frames longer than `max_substeps ×
    /// max_substep_delta_time`: physics advances less than the frame's time
    /// (CARLA's behaviour).
    PhysicsClamped {
        /// The frame time.
        delta_seconds: f64,
        /// The longest substep.
        max_substep_delta_time: f64,
        /// The most substeps per frame.
        max_substeps: u32,
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
            Self::PhysicsClamped {
                delta_seconds,
                max_substep_delta_time,
                max_substeps,
            } => write!(
                f,
                "substep rule 'clamp': physics advances {:.3} s per {delta_seconds:.3} s frame \
                 ({max_substeps} substeps of {max_substep_delta_time:.3} s), as in CARLA; \
                 frames are flagged clamped",
                max_substep_delta_time * f64::from(*max_substeps)
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
    ///
    /// # Errors
    ///
    /// Returns [`SettingsError::NotFinite`] if `fps` is NaN or infinite, and
    /// [`SettingsError::Negative`] if it is below 0. (The step's range is
    /// checked by [`WorldSettings::validate`], not here.)
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
    /// substepping on and the substep rule [`SubstepRule::Refuse`],
    /// `fixed_delta_seconds <= max_substep_delta_time * max_substeps`
    /// (compared in integer nanoseconds, so 0.1 = 0.01 × 10 holds exactly).
    /// [`SubstepRule::Clamp`] and [`SubstepRule::Stretch`] accept longer
    /// frames and say what they do with them.
    ///
    /// # Errors
    ///
    /// Returns the first rule broken, in this order: for `fixed_delta_seconds`
    /// and then `max_substep_delta_time`, [`SettingsError::NotFinite`],
    /// [`SettingsError::Negative`], [`SettingsError::TooSmall`] (below
    /// [`MIN_DELTA_SECONDS`]) or [`SettingsError::TooLarge`] (above
    /// [`MAX_DELTA_SECONDS`]); [`SettingsError::MaxSubstepsOutOfRange`] if
    /// `max_substeps` is outside `1..=`[`MAX_SUBSTEPS_LIMIT`]; and
    /// [`SettingsError::SubstepRule`] if, with substepping on under
    /// [`SubstepRule::Refuse`], the fixed step is longer than
    /// `max_substep_delta_time * max_substeps`.
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
        let refused = settings.substep_rule == SubstepRule::Refuse;
        if let (true, true, Some(fixed)) =
            (refused, settings.substepping, settings.fixed_delta_seconds)
        {
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
            (true, Some(dt)) => {
                let max = f64::from(self.max_substeps.max(1));
                let count = (dt / self.max_substep_delta_time).ceil().clamp(1.0, max);
                match self.substep_rule {
                    SubstepRule::Clamp => (dt / count).min(self.max_substep_delta_time),
                    SubstepRule::Refuse | SubstepRule::Stretch => dt / count,
                }
            }
            (true, None) => self.max_substep_delta_time,
            (false, Some(dt)) => dt,
            (false, None) => 0.0,
        };
        if substep_seconds > LONG_SUBSTEP_SECONDS {
            warnings.push(SettingsWarning::LongSubstep { substep_seconds });
        }
        if let Some(delta_seconds) = fixed.filter(|_| self.clamps_physics()) {
            warnings.push(SettingsWarning::PhysicsClamped {
                delta_seconds,
                max_substep_delta_time: self.max_substep_delta_time,
                max_substeps: self.max_substeps,
            });
        }
        warnings
    }

    /// Whether each fixed-step frame runs less physics time than it lasts:
    /// [`SubstepRule::Clamp`] with substepping on and `fixed_delta_seconds >
    /// max_substep_delta_time * max_substeps` (in integer nanoseconds).
    pub fn clamps_physics(&self) -> bool {
        self.fixed_delta_nanos().is_some_and(|delta_ns| {
            self.substep_rule.physics_ns(
                delta_ns,
                self.substepping,
                self.max_substep_nanos(),
                self.max_substeps,
            ) < delta_ns
        })
    }
}

#[cfg(test)]
#[path = "settings_tests.rs"]
mod tests;
