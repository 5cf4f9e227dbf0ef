//! Checked conversions of numbers people type (seconds, rates, counts) into
//! the values simbus uses. Both command lines parse their flags with these,
//! so a bad value is refused with the same words everywhere, before anything
//! changes, instead of panicking in a conversion.
//!
//! Each function has the shape clap's `value_parser` takes.
//!
//! ```
//! use shared_types::input::{timeout, max_substeps};
//!
//! assert_eq!(timeout("2.5").unwrap().as_millis(), 2500);
//! assert!(timeout("1e20").unwrap_err().contains("at most"));
//! assert!(max_substeps("-1").unwrap_err().contains("1..=16"));
//! ```

use std::time::Duration;

use crate::limits::MAX_WAIT_SECONDS;
use crate::MAX_SUBSTEPS_LIMIT;

fn number(text: &str) -> Result<f64, String> {
    text.trim()
        .parse::<f64>()
        .map_err(|_| format!("'{text}' is not a number"))
}

/// A wait in seconds: finite, positive, at most [`MAX_WAIT_SECONDS`].
pub fn timeout(text: &str) -> Result<Duration, String> {
    let seconds = number(text)?;
    if !(seconds.is_finite() && seconds > 0.0) {
        return Err(format!(
            "must be a positive, finite number of seconds, got {text}"
        ));
    }
    wait(seconds).map_err(|e| format!("{e}, got {text}"))
}

/// `seconds` as a [`Duration`] a clock can wait for: finite, not negative,
/// at most [`MAX_WAIT_SECONDS`].
pub fn wait(seconds: f64) -> Result<Duration, String> {
    if !(seconds.is_finite() && seconds >= 0.0) {
        return Err("must be a finite number of seconds >= 0".to_owned());
    }
    if seconds > MAX_WAIT_SECONDS {
        return Err(format!(
            "must be at most {MAX_WAIT_SECONDS:e} seconds (about 31 years)"
        ));
    }
    Ok(Duration::from_secs_f64(seconds))
}

/// A rate in hertz whose period a clock can wait for (at most one tick per
/// [`MAX_WAIT_SECONDS`]).
pub fn rate(text: &str) -> Result<f64, String> {
    let hz = number(text)?;
    if !(hz.is_finite() && hz > 0.0) {
        return Err(format!(
            "must be a positive, finite number of Hz, got {text}"
        ));
    }
    wait(1.0 / hz).map_err(|_| {
        format!(
            "{text} Hz means one tick every {:.0e} s; the longest period is {MAX_WAIT_SECONDS:e} s",
            1.0 / hz
        )
    })?;
    Ok(hz)
}

/// A simulation time in seconds the integer-nanosecond clock can reach:
/// finite, `0..=18446744073` s.
pub fn sim_time(text: &str) -> Result<f64, String> {
    let seconds = number(text)?;
    if !(seconds.is_finite() && (0.0..=crate::MAX_SENSOR_TICK_SECONDS).contains(&seconds)) {
        return Err(format!(
            "must be a finite number of seconds in 0..=18446744073 (the clock's range), got {text}"
        ));
    }
    Ok(seconds)
}

/// Any number of seconds, negative and non-finite included, for settings
/// that the settings rules check themselves (their error names the rule).
pub fn seconds(text: &str) -> Result<f64, String> {
    number(text)
}

/// `max_substeps`: a whole number in `1..=16`.
pub fn max_substeps(text: &str) -> Result<u32, String> {
    let out_of_range = || format!("must be a whole number in 1..={MAX_SUBSTEPS_LIMIT}, got {text}");
    let value: i128 = text.trim().parse().map_err(|_| out_of_range())?;
    u32::try_from(value)
        .ok()
        .filter(|n| (1..=MAX_SUBSTEPS_LIMIT).contains(n))
        .ok_or_else(out_of_range)
}

/// A whole number of microseconds, at most [`MAX_WAIT_SECONDS`].
pub fn micros(text: &str) -> Result<Duration, String> {
    let value: u64 = text
        .trim()
        .parse()
        .map_err(|_| format!("must be a whole number of microseconds >= 0, got {text}"))?;
    if value as f64 / 1e6 > MAX_WAIT_SECONDS {
        return Err(format!(
            "must be at most {MAX_WAIT_SECONDS:e} seconds, got {text} µs"
        ));
    }
    Ok(Duration::from_micros(value))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huge_tiny_and_odd_values_are_refused_not_panicked_on() {
        assert!(timeout("1e20").is_err());
        assert!(timeout("0").is_err());
        assert!(timeout("-1").is_err());
        assert!(timeout("nan").is_err());
        assert!(timeout("inf").is_err());
        assert_eq!(timeout("1e9").unwrap(), Duration::from_secs(1_000_000_000));
        assert!(rate("1e-30").unwrap_err().contains("one tick every"));
        assert_eq!(rate("20").unwrap(), 20.0);
        assert!(sim_time("inf").unwrap_err().contains("finite"));
        assert!(sim_time("-1").is_err());
        assert_eq!(sim_time("2.5").unwrap(), 2.5);
        assert!(max_substeps("-1").unwrap_err().contains("1..=16"));
        assert!(max_substeps("17").is_err());
        assert!(max_substeps("99999999999999999999").is_err());
        assert_eq!(max_substeps("16").unwrap(), 16);
        assert!(wait(1e30).is_err());
        assert!(micros("-5").is_err());
    }
}
