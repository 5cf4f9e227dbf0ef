//! What the sensor subcommands share (`sensor` and `sensor save`): the
//! wait for a sensor's next capture and the exit a sensor error gives.

use std::time::Duration;

use sim_client::{Capture, Sensor, SensorError, WaitError};

use crate::cli::failure::Failure;

/// A sensor error as the command's exit: refused (2) for what the server
/// refused or does not know, a runtime failure (1) otherwise.
pub(super) fn failure(e: SensorError) -> Failure {
    match e {
        SensorError::Refused(_) | SensorError::UnknownSensor { .. } => Failure::Refused(e.into()),
        e => Failure::Runtime(e.into()),
    }
}

/// The next capture within `timeout`; `None` when interrupted.
pub(super) fn next_capture(
    sensor: &mut Sensor,
    timeout: Duration,
) -> Result<Option<Capture>, WaitError> {
    super::interrupt::in_slices(timeout, |slice| sensor.recv(slice))
}
