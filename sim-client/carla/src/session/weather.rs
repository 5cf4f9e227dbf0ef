//! The weather: CARLA's `world.set_weather` / `world.get_weather`. The
//! gateway keeps the whole weather CARLA clients set (one per gateway,
//! CARLA's `ClearNoon` until set) and answers it back; its sun (azimuth and
//! altitude) moves the server's sun, which lights the RGB cameras. Clouds,
//! rain, fog and the rest change nothing in simbus's images.

use rmpv::Value;
use shared_types::{Command, CommandStatus, Sun};

use super::Session;
use crate::commands::number;
use crate::error::CallError;
use crate::locks::lock;
use crate::rpc::Answer;
use crate::wire::{Weather, CLEAR_NOON};

/// Where the sun's angles are in CARLA's `WeatherParameters`.
const SUN_AZIMUTH: usize = 4;
const SUN_ALTITUDE: usize = 5;

/// CARLA's `WeatherParameters` from its msgpack array: 14 finite numbers.
fn parse(v: &Value) -> Option<Weather> {
    let fields = v.as_array()?;
    if fields.len() != CLEAR_NOON.len() {
        return None;
    }
    let mut weather = CLEAR_NOON;
    for (slot, field) in weather.iter_mut().zip(fields) {
        let x = number(field)? as f32;
        if !x.is_finite() {
            return None;
        }
        *slot = x;
    }
    Some(weather)
}

impl Session {
    /// Keeps the weather a script sets; refuses another shape, changing
    /// nothing.
    pub(super) fn on_set_weather_parameters(
        &mut self,
        args: &[Value],
    ) -> Result<Answer, CallError> {
        let weather = args.first().and_then(parse).ok_or(CallError::Shape {
            method: "set_weather_parameters",
            what: "weather parameters of the wrong shape (14 finite numbers)",
        })?;
        let sun = Sun {
            azimuth: weather[SUN_AZIMUTH],
            altitude: weather[SUN_ALTITUDE],
        };
        let results = self
            .client()?
            .apply_batch_sync(&[Command::set_sun(sun)], false)
            .map_err(CallError::simbus)?;
        if let Some(refused) = results
            .results
            .iter()
            .find(|r| r.status != CommandStatus::Ok as u32)
        {
            let status =
                CommandStatus::from_u32(refused.status).unwrap_or(CommandStatus::UnknownCommand);
            return Err(CallError::SunRefused(status));
        }
        *lock(&self.hub.weather) = weather;
        Ok(Answer::Done)
    }

    /// The weather last set (CARLA's `ClearNoon` until then).
    pub(super) fn on_get_weather_parameters(&mut self, _: &[Value]) -> Result<Answer, CallError> {
        let weather = *lock(&self.hub.weather);
        Ok(Answer::Value(Value::Array(
            weather.into_iter().map(Value::F32).collect(),
        )))
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn weather_reads_fourteen_finite_numbers_and_nothing_else() {
        let fields = |n: usize| Value::Array((0..n).map(|i| Value::from(i as f64)).collect());
        let weather = parse(&fields(14)).expect("fourteen numbers");
        assert_eq!(weather[13], 13.0);
        assert!(parse(&fields(13)).is_none());
        assert!(parse(&fields(15)).is_none());
        let mut nan = vec![Value::F32(0.0); 14];
        nan[3] = Value::F64(f64::NAN);
        assert!(parse(&Value::Array(nan)).is_none());
        assert!(parse(&Value::from("sunny")).is_none());
    }
}
