//! The traffic-light command classes: `SetTrafficLightState`,
//! `SetTrafficLightTimes`, `FreezeTrafficLights`, `ResetTrafficLights`
//! (CARLA's `TrafficLight.set_state`, `set_green_time`…, `freeze`,
//! `reset_group`).

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use shared_types::{Command as Wire, CommandKind, LightState};

use super::commands::{actor_id, finite, flag, py_bool, subclass, Command};

/// A light state's name as a Python literal.
fn state_name(code: f32) -> String {
    let state = (code >= 0.0 && code.fract() == 0.0)
        .then(|| LightState::from_u32(code as u32))
        .flatten();
    state.map_or_else(|| format!("{code:?}"), |s| format!("'{}'", s.name()))
}

/// A traffic-light command as the Python expression that builds it.
pub(super) fn describe(kind: CommandKind, w: &Wire) -> String {
    let id = w.actor;
    match kind {
        CommandKind::TrafficLightState => {
            format!("SetTrafficLightState({id}, {})", state_name(w.params[0]))
        }
        CommandKind::TrafficLightTimes => {
            let time = |i: usize| {
                if w.flags & (1 << i) != 0 {
                    format!("{:?}", w.params[i])
                } else {
                    "None".to_owned()
                }
            };
            format!(
                "SetTrafficLightTimes({id}, green={}, yellow={}, red={})",
                time(0),
                time(1),
                time(2)
            )
        }
        CommandKind::FreezeTrafficLights => {
            format!("FreezeTrafficLights({}, actor_id={id})", py_bool(flag(w)))
        }
        _ => format!("ResetTrafficLights(actor_id={id})"),
    }
}

/// Shows `state` (`"red"`, `"yellow"`, `"green"` or `"off"`) on traffic
/// light `actor_id` until its junction's cycle next changes that light
/// (CARLA's `TrafficLight.set_state`; freeze the lights to keep it).
#[pyclass(module = "simbus", extends = Command, frozen)]
#[derive(Debug)]
pub(crate) struct SetTrafficLightState;

#[pymethods]
impl SetTrafficLightState {
    #[new]
    fn new(actor_id: &Bound<'_, PyAny>, state: &str) -> PyResult<PyClassInitializer<Self>> {
        let Some(state) = LightState::from_name(state) else {
            return Err(PyValueError::new_err(format!(
                "unknown light state '{state}': expected 'red', 'yellow', 'green' or 'off'"
            )));
        };
        let wire = Wire::traffic_light_state(self::actor_id(actor_id)?, state);
        Ok(subclass(Self, wire))
    }
}

/// Sets how long traffic light `actor_id` stays `green`, `yellow` and
/// `red` (seconds, 0 to 1 000 000); a time left `None` stays as it is.
#[pyclass(module = "simbus", extends = Command, frozen)]
#[derive(Debug)]
pub(crate) struct SetTrafficLightTimes;

#[pymethods]
impl SetTrafficLightTimes {
    #[new]
    #[pyo3(signature = (actor_id, *, green = None, yellow = None, red = None))]
    fn new(
        actor_id: &Bound<'_, PyAny>,
        green: Option<f64>,
        yellow: Option<f64>,
        red: Option<f64>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let time = |name, t: Option<f64>| t.map(|t| finite(name, t)).transpose();
        let times = [
            time("green", green)?,
            time("yellow", yellow)?,
            time("red", red)?,
        ];
        let wire = Wire::traffic_light_times(self::actor_id(actor_id)?, times);
        Ok(subclass(Self, wire))
    }
}

/// Freezes (`frozen` true) or unfreezes the traffic lights where they
/// are: those of traffic light `actor_id`'s junction, or with `actor_id`
/// 0 (the default) every light.
#[pyclass(module = "simbus", extends = Command, frozen)]
#[derive(Debug)]
pub(crate) struct FreezeTrafficLights;

#[pymethods]
impl FreezeTrafficLights {
    #[new]
    #[pyo3(signature = (frozen, actor_id = None))]
    fn new(
        frozen: bool,
        actor_id: Option<&Bound<'_, PyAny>>,
    ) -> PyResult<PyClassInitializer<Self>> {
        let actor = actor_id.map_or(Ok(0), |a| self::actor_id(a))?;
        Ok(subclass(Self, Wire::freeze_traffic_lights(actor, frozen)))
    }
}

/// Starts the cycle of traffic light `actor_id`'s junction again (its
/// first light green, the others red), or with `actor_id` 0 (the
/// default) every junction's.
#[pyclass(module = "simbus", extends = Command, frozen)]
#[derive(Debug)]
pub(crate) struct ResetTrafficLights;

#[pymethods]
impl ResetTrafficLights {
    #[new]
    #[pyo3(signature = (actor_id = None))]
    fn new(actor_id: Option<&Bound<'_, PyAny>>) -> PyResult<PyClassInitializer<Self>> {
        let actor = actor_id.map_or(Ok(0), |a| self::actor_id(a))?;
        Ok(subclass(Self, Wire::reset_traffic_lights(actor)))
    }
}

/// Adds the traffic-light command classes to the extension module.
pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<SetTrafficLightState>()?;
    m.add_class::<SetTrafficLightTimes>()?;
    m.add_class::<FreezeTrafficLights>()?;
    m.add_class::<ResetTrafficLights>()?;
    Ok(())
}
