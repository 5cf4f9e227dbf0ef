//! The value parsers: each turns what someone typed into a checked value,
//! or an [`InputError`] that says what was wrong.

use std::ops::RangeInclusive;
use std::time::Duration;

use shared_types::gnss::MAX_GNSS_SEED;
use shared_types::{MAX_IMAGE_SIDE, MAX_LIDAR_CHANNELS, MAX_LIDAR_POINTS};

use crate::bounds::*;
use crate::error::InputError;
use shared_types::limits::{
    FRAME_SUBSCRIBER_BUFFER, MAX_ACTOR_POSITION, MAX_MAX_CLIENTS, MAX_MAX_SENSOR_READERS,
    MAX_WAIT_SECONDS,
};
use shared_types::{
    WorldSettings, MAX_DELTA_SECONDS, MAX_KEYFRAME_SECONDS, MAX_SENSOR_TICK_SECONDS,
    MAX_SUBSTEPS_LIMIT, MIN_DELTA_SECONDS, MIN_KEYFRAME_SECONDS,
};

fn number(text: &str) -> Result<f64, InputError> {
    text.trim()
        .parse::<f64>()
        .map_err(|_| InputError::NotANumber {
            text: text.to_owned(),
        })
}

/// A finite number in `range`, or an error stating the range in `unit`.
fn real_in(text: &str, range: RangeInclusive<f64>, unit: &'static str) -> Result<f64, InputError> {
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
fn whole_in(text: &str, range: RangeInclusive<u64>) -> Result<u64, InputError> {
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

/// A sensor's range, metres: a [`metres`] value.
///
/// # Errors
///
/// Returns the errors of [`metres`]: [`InputError::NotANumber`] if `text` does
/// not read as a number, [`InputError::Metres`] if it is not a positive, finite
/// distance of at most [`MAX_DISTANCE_METRES`].
pub fn sensor_range(text: &str) -> Result<f32, InputError> {
    metres(text).map(|m| m as f32)
}

/// A depth camera's horizontal field of view, degrees: above 0, below 180.
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::FieldOfView`] if it is not finite, not above 0 or not below
/// 180.
pub fn field_of_view(text: &str) -> Result<f32, InputError> {
    let degrees = number(text)?;
    if degrees.is_finite() && degrees > 0.0 && degrees < 180.0 {
        return Ok(degrees as f32);
    }
    Err(InputError::FieldOfView {
        text: text.to_owned(),
    })
}

/// A lidar's channel count: `1..=`[`MAX_LIDAR_CHANNELS`].
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number in
/// `1..=`[`MAX_LIDAR_CHANNELS`].
pub fn lidar_channels(text: &str) -> Result<u32, InputError> {
    whole_in(text, 1..=u64::from(MAX_LIDAR_CHANNELS)).map(|n| n as u32)
}

/// A lidar's points per channel: `1..=`[`MAX_LIDAR_POINTS`].
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number in
/// `1..=`[`MAX_LIDAR_POINTS`].
pub fn lidar_points(text: &str) -> Result<u32, InputError> {
    whole_in(text, 1..=u64::from(MAX_LIDAR_POINTS)).map(|n| n as u32)
}

/// A GNSS receiver's noise seed: `0..=`[`MAX_GNSS_SEED`].
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number in
/// `0..=`[`MAX_GNSS_SEED`].
pub fn gnss_seed(text: &str) -> Result<u32, InputError> {
    whole_in(text, 0..=u64::from(MAX_GNSS_SEED)).map(|n| n as u32)
}

/// A radar's rays per simulated second:
/// `1..=`[`shared_types::ranging::MAX_RADAR_POINTS_PER_SECOND`].
///
/// # Errors
///
/// Returns [`InputError::NotWhole`] if `text` is not a whole number in
/// `1..=`[`shared_types::ranging::MAX_RADAR_POINTS_PER_SECOND`].
pub fn radar_points_per_second(text: &str) -> Result<u32, InputError> {
    let max = shared_types::ranging::MAX_RADAR_POINTS_PER_SECOND;
    whole_in(text, 1..=u64::from(max)).map(|n| n as u32)
}

/// A lidar's atmosphere attenuation rate, per metre: 0 up to
/// [`MAX_RATE_HZ`] (the intensity is `exp(-rate × distance)`).
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::OutOfRange`] if it is negative, not finite or above
/// [`MAX_RATE_HZ`].
pub fn attenuation_rate(text: &str) -> Result<f32, InputError> {
    real_in(text, 0.0..=MAX_RATE_HZ, " per metre").map(|rate| rate as f32)
}

/// An obstacle detector's hit radius, metres: above 0, at most 100.
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::OutOfRange`] if it is not finite, not above 0 or above 100.
pub fn hit_radius(text: &str) -> Result<f32, InputError> {
    let radius = number(text)?;
    if !(radius.is_finite() && radius > 0.0 && radius <= 100.0) {
        return Err(InputError::OutOfRange {
            text: text.to_owned(),
            start: 0.0,
            end: 100.0,
            unit: " of metres, above 0",
        });
    }
    Ok(radius as f32)
}

/// A lidar's rotation frequency: 0 (a full turn every capture) up to
/// [`MAX_RATE_HZ`].
///
/// # Errors
///
/// Returns [`InputError::NotANumber`] if `text` does not read as a number, and
/// [`InputError::OutOfRange`] if it is negative, not finite or above
/// [`MAX_RATE_HZ`].
pub fn rotation_frequency(text: &str) -> Result<f32, InputError> {
    real_in(
        text,
        0.0..=MAX_RATE_HZ,
        " of Hz (0: a full turn every capture)",
    )
    .map(|hz| hz as f32)
}

/// An image size `W,H` in pixels, each a whole number in
/// `1..=`[`MAX_IMAGE_SIDE`] (the spec's check bounds their product).
///
/// # Errors
///
/// Returns [`InputError::ImageSize`] if `text` is not two comma-separated whole
/// numbers, each in `1..=`[`MAX_IMAGE_SIDE`].
pub fn image_size(text: &str) -> Result<[u32; 2], InputError> {
    let refused = || InputError::ImageSize {
        text: text.to_owned(),
    };
    let sides: Vec<u32> = text
        .split(',')
        .map(|part| {
            whole_in(part, 1..=u64::from(MAX_IMAGE_SIDE))
                .ok()
                .map(|n| n as u32)
        })
        .collect::<Option<_>>()
        .ok_or_else(refused)?;
    sides.try_into().map_err(|_| refused())
}

/// A position `x,y,z` in metres, each within ±[`MAX_ACTOR_POSITION`] of
/// the origin (the world's reach).
///
/// # Errors
///
/// Returns [`InputError::Position`] if `text` is not three comma-separated
/// numbers, or if any of them is not finite or is further than
/// [`MAX_ACTOR_POSITION`] metres from the origin.
pub fn position(text: &str) -> Result<[f32; 3], InputError> {
    let refused = || InputError::Position {
        text: text.to_owned(),
    };
    let values: Vec<f64> = text
        .split(',')
        .map(|part| number(part).ok())
        .collect::<Option<_>>()
        .ok_or_else(refused)?;
    let limit = f64::from(MAX_ACTOR_POSITION);
    let [x, y, z]: [f64; 3] = values.try_into().map_err(|_| refused())?;
    if [x, y, z].iter().all(|v| v.is_finite() && v.abs() <= limit) {
        Ok([x as f32, y as f32, z as f32])
    } else {
        Err(refused())
    }
}

/// A scene name (`default`, `empty`, `town`, `flat` or `boxes:N`, N in
/// `1..=`[`MAX_SCENE_BOXES`](shared_types::scene::MAX_SCENE_BOXES)),
/// checked as the server reads it.
///
/// # Errors
///
/// Returns [`InputError::Scene`] holding the
/// [`SceneNameError`](shared_types::scene::SceneNameError): `Unknown` for a
/// name the server does not know, `BoxCount` for a `boxes:N` whose N is not a
/// whole number in
/// `1..=`[`MAX_SCENE_BOXES`](shared_types::scene::MAX_SCENE_BOXES).
pub fn scene(text: &str) -> Result<String, InputError> {
    let name = text.parse::<shared_types::scene::SceneName>()?;
    Ok(name.to_string())
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn huge_tiny_and_odd_values_are_refused_not_panicked_on() {
        assert_eq!(render_threads("3").unwrap().get(), 3);
        for refused in ["0", "-1", "1025", "1.5", "many", "18446744073709551616"] {
            assert!(render_threads(refused).is_err(), "{refused}");
        }
        assert!(timeout("1e20").is_err());
        assert!(timeout("0").is_err());
        assert!(timeout("-1").is_err());
        assert!(timeout("nan").is_err());
        assert!(timeout("inf").is_err());
        assert_eq!(timeout("1e9").unwrap(), Duration::from_secs(1_000_000_000));
        assert!(rate("1e-30")
            .unwrap_err()
            .to_string()
            .contains("one tick every"));
        assert!(rate("1e300")
            .unwrap_err()
            .to_string()
            .contains("at most 1e6 Hz"));
        assert_eq!(rate("20").unwrap(), 20.0);
        assert_eq!(rate_limit("0").unwrap(), 0.0);
        assert!(rate_limit("NaN").is_err());
        assert!(sim_time("inf").unwrap_err().to_string().contains("finite"));
        assert!(sim_time("-1").is_err());
        assert_eq!(sim_time("2.5").unwrap(), 2.5);
        assert_eq!(sim_offset("-2.5").unwrap(), -2.5);
        assert!(sim_offset("-1e300").is_err());
        assert!(max_substeps("-1")
            .unwrap_err()
            .to_string()
            .contains("1..=16"));
        assert!(max_substeps("17").is_err());
        assert!(max_substeps("99999999999999999999").is_err());
        assert_eq!(max_substeps("16").unwrap(), 16);
        assert!(wait(1e30).is_err());
        assert!(micros("-5").is_err());
        assert!(hybrid_window("99999999999")
            .unwrap_err()
            .to_string()
            .contains("0..=1000000"));
        assert_eq!(hybrid_window("0").unwrap(), Duration::ZERO);
        assert!(keyframe_seconds("NaN").is_err());
        assert!(keyframe_seconds("0").is_err());
        assert_eq!(keyframe_seconds("10").unwrap(), 10.0);
        assert!(count("0").unwrap_err().to_string().contains(">= 1"));
        assert_eq!(count("3").unwrap(), 3);
        assert!(max_clients("0")
            .unwrap_err()
            .to_string()
            .contains("1..=1024"));
        assert!(field_of_view("180").is_err());
        assert!(sensor_range("1e300").is_err());
        assert!(position("1e9,0,0")
            .unwrap_err()
            .to_string()
            .contains("+-100000 m"));
        assert!(position("NaN,0,0").is_err());
        assert!(position("1,2").is_err());
        assert_eq!(position("-1, 2,3").unwrap(), [-1.0, 2.0, 3.0]);
    }

    #[test]
    fn settings_flags_name_their_rule_and_range() {
        assert_eq!(fixed_delta_seconds("0").unwrap(), 0.0);
        let huge = fixed_delta_seconds("1e300").unwrap_err().to_string();
        assert!(
            huge.contains("1e300 s is longer than the maximum of 3600 s"),
            "{huge}"
        );
        assert!(huge.len() < 200, "no 300-digit numbers: {huge}");
        assert!(fixed_delta_seconds("-1")
            .unwrap_err()
            .to_string()
            .contains("negative"));
        assert!(fixed_delta_seconds("NaN")
            .unwrap_err()
            .to_string()
            .contains("not a finite number"));
        assert!(fixed_step("0")
            .unwrap_err()
            .to_string()
            .contains("1e-6..=3600 s"));
        assert_eq!(fps("0").unwrap(), 0.0);
        assert_eq!(fps("30").unwrap(), 30.0);
        let tiny = fps("1e-300").unwrap_err().to_string();
        assert!(tiny.contains("fps = 1e-300 is out of range"), "{tiny}");
        assert!(tiny.contains("0.000277778..=1e6"), "{tiny}");
        assert!(fps("1e300").is_err());
        // The range said once (issue 44, item 12: "it must be" twice).
        assert_eq!(
            fps("-20").unwrap_err().to_string(),
            "fps = -20 is negative: it must be 0 (variable step) or in 0.000277778..=1e6 \
             (a fixed step is 1e-6..=3600 s)"
        );
        assert!(max_substep_delta_time("0")
            .unwrap_err()
            .to_string()
            .contains("1e-6..=3600 s"));
    }

    #[test]
    fn sensor_flags_accept_exactly_what_a_spec_accepts() {
        let side = format!("{MAX_IMAGE_SIDE}");
        assert_eq!(image_size(&format!("{side},1")), Ok([MAX_IMAGE_SIDE, 1]));
        assert!(image_size(&format!("{},1", MAX_IMAGE_SIDE + 1)).is_err());
        let channels = format!("{}", MAX_LIDAR_CHANNELS + 1);
        assert!(lidar_channels(&channels).is_err());
        let points = format!("{}", MAX_LIDAR_POINTS + 1);
        assert!(lidar_points(&points).is_err());
    }
}
