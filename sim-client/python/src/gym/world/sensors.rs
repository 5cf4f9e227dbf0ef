//! The egos' sensors: an RGB camera and a lidar on each ego when the task
//! asks, their captures of the frame read copied into the caller's batch
//! arrays (one copy: the camera's BGRA to RGB, the lidar's points into
//! padded rows).

use numpy::{PyReadwriteArray3, PyReadwriteArray4};
use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use shared_types::{SensorKind, SensorSpec};
use sim_client::{Capture, Sensor};

use super::{error, DrivingWorld};
use crate::errors;

/// Where an ego's camera and lidar ride (X forward, Y up, Z right, metres).
const CAMERA_MOUNT: [f32; 3] = [0.5, 1.6, 0.0];
const LIDAR_MOUNT: [f32; 3] = [0.0, 2.0, 0.0];
/// The lidar's range and field of view (degrees), CARLA's defaults'.
const LIDAR_RANGE: f32 = 50.0;
const LIDAR_FOV: (f32, f32) = (10.0, -30.0);

/// The arrays a step's sensor captures are written into: `camera` (ego,
/// height, width, RGB) and `lidar` (ego, point, x/y/z/intensity).
#[derive(Debug, Default)]
pub(crate) struct Captures<'py> {
    pub(crate) camera: Option<PyReadwriteArray4<'py, u8>>,
    pub(crate) lidar: Option<PyReadwriteArray3<'py, f32>>,
}

/// One ego's sensor: its id and its reader (none until opened).
#[derive(Debug)]
pub(crate) struct EgoSensor {
    id: u64,
    reader: Option<Sensor>,
}

impl DrivingWorld {
    /// Spawns each ego's camera and lidar, as the task asks.
    pub(super) fn spawn_sensors(&mut self) -> PyResult<()> {
        for ego in &self.egos {
            if let Some((width, height)) = self.camera_size {
                let spec = SensorSpec::camera_of(
                    SensorKind::Rgb,
                    CAMERA_MOUNT,
                    (width, height),
                    90.0,
                    1000.0,
                )
                .ok_or_else(|| PyValueError::new_err("no such camera"))?
                .attached_to(ego.id);
                let sensor = self.client.spawn_sensor(spec).map_err(error)?;
                self.cameras.push(EgoSensor {
                    id: sensor.id(),
                    reader: None,
                });
            }
            if let Some((channels, points)) = self.lidar_size {
                let (upper, lower) = LIDAR_FOV;
                let spec =
                    SensorSpec::lidar(LIDAR_MOUNT, channels, points, LIDAR_RANGE, upper, lower)
                        .attached_to(ego.id);
                let sensor = self.client.spawn_sensor(spec).map_err(error)?;
                self.lidars.push(EgoSensor {
                    id: sensor.id(),
                    reader: None,
                });
            }
        }
        Ok(())
    }

    /// Opens the sensors' readers again (a restore ends them; they come
    /// back under their ids).
    pub(super) fn reopen_sensors(&mut self) -> PyResult<()> {
        for sensor in self.cameras.iter_mut().chain(self.lidars.iter_mut()) {
            sensor.reader = None;
            sensor.reader = Some(self.client.sensor(sensor.id).map_err(error)?);
        }
        Ok(())
    }

    /// Closes every reader.
    pub(super) fn close_sensors(&mut self) {
        for sensor in self.cameras.iter_mut().chain(self.lidars.iter_mut()) {
            sensor.reader = None;
        }
    }

    /// Copies each ego sensor's capture of the frame read into `into`.
    pub(super) fn capture(&mut self, into: Captures<'_>) -> PyResult<()> {
        let (frame, timeout) = (self.frame, self.timeout);
        if let Some(mut images) = into.camera {
            let mut images = images.as_array_mut();
            for (i, sensor) in self.cameras.iter_mut().enumerate() {
                let Some(capture) = capture_of(sensor, frame, timeout)? else {
                    continue;
                };
                let pixels = capture.image().unwrap_or(&[]);
                let mut image = images.index_axis_mut(numpy::ndarray::Axis(0), i);
                let rgb = image
                    .as_slice_mut()
                    .filter(|rgb| rgb.len() == pixels.len() * 3)
                    .ok_or_else(|| {
                        PyValueError::new_err(
                            "the camera array is not the camera's size (contiguous)",
                        )
                    })?;
                for (dst, p) in rgb.chunks_exact_mut(3).zip(pixels) {
                    dst.copy_from_slice(&[p.r, p.g, p.b]);
                }
            }
        }
        if let Some(mut clouds) = into.lidar {
            let mut clouds = clouds.as_array_mut();
            for (i, sensor) in self.lidars.iter_mut().enumerate() {
                let Some(capture) = capture_of(sensor, frame, timeout)? else {
                    continue;
                };
                let points = capture.points().unwrap_or(&[]);
                let mut cloud = clouds.index_axis_mut(numpy::ndarray::Axis(0), i);
                let rows = cloud
                    .as_slice_mut()
                    .ok_or_else(|| PyValueError::new_err("the lidar array must be contiguous"))?;
                rows.fill(0.0);
                for (dst, p) in rows.chunks_exact_mut(4).zip(points) {
                    dst.copy_from_slice(&[p.x, p.y, p.z, p.intensity]);
                }
            }
        }
        Ok(())
    }
}

/// The capture of frame `frame` (or later) of `sensor`, passing over older ones.
fn capture_of(
    sensor: &mut EgoSensor,
    frame: u64,
    timeout: std::time::Duration,
) -> PyResult<Option<Capture>> {
    let Some(reader) = sensor.reader.as_mut() else {
        return Ok(None);
    };
    loop {
        let capture = reader.recv(timeout).map_err(errors::wait)?;
        if capture.header().frame >= frame {
            return Ok(Some(capture));
        }
    }
}
