//! Why a value someone typed was refused: [`InputError`].

use std::fmt;

use shared_types::limits::{MAX_ACTOR_POSITION, MAX_WAIT_SECONDS};
use shared_types::scene::SceneNameError;
use shared_types::{SettingsError, MAX_DELTA_SECONDS, MAX_IMAGE_SIDE, MIN_DELTA_SECONDS};

use shared_types::{Exact, Readable};

use crate::bounds::{MAX_DISTANCE_METRES, MAX_RATE_HZ};

/// Why a value given on a command line was refused. Each variant keeps the
/// text given (or the value read from it), the range it had to be in and
/// the rule it broke; its message names all three.
///
/// The message is complete on its own (clap prints only it, after the flag's
/// name); a lower-level error it includes is also kept, typed, as its
/// [`source`](std::error::Error::source).
#[derive(Debug, Clone, PartialEq, thiserror::Error)]
pub enum InputError {
    /// The text does not read as a number at all.
    #[error("'{text}' is not a number")]
    NotANumber {
        /// The text given.
        text: String,
    },
    /// A number outside its (finite) range.
    #[error(
        "must be a finite number{unit} in {}..={}, got {text}",
        Readable(*start),
        Readable(*end)
    )]
    OutOfRange {
        /// The text given.
        text: String,
        /// The smallest value allowed.
        start: f64,
        /// The largest value allowed.
        end: f64,
        /// What the number counts, in words (` of seconds`), and any hint.
        unit: &'static str,
    },
    /// Not a whole number in its range.
    #[error("must be a whole number {}, got {text}", WholeRange(*start, *end))]
    NotWhole {
        /// The text given.
        text: String,
        /// The smallest value allowed.
        start: u64,
        /// The largest value allowed (`u64::MAX`: no upper bound).
        end: u64,
    },
    /// A wait of zero, a negative or a non-finite number of seconds.
    #[error("must be a positive, finite number of seconds, got {text}")]
    NotPositiveSeconds {
        /// The text given.
        text: String,
    },
    /// A wait ([`super::wait`]) that is negative or not finite.
    #[error("must be a finite number of seconds >= 0")]
    WaitNotFinite {
        /// The seconds given.
        seconds: f64,
    },
    /// A wait ([`super::wait`]) longer than [`MAX_WAIT_SECONDS`].
    #[error("must be at most {MAX_WAIT_SECONDS:e} seconds (about 31 years)")]
    WaitTooLong {
        /// The seconds given.
        seconds: f64,
    },
    /// A timeout the clock cannot wait for.
    #[error("{source}, got {text}")]
    Timeout {
        /// The text given.
        text: String,
        /// The rule of [`super::wait`] it broke.
        #[source]
        source: Box<InputError>,
    },
    /// A rate of zero, a negative or a non-finite number of hertz.
    #[error("must be a positive, finite number of Hz, at most {MAX_RATE_HZ:e}, got {text}")]
    RateNotPositive {
        /// The text given.
        text: String,
    },
    /// A rate above [`MAX_RATE_HZ`].
    #[error("must be at most {MAX_RATE_HZ:e} Hz (one per microsecond), got {text}")]
    RateTooHigh {
        /// The text given.
        text: String,
    },
    /// A rate so low that its period is longer than any wait.
    #[error(
        "{text} Hz means one tick every {:.0e} s; the longest period is {MAX_WAIT_SECONDS:e} s",
        1.0 / hz
    )]
    PeriodTooLong {
        /// The text given.
        text: String,
        /// The rate read from it.
        hz: f64,
    },
    /// A simulation time outside the clock's range.
    #[error(
        "must be a finite number of seconds in 0..=18446744073 (the clock's range), got {text}"
    )]
    SimTime {
        /// The text given.
        text: String,
    },
    /// A value refused by a rule, with what else the flag accepts.
    #[error("{source}{hint}")]
    Hinted {
        /// The rule it broke.
        #[source]
        source: Box<InputError>,
        /// What else the flag accepts (`" (or 0: no limit)"`).
        hint: &'static str,
    },
    /// A `fixed_delta_seconds` the settings refuse.
    #[error("{source}; 0 means variable step, {}", StepRange)]
    FixedDelta {
        /// The settings rule it broke.
        #[source]
        source: SettingsError,
    },
    /// A variable step (0) where a fixed step is needed.
    #[error("must be a fixed step ({}), got {text}", StepRange)]
    NotFixedStep {
        /// The text given.
        text: String,
    },
    /// An `fps` the settings refuse (negative, not a number): the range
    /// says what it must be, once.
    #[error("fps = {} is {}: {}", Exact(*fps), if fps.is_finite() { "negative" } else { "not a finite number" }, FpsRange)]
    Fps {
        /// The rate given.
        fps: f64,
        /// The settings rule it broke.
        rule: SettingsError,
    },
    /// An `fps` whose step `1/fps` is out of the settings' range.
    #[error("fps = {} is out of range: {}", Exact(*fps), FpsRange)]
    FpsOutOfRange {
        /// The rate given.
        fps: f64,
    },
    /// A `max_substep_delta_time` the settings refuse.
    #[error(
        "{source}; the range is {}..={} s",
        Readable(MIN_DELTA_SECONDS),
        Readable(MAX_DELTA_SECONDS)
    )]
    MaxSubstepDelta {
        /// The settings rule it broke.
        #[source]
        source: SettingsError,
    },
    /// Not a whole number of microseconds.
    #[error("must be a whole number of microseconds >= 0, got {text}")]
    NotMicros {
        /// The text given.
        text: String,
    },
    /// More microseconds than any wait.
    #[error("must be at most {MAX_WAIT_SECONDS:e} seconds, got {text} µs")]
    MicrosTooLong {
        /// The text given.
        text: String,
    },
    /// A distance that is not positive, not finite, or above
    /// [`MAX_DISTANCE_METRES`].
    #[error(
        "must be a positive, finite number of metres, at most {}, got {text}",
        Readable(MAX_DISTANCE_METRES)
    )]
    Metres {
        /// The text given.
        text: String,
    },
    /// A field of view outside (0, 180) degrees.
    #[error("must be a finite number of degrees above 0 and below 180, got {text}")]
    FieldOfView {
        /// The text given.
        text: String,
    },
    /// Not `W,H` with each side in `1..=`[`MAX_IMAGE_SIDE`].
    #[error("must be W,H: two whole numbers of pixels in 1..={MAX_IMAGE_SIDE}, got '{text}'")]
    ImageSize {
        /// The text given.
        text: String,
    },
    /// Not `x,y,z` within ±[`MAX_ACTOR_POSITION`] m of the origin.
    #[error(
        "must be x,y,z: three finite numbers within +-{MAX_ACTOR_POSITION} m of the origin, got '{text}'"
    )]
    Position {
        /// The text given.
        text: String,
    },
    /// Not a scene the server knows.
    #[error(transparent)]
    Scene(#[from] SceneNameError),
}

impl InputError {
    /// This error, followed by `hint` (what else the flag accepts).
    pub(super) fn hinted(self, hint: &'static str) -> Self {
        Self::Hinted {
            source: Box::new(self),
            hint,
        }
    }
}

/// `in A..=B`, or `>= A` when there is no upper bound.
struct WholeRange(u64, u64);

impl fmt::Display for WholeRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match *self {
            WholeRange(start, u64::MAX) => write!(f, ">= {start}"),
            WholeRange(start, end) => write!(f, "in {start}..={end}"),
        }
    }
}

/// The settings' range of a fixed step, in words.
struct StepRange;

impl fmt::Display for StepRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "a fixed step is {}..={} s",
            Readable(MIN_DELTA_SECONDS),
            Readable(MAX_DELTA_SECONDS)
        )
    }
}

/// The range of `fps`, in words.
struct FpsRange;

impl fmt::Display for FpsRange {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        write!(
            f,
            "it must be 0 (variable step) or in {}..={} ({StepRange})",
            Readable(1.0 / MAX_DELTA_SECONDS),
            Readable(1.0 / MIN_DELTA_SECONDS),
        )
    }
}

#[cfg(test)]
mod tests {
    use std::error::Error as _;

    use super::*;
    use crate::*;
    use shared_types::WorldSettings;
    use shared_types::{MAX_KEYFRAME_SECONDS, MIN_KEYFRAME_SECONDS};

    fn message<T: fmt::Debug>(result: Result<T, InputError>) -> String {
        result.unwrap_err().to_string()
    }

    #[test]
    fn every_refusal_reads_as_it_did_when_it_was_a_string() {
        let settings = |s: WorldSettings| s.validate().unwrap_err().to_string();
        let negative_step = settings(WorldSettings {
            fixed_delta_seconds: Some(-1.0),
            substepping: false,
            ..WorldSettings::default()
        });
        let zero_substep = settings(WorldSettings {
            max_substep_delta_time: 0.0,
            ..WorldSettings::default()
        });
        let cases = [
            (message(timeout("abc")), "'abc' is not a number".to_owned()),
            (
                message(timeout("0")),
                "must be a positive, finite number of seconds, got 0".to_owned(),
            ),
            (
                message(timeout("1e20")),
                "must be at most 1e9 seconds (about 31 years), got 1e20".to_owned(),
            ),
            (
                message(wait(-1.0)),
                "must be a finite number of seconds >= 0".to_owned(),
            ),
            (
                message(rate("0")),
                "must be a positive, finite number of Hz, at most 1e6, got 0".to_owned(),
            ),
            (
                message(rate("2e6")),
                "must be at most 1e6 Hz (one per microsecond), got 2e6".to_owned(),
            ),
            (
                message(rate("1e-30")),
                "1e-30 Hz means one tick every 1e30 s; the longest period is 1e9 s".to_owned(),
            ),
            (
                message(rate_limit("-1")),
                "must be a positive, finite number of Hz, at most 1e6, got -1 (or 0: no limit)"
                    .to_owned(),
            ),
            (
                message(sensor_tick("-1")),
                "must be a finite number of seconds in 0..=18446744073 (the clock's range), \
                 got -1; 0 captures every frame"
                    .to_owned(),
            ),
            (
                message(sim_offset("1e300")),
                "must be a finite number of seconds (negative: from the end) in \
                 -1.84467e10..=1.84467e10, got 1e300"
                    .to_owned(),
            ),
            (
                message(fixed_delta_seconds("-1")),
                format!("{negative_step}; 0 means variable step, a fixed step is 1e-6..=3600 s"),
            ),
            (
                message(fixed_step("0")),
                "must be a fixed step (a fixed step is 1e-6..=3600 s), got 0".to_owned(),
            ),
            (
                message(fps("1e-300")),
                "fps = 1e-300 is out of range: it must be 0 (variable step) or in \
                 0.000277778..=1e6 (a fixed step is 1e-6..=3600 s)"
                    .to_owned(),
            ),
            (
                message(max_substep_delta_time("0")),
                format!("{zero_substep}; the range is 1e-6..=3600 s"),
            ),
            (
                message(max_substeps("0")),
                "must be a whole number in 1..=16, got 0".to_owned(),
            ),
            (
                message(count("0")),
                "must be a whole number >= 1, got 0".to_owned(),
            ),
            (
                message(micros("x")),
                "must be a whole number of microseconds >= 0, got x".to_owned(),
            ),
            (
                message(micros("1000000000000000000")),
                "must be at most 1e9 seconds, got 1000000000000000000 µs".to_owned(),
            ),
            (
                message(metres("0")),
                "must be a positive, finite number of metres, at most 1e6, got 0".to_owned(),
            ),
            (
                message(hybrid_window("-1")),
                "must be a whole number in 0..=1000000, got -1 (microseconds; 0 sleeps at once)"
                    .to_owned(),
            ),
            (
                message(keyframe_seconds("0")),
                format!(
                    "must be a finite number of seconds in {}..={}, got 0",
                    Readable(MIN_KEYFRAME_SECONDS),
                    Readable(MAX_KEYFRAME_SECONDS)
                ),
            ),
            (
                message(time_factor("0")),
                "must be a finite number (times the recording's speed) in 0.001..=1000, got 0"
                    .to_owned(),
            ),
            (
                message(refresh_interval("0")),
                "must be a finite number of seconds in 0.05..=3600, got 0".to_owned(),
            ),
            (
                message(field_of_view("180")),
                "must be a finite number of degrees above 0 and below 180, got 180".to_owned(),
            ),
            (
                message(rotation_frequency("-1")),
                "must be a finite number of Hz (0: a full turn every capture) in 0..=1e6, got -1"
                    .to_owned(),
            ),
            (
                message(image_size("0,1")),
                "must be W,H: two whole numbers of pixels in 1..=8192, got '0,1'".to_owned(),
            ),
            (
                message(position("1,2")),
                "must be x,y,z: three finite numbers within +-100000 m of the origin, got '1,2'"
                    .to_owned(),
            ),
            (
                message(scene("nope")),
                "unknown scene 'nope': expected 'default', 'empty', 'town', 'flat' or 'boxes:N'"
                    .to_owned(),
            ),
        ];
        for (got, want) in cases {
            assert_eq!(got, want);
        }
    }

    #[test]
    fn a_refusal_keeps_the_value_the_range_and_the_rule_it_broke() {
        assert_eq!(
            max_clients("0"),
            Err(InputError::NotWhole {
                text: "0".to_owned(),
                start: 1,
                end: 1024,
            })
        );
        assert_eq!(
            refresh_interval("9999"),
            Err(InputError::OutOfRange {
                text: "9999".to_owned(),
                start: 0.05,
                end: 3600.0,
                unit: " of seconds",
            })
        );
        // A settings rule stays a typed SettingsError, reachable as the source.
        let refused = fixed_delta_seconds("-1").unwrap_err();
        let InputError::FixedDelta { source } = &refused else {
            panic!("{refused:?}");
        };
        assert!(matches!(source, SettingsError::Negative { .. }));
        let cause = refused.source().expect("the settings error is the source");
        assert!(cause.downcast_ref::<SettingsError>().is_some());
        // A hint wraps the rule it adds to.
        let refused = rate_limit("-1").unwrap_err();
        let cause = refused.source().expect("the rate's own refusal");
        assert_eq!(
            cause.downcast_ref::<Box<InputError>>().map(|e| &**e),
            Some(&InputError::RateNotPositive {
                text: "-1".to_owned()
            })
        );
        assert!(matches!(
            scene("boxes:0"),
            Err(InputError::Scene(SceneNameError::BoxCount(_)))
        ));
    }
}
