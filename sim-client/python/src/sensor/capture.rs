//! [`Capture`]: one capture of a sensor, its data a numpy array over the
//! capture's shared memory (the [`Loan`] is the array's base object, so no
//! array outlives its sample).

use std::mem::{offset_of, size_of};
use std::thread::ThreadId;

use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use pyo3::types::{PySlice, PyString, PyTuple};
use shared_types::{
    CollisionEvent, GnssMeasurement, ImuMeasurement, LidarPoint, ObstacleDetection, RadarDetection,
    SemanticLidarPoint, SensorHeader, SensorKind,
};

use super::kind_name;
use crate::errors::raise;
use crate::loan::{bytes_of, give_back, structured_dtype, Lent, Loan};

/// `fn $name(py)`: the numpy dtype of one `$record` (its wire layout:
/// each field's name, numpy type and offset), made once per process.
macro_rules! record_dtype {
    ($(#[$doc:meta])* $name:ident: $record:ty { $($field:ident: $numpy:literal),* $(,)? }) => {
        $(#[$doc])*
        fn $name(py: Python<'_>) -> PyResult<&Bound<'_, PyAny>> {
            static DTYPE: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
            DTYPE
                .get_or_try_init(py, || {
                    let fields = [$((stringify!($field), $numpy, offset_of!($record, $field))),*];
                    structured_dtype(py, &fields, size_of::<$record>()).map(Bound::unbind)
                })
                .map(|dtype| dtype.bind(py))
        }
    };
}

record_dtype! {
    /// An IMU capture's dtype: the wire layout of [`ImuMeasurement`].
    imu_dtype: ImuMeasurement { accelerometer: "(3,)<f4", gyroscope: "(3,)<f4" }
}

record_dtype! {
    /// A GNSS capture's dtype: the wire layout of [`GnssMeasurement`].
    gnss_dtype: GnssMeasurement { latitude: "<f8", longitude: "<f8", altitude: "<f8" }
}

record_dtype! {
    /// A collision capture's dtype: the wire layout of [`CollisionEvent`].
    collision_dtype: CollisionEvent { other_actor: "<u8", normal_impulse: "(3,)<f4" }
}

record_dtype! {
    /// An obstacle capture's dtype: the wire layout of [`ObstacleDetection`].
    obstacle_dtype: ObstacleDetection { other_actor: "<u8", distance: "<f4" }
}

record_dtype! {
    /// A semantic lidar capture's dtype: the wire layout of
    /// [`SemanticLidarPoint`] (CARLA's `SemanticLidarDetection`).
    semantic_lidar_dtype: SemanticLidarPoint {
        x: "<f4",
        y: "<f4",
        z: "<f4",
        cos_inc_angle: "<f4",
        object_idx: "<u4",
        object_tag: "<u4",
    }
}

record_dtype! {
    /// A radar capture's dtype: the wire layout of [`RadarDetection`].
    radar_dtype: RadarDetection { velocity: "<f4", azimuth: "<f4", altitude: "<f4", depth: "<f4" }
}

/// One capture: its header's values, and its data as a numpy array over
/// the capture's shared memory while the capture is held (`release()`,
/// the end of a `with` block, or `copy()` to keep it). The arrays are
/// read, and the capture released, on the thread that read it; its other
/// values, and a copy, go anywhere.
#[pyclass(module = "simbus")]
#[derive(Debug)]
pub(crate) struct Capture {
    header: SensorHeader,
    /// The sample, while held; `None` once released.
    pub(super) loan: Option<Py<Loan>>,
    /// The thread the sample belongs to (the one that received it).
    thread: ThreadId,
    /// The data, copied (a capture from `copy()`).
    owned: Option<Py<PyAny>>,
}

impl Capture {
    /// A capture over `capture`, lent until released.
    pub(crate) fn lent(py: Python<'_>, capture: sim_client::Capture) -> PyResult<Self> {
        let header = *capture.header();
        let loan = Py::new(
            py,
            Loan {
                sample: Lent::Capture(capture),
            },
        )?;
        Ok(Self {
            header,
            loan: Some(loan),
            thread: std::thread::current().id(),
            owned: None,
        })
    }

    /// The loan, on the thread it belongs to.
    fn loan<'py>(&self, py: Python<'py>) -> PyResult<&Bound<'py, Loan>> {
        let Some(loan) = &self.loan else {
            return Err(raise(
                "ReleasedError",
                format!(
                    "capture {} of sensor {} (frame {}) was released: its shared memory went back to the server (copy() a capture to keep it)",
                    self.header.sequence, self.header.sensor_id, self.header.frame
                ),
            ));
        };
        if std::thread::current().id() != self.thread {
            return Err(raise(
                "Error",
                format!(
                    "capture {} of sensor {} belongs to the thread that received it: use its arrays there, or copy() it there to use it anywhere",
                    self.header.sequence, self.header.sensor_id
                ),
            ));
        }
        Ok(loan.bind(py))
    }

    /// The array over the start of the loan's payload: elements of
    /// `element` bytes viewed as `dtype`, shaped `shape` (the sizes come
    /// from the server's header: checked against the sample).
    fn typed<'py>(
        &self,
        loan: &Bound<'py, Loan>,
        dtype: &Bound<'py, PyAny>,
        element: usize,
        shape: &[usize],
    ) -> PyResult<Bound<'py, PyAny>> {
        let py = loan.py();
        let bytes = bytes_of(loan)?;
        let wanted = shape.iter().try_fold(element, |n, &d| n.checked_mul(d));
        let have = bytes.as_any().len()?;
        let Some(wanted) = wanted.filter(|&n| n <= have) else {
            return Err(raise(
                "Error",
                format!(
                    "capture {} of sensor {} says it holds {shape:?} elements of {element} bytes but its sample has {have} bytes",
                    self.header.sequence, self.header.sensor_id
                ),
            ));
        };
        let slice = PySlice::new(py, 0, wanted as isize, 1);
        let prefix = bytes.as_any().get_item(slice)?;
        let typed = prefix.call_method1("view", (dtype,))?;
        typed.call_method1("reshape", (PyTuple::new(py, shape)?,))
    }
}

#[pymethods]
impl Capture {
    /// The frame captured.
    #[getter]
    fn frame(&self) -> u64 {
        self.header.frame
    }

    /// Simulation time of the frame since the episode began, nanoseconds.
    #[getter]
    fn elapsed_ns(&self) -> u64 {
        self.header.elapsed_ns
    }

    /// Simulation time of the frame since the episode began, seconds.
    #[getter]
    fn elapsed_seconds(&self) -> f64 {
        self.header.elapsed_ns as f64 / 1e9
    }

    /// The episode of the frame.
    #[getter]
    fn episode(&self) -> u64 {
        self.header.episode
    }

    /// Captures of this sensor so far, this one included (gaps: missed).
    #[getter]
    fn sequence(&self) -> u64 {
        self.header.sequence
    }

    /// The sensor's id.
    #[getter]
    fn sensor_id(&self) -> u64 {
        self.header.sensor_id
    }

    /// The sensor's kind, as `spawn_sensor` names it (`"depth"`,
    /// `"semantic_lidar"`, `"radar"`, ...).
    #[getter]
    fn kind(&self) -> &'static str {
        kind_name(self.header.kind)
    }

    /// Cameras: image width in pixels; lidar: channels; IMU: 1.
    #[getter]
    fn width(&self) -> u32 {
        self.header.size[0]
    }

    /// Cameras: image height in pixels; lidar: points per channel; IMU: 1.
    #[getter]
    fn height(&self) -> u32 {
        self.header.size[1]
    }

    /// Valid elements: pixels, lidar returns, 1 IMU reading.
    #[getter]
    fn count(&self) -> u32 {
        self.header.count
    }

    /// The sensor's position in the world at capture, metres.
    #[getter]
    fn position(&self) -> (f32, f32, f32) {
        let [x, y, z] = self.header.position;
        (x, y, z)
    }

    /// The sensor's orientation in the world at capture, quaternion
    /// (x, y, z, w).
    #[getter]
    fn rotation(&self) -> (f32, f32, f32, f32) {
        let [x, y, z, w] = self.header.rotation;
        (x, y, z, w)
    }

    /// Wall-clock time at which the server published it (seconds).
    #[getter]
    fn timestamp(&self) -> f64 {
        self.header.platform_timestamp
    }

    /// The data, read-only, over the capture's shared memory (its base
    /// keeps the capture lent while it lives): depth `float32 (height,
    /// width)` metres; RGB, semantic and instance `uint8 (height, width,
    /// 4)` blue, green, red, alpha (semantic: the tag in red; instance:
    /// the tag in red, the actor id in green and blue); lidar `float32 (N, 4)` x, y, z, intensity for the N
    /// returns; semantic lidar one record per return (`x`, `y`, `z`,
    /// `cos_inc_angle`, `object_idx`, `object_tag`); radar one record per
    /// detection (`velocity`, `azimuth`, `altitude`, `depth`); IMU one
    /// record (`accelerometer`, `gyroscope`); collision
    /// one record per contact (`other_actor`, `normal_impulse`); obstacle
    /// one record (`other_actor`, `distance`).
    #[getter]
    fn array<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        if let Some(owned) = &self.owned {
            return Ok(owned.bind(py).clone());
        }
        let loan = self.loan(py)?;
        let f4 = PyString::new(py, "<f4").into_any();
        let [w, h] = self.header.size.map(|v| v as usize);
        match SensorKind::from_u32(self.header.kind) {
            Some(SensorKind::Depth) => self.typed(loan, &f4, size_of::<f32>(), &[h, w]),
            Some(SensorKind::Rgb | SensorKind::Semantic | SensorKind::Instance) => {
                let u1 = PyString::new(py, "u1").into_any();
                self.typed(loan, &u1, 1, &[h, w, 4])
            }
            Some(SensorKind::Lidar) => {
                let element = size_of::<LidarPoint>();
                let slots = match &loan.borrow().sample {
                    Lent::Capture(c) => c.bytes().len() / element,
                    Lent::Frame(_) => 0,
                };
                let n = (self.header.count as usize).min(slots);
                self.typed(loan, &f4, size_of::<f32>(), &[n, 4])
            }
            Some(SensorKind::Gnss) => {
                self.typed(loan, gnss_dtype(py)?, size_of::<GnssMeasurement>(), &[1])
            }
            Some(SensorKind::SemanticLidar) => {
                let element = size_of::<SemanticLidarPoint>();
                let n = self.header.count as usize;
                self.typed(loan, semantic_lidar_dtype(py)?, element, &[n])
            }
            Some(SensorKind::Radar) => {
                let element = size_of::<RadarDetection>();
                let n = self.header.count as usize;
                self.typed(loan, radar_dtype(py)?, element, &[n])
            }
            Some(SensorKind::Collision) => {
                let element = size_of::<CollisionEvent>();
                let n = self.header.count as usize;
                self.typed(loan, collision_dtype(py)?, element, &[n])
            }
            Some(SensorKind::Obstacle) => self.typed(
                loan,
                obstacle_dtype(py)?,
                size_of::<ObstacleDetection>(),
                &[1],
            ),
            _ => self.typed(loan, imu_dtype(py)?, size_of::<ImuMeasurement>(), &[1]),
        }
    }

    /// Whether the data is still held (lent, or copied).
    #[getter]
    fn held(&self) -> bool {
        self.loan.is_some() || self.owned.is_some()
    }

    /// A capture with the same values and its own copy of the data: it
    /// holds no shared memory, and may go to any thread.
    fn copy(&self, py: Python<'_>) -> PyResult<Capture> {
        let array = self.array(py)?.call_method0("copy")?;
        Ok(Capture {
            header: self.header,
            loan: None,
            thread: self.thread,
            owned: Some(array.unbind()),
        })
    }

    /// Gives the capture's shared memory back to the server. Raises
    /// `BufferError` while numpy arrays still view it (delete them, or
    /// `copy()` first); afterwards `array` raises `simbus.ReleasedError`.
    fn release(&mut self, py: Python<'_>) -> PyResult<()> {
        if self.loan.is_none() {
            return Ok(());
        }
        self.loan(py)?;
        let h = self.header;
        give_back(&mut self.loan, || {
            format!(
                "capture {} of sensor {} (frame {})",
                h.sequence, h.sensor_id, h.frame
            )
        })
    }

    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __exit__(
        &mut self,
        py: Python<'_>,
        _kind: Option<Bound<'_, PyAny>>,
        _value: Option<Bound<'_, PyAny>>,
        _traceback: Option<Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        self.release(py)
    }

    fn __repr__(&self) -> String {
        format!(
            "<simbus.Capture sensor {} {} frame {} #{} {}x{}{}>",
            self.header.sensor_id,
            self.kind(),
            self.header.frame,
            self.header.sequence,
            self.header.size[0],
            self.header.size[1],
            if self.held() { "" } else { " released" }
        )
    }
}
