//! The control command classes: `ApplyVehicleControl` and
//! `ApplyWalkerControl` (CARLA's `VehicleControl` and `WalkerControl`).

use pyo3::prelude::*;
use shared_types::Command as Wire;

use super::commands::{actor_id, finite, flag, numbers, subclass, triple, Command};

/// Drives a vehicle: `throttle` 0..1, `steer` -1..1 (positive: left),
/// `brake` 0..1, `hand_brake`, `reverse` (the reverse gear). Holds until
/// changed.
#[pyclass(module = "simbus", extends = Command, frozen)]
#[derive(Debug)]
pub(crate) struct ApplyVehicleControl;

#[pymethods]
impl ApplyVehicleControl {
    #[new]
    #[pyo3(signature = (actor_id, throttle = 0.0, steer = 0.0, brake = 0.0, hand_brake = false, reverse = false))]
    fn new(
        actor_id: &Bound<'_, PyAny>,
        throttle: f64,
        steer: f64,
        brake: f64,
        hand_brake: bool,
        reverse: bool,
    ) -> PyResult<PyClassInitializer<Self>> {
        let wire = Wire::vehicle_control(
            self::actor_id(actor_id)?,
            finite("throttle", throttle)?,
            finite("steer", steer)?,
            finite("brake", brake)?,
            hand_brake,
        )
        .in_reverse(reverse);
        Ok(subclass(Self, wire))
    }

    /// Throttle, 0..1.
    #[getter]
    fn throttle(slf: PyRef<'_, Self>) -> f32 {
        slf.as_ref().wire.params[0]
    }

    /// Steer, -1..1 (positive: left).
    #[getter]
    fn steer(slf: PyRef<'_, Self>) -> f32 {
        slf.as_ref().wire.params[1]
    }

    /// Brake, 0..1.
    #[getter]
    fn brake(slf: PyRef<'_, Self>) -> f32 {
        slf.as_ref().wire.params[2]
    }

    /// The hand brake.
    #[getter]
    fn hand_brake(slf: PyRef<'_, Self>) -> bool {
        flag(&slf.as_ref().wire)
    }

    /// The reverse gear.
    #[getter]
    fn reverse(slf: PyRef<'_, Self>) -> bool {
        slf.as_ref().wire.flags & Wire::REVERSE != 0
    }
}

/// Walks a walker: `direction` (x, y, z; its horizontal part is used),
/// `speed` m/s (0..=20), `jump` once. Holds until changed (CARLA's
/// `WalkerControl`).
#[pyclass(module = "simbus", extends = Command, frozen)]
#[derive(Debug)]
pub(crate) struct ApplyWalkerControl;

#[pymethods]
impl ApplyWalkerControl {
    #[new]
    #[pyo3(signature = (actor_id, direction = None, speed = 0.0, jump = false))]
    fn new(
        actor_id: &Bound<'_, PyAny>,
        direction: Option<&Bound<'_, PyAny>>,
        speed: f64,
        jump: bool,
    ) -> PyResult<PyClassInitializer<Self>> {
        let direction = direction.map_or(Ok([1.0, 0.0, 0.0]), |d| numbers("direction", d))?;
        let wire = Wire::walker_control(
            self::actor_id(actor_id)?,
            direction,
            finite("speed", speed)?,
            jump,
        );
        Ok(subclass(Self, wire))
    }

    /// Direction (x, y, z).
    #[getter]
    fn direction(slf: PyRef<'_, Self>) -> (f32, f32, f32) {
        triple(slf.as_ref().wire.vector)
    }

    /// Speed, m/s.
    #[getter]
    fn speed(slf: PyRef<'_, Self>) -> f32 {
        slf.as_ref().wire.params[0]
    }

    /// A jump.
    #[getter]
    fn jump(slf: PyRef<'_, Self>) -> bool {
        flag(&slf.as_ref().wire)
    }
}

/// Drives a vehicle to a steering angle and a speed (CARLA's
/// `VehicleAckermannControl`): `steer` radians (positive: left) reached at
/// `steer_speed` rad/s (0: at once), `speed` m/s (negative: backwards)
/// reached at `acceleration` m/s² (0: as hard as it can). Holds until an
/// `ApplyVehicleControl` or another target replaces it.
#[pyclass(module = "simbus", extends = Command, frozen)]
#[derive(Debug)]
pub(crate) struct ApplyVehicleAckermannControl;

#[pymethods]
impl ApplyVehicleAckermannControl {
    #[new]
    #[pyo3(signature = (actor_id, steer = 0.0, steer_speed = 0.0, speed = 0.0, acceleration = 0.0))]
    fn new(
        actor_id: &Bound<'_, PyAny>,
        steer: f64,
        steer_speed: f64,
        speed: f64,
        acceleration: f64,
    ) -> PyResult<PyClassInitializer<Self>> {
        let wire = Wire::vehicle_ackermann(
            self::actor_id(actor_id)?,
            finite("steer", steer)?,
            finite("steer_speed", steer_speed)?,
            finite("speed", speed)?,
            finite("acceleration", acceleration)?,
        );
        Ok(subclass(Self, wire))
    }
}

/// Adds the control command classes to the extension module.
pub(super) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<ApplyVehicleControl>()?;
    m.add_class::<ApplyWalkerControl>()?;
    m.add_class::<ApplyVehicleAckermannControl>()?;
    Ok(())
}
