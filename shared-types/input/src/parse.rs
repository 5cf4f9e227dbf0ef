//! The value parsers: each turns what someone typed into a checked value,
//! or an [`InputError`] that says what was wrong.

use std::ops::RangeInclusive;
use std::time::Duration;

use crate::bounds::*;
use crate::error::InputError;
use shared_types::limits::{
    FRAME_SUBSCRIBER_BUFFER, MAX_MAX_CLIENTS, MAX_MAX_SENSOR_READERS, MAX_WAIT_SECONDS,
};
use shared_types::{
    WorldSettings, MAX_DELTA_SECONDS, MAX_KEYFRAME_SECONDS, MAX_SENSOR_TICK_SECONDS,
    MAX_SUBSTEPS_LIMIT, MIN_DELTA_SECONDS, MIN_KEYFRAME_SECONDS,
};

pub(crate) fn number(text: &str) -> Result<f64, InputError> {
    text.trim()
        .parse::<f64>()
        .map_err(|_| InputError::NotANumber {
            text: text.to_owned(),
        })
}

/// A finite number in `range`, or an error stating the range in `unit`.
pub(crate) fn real_in(
    text: &str,
    range: RangeInclusive<f64>,
    unit: &'static str,
) -> Result<f64, InputError> {
    let value = number(text)?;
    if value.is_finite() && range.contains(&value) {
        return Ok(value);
    }
    Err(InputError::OutOfRange {
        text: text.to_owned(),
        start: *range.start(),
        end: *range.end(),
        unit,
    })
}

/// A whole number in `range` (a decimal point, an exponent or a sign that
/// takes it out of range is refused with the range named).
pub(crate) fn whole_in(text: &str, range: RangeInclusive<u64>) -> Result<u64, InputError> {
    let out_of_range = || InputError::NotWhole {
        text: text.to_owned(),
        start: *range.start(),
        end: *range.end(),
    };
    let value: i128 = text.trim().parse().map_err(|_| out_of_range())?;
    u64::try_from(value)
        .ok()
        .filter(|n| range.contains(n))
        .ok_or_else(out_of_range)
}

/// A wait in seconds: finite, positive, at most [`MAX_WAIT_SECONDS`].
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number,
/// [`InputError::NotPositiveSeconds`] if it is zero, negative or not finite,
/// and [`InputError::Timeout`] (wrapping [`InputError::WaitTooLong`]) if it is
/// longer than [`MAX_WAIT_SECONDS`].
pub fn timeout(text: &str) -> Result<Duration, InputError> {
    let seconds = number(text)?;
    if !(seconds.is_finite() && seconds > 0.0) {
        return Err(InputError::NotPositiveSeconds {
            text: text.to_owned(),
        });
    }
    wait(seconds).map_err(|e| InputError::Timeout {
        text: text.to_owned(),
        source: Box::new(e),
    })
}

/// `seconds` as a [`Duration`] a clock can wait for: finite, not negative,
/// at most [`MAX_WAIT_SECONDS`].
///
/// # Errors
///
/// Returns [`InputError::WaitNotFinite`] if `seconds` is negative, NaN or
/// infinite, and [`InputError::WaitTooLong`] if it is longer than
/// [`MAX_WAIT_SECONDS`].
pub fn wait(seconds: f64) -> Result<Duration, InputError> {
    if !(seconds.is_finite() && seconds >= 0.0) {
        return Err(InputError::WaitNotFinite { seconds });
    }
    if seconds > MAX_WAIT_SECONDS {
        return Err(InputError::WaitTooLong { seconds });
    }
    Ok(Duration::from_secs_f64(seconds))
}

/// A rate in hertz: positive, at most [`MAX_RATE_HZ`], and with a period a
/// clock can wait for (at most one tick per [`MAX_WAIT_SECONDS`]).
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number,
/// [`InputError::RateNotPositive`] if it is zero, negative or not finite,
/// [`InputError::RateTooHigh`] if it is above [`MAX_RATE_HZ`], and
/// [`InputError::PeriodTooLong`] if one period (`1/hz`) is longer than
/// [`MAX_WAIT_SECONDS`].
pub fn rate(text: &str) -> Result<f64, InputError> {
    let hz = number(text)?;
    let text = text.to_owned();
    if !(hz.is_finite() && hz > 0.0) {
        return Err(InputError::RateNotPositive { text });
    }
    if hz > MAX_RATE_HZ {
        return Err(InputError::RateTooHigh { text });
    }
    if wait(1.0 / hz).is_err() {
        return Err(InputError::PeriodTooLong { text, hz });
    }
    Ok(hz)
}

/// A rate limit in hertz: 0 (no limit) or a [`rate`].
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number; any
/// other value [`rate`] refuses is returned as its error wrapped in
/// [`InputError::Hinted`] (the hint says that 0 means no limit).
pub fn rate_limit(text: &str) -> Result<f64, InputError> {
    match number(text)? {
        0.0 => Ok(0.0),
        _ => rate(text).map_err(|e| e.hinted(" (or 0: no limit)")),
    }
}

/// A simulation time in seconds the integer-nanosecond clock can reach:
/// finite, `0..=18446744073` s.
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::SimTime`] if it is negative, not finite, or beyond the clock's
/// range ([`MAX_SENSOR_TICK_SECONDS`]).
pub fn sim_time(text: &str) -> Result<f64, InputError> {
    let seconds = number(text)?;
    if !(seconds.is_finite() && (0.0..=MAX_SENSOR_TICK_SECONDS).contains(&seconds)) {
        return Err(InputError::SimTime {
            text: text.to_owned(),
        });
    }
    Ok(seconds)
}

/// An offset in simulation seconds, negative counting from the end:
/// finite, within the clock's range either way.
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::OutOfRange`] if it is not finite or further than
/// [`MAX_SENSOR_TICK_SECONDS`] from 0 either way.
pub fn sim_offset(text: &str) -> Result<f64, InputError> {
    real_in(
        text,
        -MAX_SENSOR_TICK_SECONDS..=MAX_SENSOR_TICK_SECONDS,
        " of seconds (negative: from the end)",
    )
}

/// A sensor's capture period: 0 (every frame) or up to the clock's range.
///
/// # Errors
///
/// Returns the error of [`sim_time`] wrapped in [`InputError::Hinted`] (the
/// hint says that 0 captures every frame) if `text` is not a number or is out
/// of the clock's range.
pub fn sensor_tick(text: &str) -> Result<f64, InputError> {
    sim_time(text).map_err(|e| e.hinted("; 0 captures every frame"))
}

/// Any number of seconds, negative and non-finite included, for values
/// that are checked later by rules that name themselves.
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number; any
/// number, even NaN or infinite, is accepted.
pub fn seconds(text: &str) -> Result<f64, InputError> {
    number(text)
}

/// `fixed_delta_seconds`: 0 (variable step) or a fixed step the settings
/// accept ([`MIN_DELTA_SECONDS`]`..=`[`MAX_DELTA_SECONDS`]); the error
/// names the settings rule.
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::FixedDelta`] (with the settings'
/// [`SettingsError`](shared_types::SettingsError) as its source) if the
/// settings refuse it as a fixed step: negative, not finite, or outside
/// [`MIN_DELTA_SECONDS`]`..=`[`MAX_DELTA_SECONDS`].
pub fn fixed_delta_seconds(text: &str) -> Result<f64, InputError> {
    let dt = number(text)?;
    let settings = WorldSettings {
        fixed_delta_seconds: Some(dt),
        substepping: false,
        ..WorldSettings::default()
    };
    settings
        .validate()
        .map_err(|source| InputError::FixedDelta { source })?;
    Ok(dt)
}

/// A fixed step that must be fixed (no 0): [`MIN_DELTA_SECONDS`]`..=`
/// [`MAX_DELTA_SECONDS`].
///
/// # Errors
///
/// Returns the errors of [`fixed_delta_seconds`] ([`InputError::NotANumber`],
/// [`InputError::FixedDelta`]), and [`InputError::NotFixedStep`] if `text` is 0
/// (a variable step).
pub fn fixed_step(text: &str) -> Result<f64, InputError> {
    match fixed_delta_seconds(text)? {
        0.0 => Err(InputError::NotFixedStep {
            text: text.to_owned(),
        }),
        dt => Ok(dt),
    }
}

/// `fps`: 0 (variable step) or a rate whose step `1/fps` the settings
/// accept, i.e. `1/`[`MAX_DELTA_SECONDS`]`..=1/`[`MIN_DELTA_SECONDS`].
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number,
/// [`InputError::Fps`] if it is negative or not finite, and
/// [`InputError::FpsOutOfRange`] if its step `1/fps` is outside
/// [`MIN_DELTA_SECONDS`]`..=`[`MAX_DELTA_SECONDS`].
pub fn fps(text: &str) -> Result<f64, InputError> {
    let fps = number(text)?;
    match WorldSettings::delta_from_fps(fps) {
        Err(rule) => Err(InputError::Fps { fps, rule }),
        Ok(None) => Ok(0.0),
        Ok(Some(dt)) if (MIN_DELTA_SECONDS..=MAX_DELTA_SECONDS).contains(&dt) => Ok(fps),
        Ok(Some(_)) => Err(InputError::FpsOutOfRange { fps }),
    }
}

/// `max_substep_delta_time`: [`MIN_DELTA_SECONDS`]`..=`[`MAX_DELTA_SECONDS`].
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::MaxSubstepDelta`] (with the settings'
/// [`SettingsError`](shared_types::SettingsError) as its source) if the
/// settings refuse it.
pub fn max_substep_delta_time(text: &str) -> Result<f64, InputError> {
    let dt = number(text)?;
    let settings = WorldSettings {
        max_substep_delta_time: dt,
        ..WorldSettings::default()
    };
    settings
        .validate()
        .map_err(|source| InputError::MaxSubstepDelta { source })?;
    Ok(dt)
}

/// `max_substeps`: a whole number in `1..=16`.
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number in
/// `1..=`[`MAX_SUBSTEPS_LIMIT`].
pub fn max_substeps(text: &str) -> Result<u32, InputError> {
    whole_in(text, 1..=u64::from(MAX_SUBSTEPS_LIMIT)).map(|n| n as u32)
}

/// A whole number of microseconds, at most [`MAX_WAIT_SECONDS`].
///
/// # Errors
///
/// Returns [`InputError::NotMicros`] if `text` is not a whole number of
/// microseconds (a sign, a decimal point or an exponent), and
/// [`InputError::MicrosTooLong`] if it is longer than [`MAX_WAIT_SECONDS`].
pub fn micros(text: &str) -> Result<Duration, InputError> {
    let value: u64 = text.trim().parse().map_err(|_| InputError::NotMicros {
        text: text.to_owned(),
    })?;
    if value as f64 / 1e6 > MAX_WAIT_SECONDS {
        return Err(InputError::MicrosTooLong {
            text: text.to_owned(),
        });
    }
    Ok(Duration::from_micros(value))
}

/// A distance in metres: positive, finite and at most
/// [`MAX_DISTANCE_METRES`] (`recorder blocked --min-distance`, sensor
/// ranges).
///
/// ```
/// use simbus_input::{metres, InputError};
///
/// assert_eq!(metres("0.1"), Ok(0.1));
/// let refused = metres("NaN").unwrap_err();
/// assert!(matches!(&refused, InputError::Metres { text } if text == "NaN"));
/// assert!(refused.to_string().contains("positive, finite number of metres"));
/// assert!(metres("0").is_err() && metres("inf").is_err() && metres("-1").is_err());
/// ```
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::Metres`] if it is not positive, not finite, or above
/// [`MAX_DISTANCE_METRES`].
pub fn metres(text: &str) -> Result<f64, InputError> {
    let value = number(text)?;
    if !(value.is_finite() && value > 0.0 && value <= MAX_DISTANCE_METRES) {
        return Err(InputError::Metres {
            text: text.to_owned(),
        });
    }
    Ok(value)
}

/// `--hybrid-window-us`: `0..=`[`MAX_HYBRID_WINDOW_MICROS`] microseconds
/// (0: sleep at once).
///
/// # Errors
///
/// Returns [`InputError::NotWhole`], wrapped in [`InputError::Hinted`], if
/// `text` is not a whole number in `0..=`[`MAX_HYBRID_WINDOW_MICROS`].
pub fn hybrid_window(text: &str) -> Result<Duration, InputError> {
    whole_in(text, 0..=MAX_HYBRID_WINDOW_MICROS)
        .map(Duration::from_micros)
        .map_err(|e| e.hinted(" (microseconds; 0 sleeps at once)"))
}

/// `--keyframe-seconds`: simulation seconds between keyframes,
/// [`MIN_KEYFRAME_SECONDS`]`..=`[`MAX_KEYFRAME_SECONDS`].
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::OutOfRange`] if it is not finite or outside
/// [`MIN_KEYFRAME_SECONDS`]`..=`[`MAX_KEYFRAME_SECONDS`].
pub fn keyframe_seconds(text: &str) -> Result<f64, InputError> {
    real_in(
        text,
        MIN_KEYFRAME_SECONDS..=MAX_KEYFRAME_SECONDS,
        " of seconds",
    )
}

/// A count that must be at least 1 (`--max-frames`, `--frames`,
/// `--captures`, `--every`: 0 would mean nothing).
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number of at least
/// 1.
pub fn count(text: &str) -> Result<u64, InputError> {
    whole_in(text, 1..=u64::MAX)
}

/// `watch --window`: how many frames a lockstep watcher that prints every
/// frame may fall behind, `0..=15`: its frame queue holds
/// [`FRAME_SUBSCRIBER_BUFFER`] frames, the one it reads and 15 more.
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number in
/// `0..=15`.
pub fn watch_window(text: &str) -> Result<u32, InputError> {
    whole_in(text, 0..=FRAME_SUBSCRIBER_BUFFER as u64 - 1).map(|n| n as u32)
}

/// `--max-clients`: `1..=`[`MAX_MAX_CLIENTS`].
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number in
/// `1..=`[`MAX_MAX_CLIENTS`].
pub fn max_clients(text: &str) -> Result<usize, InputError> {
    whole_in(text, 1..=MAX_MAX_CLIENTS as u64).map(|n| n as usize)
}

/// `--max-sensor-readers`: `1..=`[`MAX_MAX_SENSOR_READERS`].
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number in
/// `1..=`[`MAX_MAX_SENSOR_READERS`].
pub fn max_sensor_readers(text: &str) -> Result<usize, InputError> {
    whole_in(text, 1..=MAX_MAX_SENSOR_READERS as u64).map(|n| n as usize)
}

/// `--render-threads`: `1..=`[`MAX_RENDER_THREADS`].
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number in
/// `1..=`[`MAX_RENDER_THREADS`].
pub fn render_threads(text: &str) -> Result<std::num::NonZeroUsize, InputError> {
    whole_in(text, 1..=MAX_RENDER_THREADS as u64)
        .map(|n| std::num::NonZeroUsize::new(n as usize).unwrap_or(std::num::NonZeroUsize::MIN))
}

/// Lockstep participants to wait for: `0..=`[`MAX_MAX_CLIENTS`] (a world
/// admits no more).
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number in
/// `0..=`[`MAX_MAX_CLIENTS`].
pub fn participants(text: &str) -> Result<u32, InputError> {
    whole_in(text, 0..=MAX_MAX_CLIENTS as u64).map(|n| n as u32)
}

/// A replay's time factor: [`MIN_TIME_FACTOR`]`..=`[`MAX_TIME_FACTOR`].
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::OutOfRange`] if it is not finite or outside
/// [`MIN_TIME_FACTOR`]`..=`[`MAX_TIME_FACTOR`].
pub fn time_factor(text: &str) -> Result<f64, InputError> {
    real_in(
        text,
        MIN_TIME_FACTOR..=MAX_TIME_FACTOR,
        " (times the recording's speed)",
    )
}

/// `top --interval`: [`MIN_REFRESH_SECONDS`]`..=`[`MAX_REFRESH_SECONDS`].
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::OutOfRange`] if it is not finite or outside
/// [`MIN_REFRESH_SECONDS`]`..=`[`MAX_REFRESH_SECONDS`].
pub fn refresh_interval(text: &str) -> Result<f64, InputError> {
    real_in(
        text,
        MIN_REFRESH_SECONDS..=MAX_REFRESH_SECONDS,
        " of seconds",
    )
}

#[cfg(test)]
#[path = "parse_tests.rs"]
mod tests;
