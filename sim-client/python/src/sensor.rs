//! Sensors: spawning them (`client.spawn_sensor(...)`), reading captures
//! as numpy arrays over the capture's shared memory ([`Capture`]), and
//! listening on a thread of their own ([`Listening`]).
//!
//! A capture's arrays view the sample the server lent, through a
//! [`Loan`] that is the arrays' base object: no copy, and no array outlives
//! its sample. The sample belongs to the thread that received it (iceoryx2's
//! samples do), so the arrays are read there; a capture's other values
//! (frame, pose, ...) and `copy()`'s arrays may go anywhere.

mod capture;
mod listen;
mod spec;

use std::collections::HashMap;

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use shared_types::{SensorInfo as Info, SensorKind, SensorParams, SensorRefusal};
use sim_client::{SensorError, WaitError};

use self::capture::Capture;
use self::listen::Listening;
use self::spec::{spec_for, SpawnParams};
use crate::args::seconds;
use crate::client::Client;
use crate::errors::{self, message, raise};
use crate::gil::detached;

/// Adds this module's classes and functions to the extension module.
pub(crate) fn register(m: &Bound<'_, PyModule>) -> PyResult<()> {
    m.add_class::<Sensor>()?;
    m.add_class::<Capture>()?;
    m.add_class::<Listening>()?;
    m.add_class::<SensorInfo>()?;
    Ok(())
}

/// A sensor request's error as its exception: a spec that breaks a rule is
/// a `ValueError` (nothing was sent), a refusal (unknown actor or sensor)
/// a `simbus.CommandError`, a failed request as every request's.
fn sensor_error(error: SensorError) -> PyErr {
    // The Rust message says it all (a spec error is also its source).
    let text = error.to_string();
    match error {
        SensorError::InvalidSpec(_) => PyValueError::new_err(text),
        SensorError::Refused(SensorRefusal::NoMemory) => raise("Error", text),
        SensorError::Refused(_) | SensorError::UnknownSensor { .. } => raise("CommandError", text),
        SensorError::Request(e) => errors::request(e),
    }
}

/// A capture wait's error as its exception: `simbus.Full`, saying what to
/// do, when this reader holds as many captures as it may; the rest as
/// every wait's ([`errors::wait`]).
fn wait_error(sensor: u64, error: WaitError) -> PyErr {
    match &error {
        WaitError::Transport { source, .. } if errors::holds_all_it_may(source.as_ref()) => {
            raise(
                "Full",
                format!(
                    "this reader of sensor {sensor} already holds {MAX_HELD} captures: release() one (copy() what you keep), or delete the arrays that view it ({})",
                    message(&error)
                ),
            )
        }
        _ => errors::wait(error),
    }
}

/// How many captures one reader may hold at once (the sensor services'
/// `subscriber_borrowed`).
const MAX_HELD: usize = 2;

#[pymethods]
impl Client {
    /// Builds a sensor and subscribes to it: `kind` is `"depth"`, `"rgb"`,
    /// `"semantic"`, `"instance"`, `"lidar"`, `"semantic_lidar"`,
    /// `"radar"`, `"imu"`, `"gnss"`, `"collision"` or `"obstacle"`. It
    /// rides on actor
    /// `parent` (and dies with it) or, without one, stays fixed in the world; `at` is its position
    /// relative to the parent (X forward, Y up, Z right, metres; 2 m up by
    /// default), `rotation` its orientation relative to the parent as a
    /// quaternion (x, y, z, w), `sensor_tick` its capture
    /// period in simulation seconds (0: every frame). Cameras: `width`,
    /// `height` (640 x 480), horizontal `fov` in degrees (90), far `range`
    /// in metres (depth 100, the others 1000). Lidars (plain and
    /// semantic): `channels` (32), `points` per channel in a turn (512),
    /// `range` (50), `upper_fov`/`lower_fov` in degrees (10/-30),
    /// `rotation_frequency` in Hz (0: a full turn every capture); a lidar's
    /// `noise`: CARLA's attributes without their `noise_` prefix
    /// (`stddev`, `dropoff_general_rate`, `dropoff_intensity_limit`,
    /// `dropoff_zero_intensity`, `atmosphere_attenuation_rate`, `seed`; all
    /// 0: exact). Radar:
    /// `fov` and `vertical_fov` in degrees (30/30), `range` (100),
    /// `points_per_second` (1500), `noise={"seed": N}` (0).
    /// Obstacle: `range` ahead (5 m), `hit_radius` (0.5 m),
    /// `only_dynamics` (False). Collision: a `parent` to watch.
    /// GNSS: `noise`, a dict of CARLA's noise attributes without their
    /// `noise_` prefix (`lat_stddev`, `alt_bias`, `seed`, ...; all 0).
    /// Invalid values raise `ValueError` and spawn nothing; an unknown
    /// parent raises `simbus.CommandError`.
    #[pyo3(signature = (kind, *, parent = None, at = [0.0, 2.0, 0.0], rotation = None, sensor_tick = 0.0, width = None, height = None, fov = None, range = None, channels = None, points = None, upper_fov = None, lower_fov = None, rotation_frequency = None, noise = None, hit_radius = None, only_dynamics = None, vertical_fov = None, points_per_second = None))]
    #[allow(clippy::too_many_arguments)]
    fn spawn_sensor(
        slf: &Bound<'_, Self>,
        kind: &str,
        parent: Option<u64>,
        at: [f64; 3],
        rotation: Option<[f64; 4]>,
        sensor_tick: f64,
        width: Option<f64>,
        height: Option<f64>,
        fov: Option<f64>,
        range: Option<f64>,
        channels: Option<f64>,
        points: Option<f64>,
        upper_fov: Option<f64>,
        lower_fov: Option<f64>,
        rotation_frequency: Option<f64>,
        noise: Option<HashMap<String, f64>>,
        hit_radius: Option<f64>,
        only_dynamics: Option<bool>,
        vertical_fov: Option<f64>,
        points_per_second: Option<f64>,
    ) -> PyResult<Sensor> {
        let params = SpawnParams {
            parent,
            at,
            rotation,
            sensor_tick,
            width,
            height,
            fov,
            range,
            channels,
            points,
            upper_fov,
            lower_fov,
            rotation_frequency,
            noise,
            hit_radius,
            only_dynamics,
            vertical_fov,
            points_per_second,
        };
        let spec = spec_for(kind, &params)?;
        let client = slf.borrow();
        let inner = &client.inner;
        let sensor = detached(slf.py(), inner, |c| c.spawn_sensor(spec)).map_err(|e| match e {
            SensorError::Refused(SensorRefusal::UnknownActor) => raise(
                "CommandError",
                format!(
                    "{e}: world '{}' has no actor {}",
                    inner.world().as_str(),
                    spec.attach_to
                ),
            ),
            e => sensor_error(e),
        })?;
        Ok(Sensor::new(slf, sensor))
    }

    /// Subscribes to the existing sensor `id` (`simbus.CommandError` names
    /// an id the world does not have).
    fn sensor(slf: &Bound<'_, Self>, id: u64) -> PyResult<Sensor> {
        let client = slf.borrow();
        let inner = &client.inner;
        let sensor = detached(slf.py(), inner, |c| c.sensor(id)).map_err(sensor_error)?;
        Ok(Sensor::new(slf, sensor))
    }

    /// Every sensor of the world, as `simbus.SensorInfo`s.
    fn list_sensors(&self, py: Python<'_>) -> PyResult<Vec<SensorInfo>> {
        let list = detached(py, &self.inner, |c| c.list_sensors()).map_err(sensor_error)?;
        Ok(list.into_iter().map(SensorInfo::from).collect())
    }

    /// Removes sensor `id` from the world; its readers' next read raises
    /// `simbus.SensorEnded`. An unknown id raises `simbus.CommandError`
    /// naming it.
    fn destroy_sensor(&self, py: Python<'_>, id: u64) -> PyResult<()> {
        detached(py, &self.inner, |c| c.destroy_sensor(id)).map_err(sensor_error)
    }
}

/// What the world says about one sensor (`client.list_sensors()`); a
/// parameter of another kind is `None`.
#[pyclass(module = "simbus", frozen, get_all)]
#[derive(Debug, Clone)]
pub(crate) struct SensorInfo {
    /// The sensor's id.
    id: u64,
    /// `"depth"`, `"lidar"`, `"imu"` or `"gnss"`.
    kind: &'static str,
    /// The actor it rides on, or `None` when fixed in the world.
    parent: Option<u64>,
    /// Position relative to the parent (or the world), metres.
    position: (f32, f32, f32),
    /// Orientation relative to the parent, quaternion (x, y, z, w); zeros
    /// mean none.
    rotation: (f32, f32, f32, f32),
    /// Capture period in simulation seconds (0: every frame).
    sensor_tick: f64,
    /// Captures so far.
    captures: u64,
    /// Depth: image width in pixels.
    width: Option<u32>,
    /// Depth: image height in pixels.
    height: Option<u32>,
    /// Depth: horizontal field of view, degrees.
    fov: Option<f32>,
    /// Depth: far range; lidar: range, metres.
    range: Option<f32>,
    /// Lidar: channels.
    channels: Option<u32>,
    /// Lidar: points per channel in a full turn.
    points: Option<u32>,
    /// Lidar: elevation of the top channel, degrees.
    upper_fov: Option<f32>,
    /// Lidar: elevation of the bottom channel, degrees.
    lower_fov: Option<f32>,
    /// Lidar: rotation frequency, Hz (0: a full turn every capture).
    rotation_frequency: Option<f32>,
}

impl From<Info> for SensorInfo {
    fn from(info: Info) -> Self {
        let spec = &info.spec;
        let (depth, lidar) = (spec.camera(), spec.lidar_params());
        let [x, y, z] = spec.position;
        let [qx, qy, qz, qw] = spec.rotation;
        Self {
            id: info.id,
            kind: kind_name(spec.kind),
            parent: (spec.attach_to != 0).then_some(spec.attach_to),
            position: (x, y, z),
            rotation: (qx, qy, qz, qw),
            sensor_tick: spec.sensor_tick,
            captures: info.captures,
            width: depth.map(|d| d.width),
            height: depth.map(|d| d.height),
            fov: depth.map(|d| d.fov),
            range: match spec.sensor_params() {
                Some(SensorParams::Depth(d)) => Some(d.range),
                Some(SensorParams::Lidar(l)) => Some(l.range),
                _ => None,
            },
            channels: lidar.map(|l| l.channels),
            points: lidar.map(|l| l.points),
            upper_fov: lidar.map(|l| l.upper_fov),
            lower_fov: lidar.map(|l| l.lower_fov),
            rotation_frequency: lidar.map(|l| l.rotation_hz),
        }
    }
}

#[pymethods]
impl SensorInfo {
    fn __repr__(&self) -> String {
        format!(
            "<simbus.SensorInfo {} {} parent={:?} captures={}>",
            self.id, self.kind, self.parent, self.captures
        )
    }
}

/// The name of wire kind `kind`.
fn kind_name(kind: u32) -> &'static str {
    match SensorKind::from_u32(kind) {
        // Python's spelling of the command line's `semantic-lidar`.
        Some(SensorKind::SemanticLidar) => "semantic_lidar",
        Some(kind) => kind.name(),
        None => "unknown",
    }
}

/// A subscription to one sensor (`client.spawn_sensor(...)`,
/// `client.sensor(id)`). In synchronous mode a reader that reads every
/// capture before the next tick gets each frame's, none lost; a slower one
/// loses the oldest (4 are queued), counted by `missed`. A reader holds at
/// most 2 captures at once: release them. Leaving a `with` block closes
/// the reader (the sensor stays in the world; `destroy()` removes it).
/// Bound to the thread that opened it.
#[pyclass(module = "simbus", unsendable)]
#[derive(Debug)]
pub(crate) struct Sensor {
    /// The reader; `None` once closed.
    inner: Option<sim_client::Sensor>,
    id: u64,
    kind: u32,
    /// The client that opened it (destroy asks through it).
    client: Py<Client>,
}

impl Sensor {
    fn new(client: &Bound<'_, Client>, mut inner: sim_client::Sensor) -> Self {
        inner.set_wait_mode(client.borrow().wait_mode);
        Self {
            id: inner.id(),
            kind: inner.spec().kind,
            inner: Some(inner),
            client: client.clone().unbind(),
        }
    }

    fn open(&mut self) -> PyResult<&mut sim_client::Sensor> {
        let id = self.id;
        self.inner.as_mut().ok_or_else(|| {
            raise(
                "Error",
                format!(
                    "the reader of sensor {id} was closed; open it again with client.sensor({id})"
                ),
            )
        })
    }
}

#[pymethods]
impl Sensor {
    /// The sensor's id.
    #[getter]
    fn id(&self) -> u64 {
        self.id
    }

    /// `"depth"`, `"lidar"`, `"imu"` or `"gnss"`.
    #[getter]
    fn kind(&self) -> &'static str {
        kind_name(self.kind)
    }

    /// Captures this reader lost since it subscribed (it fell more than 4
    /// behind).
    #[getter]
    fn missed(&self) -> u64 {
        self.inner.as_ref().map_or(0, |s| s.missed())
    }

    /// Whether the reader was closed.
    #[getter]
    fn closed(&self) -> bool {
        self.inner.is_none()
    }

    /// The next capture, waiting up to `timeout` seconds (the GIL
    /// released). Raises `simbus.TimeoutError` when none came, and
    /// `simbus.SensorEnded` (with `reason`) once the sensor is gone.
    #[pyo3(signature = (timeout = 5.0))]
    fn read(&mut self, py: Python<'_>, timeout: f64) -> PyResult<Capture> {
        let (timeout, id) = (seconds("timeout", timeout)?, self.id);
        let reader = self.open()?;
        let capture = detached(py, reader, |r| r.recv(timeout)).map_err(|e| wait_error(id, e))?;
        Capture::lent(py, capture)
    }

    /// The next queued capture, or `None` without waiting.
    fn try_read(&mut self, py: Python<'_>) -> PyResult<Option<Capture>> {
        let id = self.id;
        let capture = self.open()?.try_recv().map_err(|e| wait_error(id, e))?;
        capture.map(|c| Capture::lent(py, c)).transpose()
    }

    /// Calls `callback(capture)` with every capture from now on, on a
    /// thread of its own with its own client and subscription (CARLA's
    /// `sensor.listen`), until `stop()`. A capture's arrays are valid
    /// during the callback: `copy()` what you keep. Exceptions raised by
    /// the callback are printed (with their traceback) and counted; the
    /// listening goes on. The sensor's end stops it (`Listening.ended`).
    #[pyo3(signature = (callback, *, timeout = 5.0))]
    fn listen(&self, py: Python<'_>, callback: Py<PyAny>, timeout: f64) -> PyResult<Listening> {
        if !callback.bind(py).is_callable() {
            return Err(pyo3::exceptions::PyTypeError::new_err(
                "callback must be callable",
            ));
        }
        let (world, mode) = {
            let client = self.client.borrow(py);
            (client.inner.world().to_string(), client.wait_mode)
        };
        let timeout = seconds("timeout", timeout)?;
        Listening::start(py, world, timeout, self.id, mode, callback)
    }

    /// Removes the sensor from the world and closes this reader.
    fn destroy(&mut self, py: Python<'_>) -> PyResult<()> {
        let client = self.client.borrow(py);
        let (inner, id) = (&client.inner, self.id);
        detached(py, inner, |c| c.destroy_sensor(id)).map_err(sensor_error)?;
        self.inner = None;
        Ok(())
    }

    /// Closes this reader (the sensor stays in the world). Captures still
    /// held stay valid until released.
    fn close(&mut self) {
        self.inner = None;
    }

    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __exit__(
        &mut self,
        _kind: Option<Bound<'_, PyAny>>,
        _value: Option<Bound<'_, PyAny>>,
        _traceback: Option<Bound<'_, PyAny>>,
    ) {
        self.close();
    }

    fn __repr__(&self) -> String {
        format!(
            "<simbus.Sensor {} {}{}>",
            self.id,
            self.kind(),
            if self.closed() { " closed" } else { "" }
        )
    }
}
