//! [`Frame`]: one frame of the world, its actors and their packed poses
//! numpy structured arrays over the frame's shared memory.

use std::mem::{offset_of, size_of};

use pyo3::prelude::*;
use pyo3::sync::PyOnceLock;
use shared_types::{ActorPose, ActorState, FrameHeader};

use crate::errors::raise;
use crate::loan::{give_back, structured_dtype, view_as, Lent, Loan};

/// The actors' dtype: the wire layout of [`ActorState`], field by field.
pub(crate) fn actor_dtype(py: Python<'_>) -> PyResult<&Bound<'_, PyAny>> {
    static DTYPE: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
    DTYPE
        .get_or_try_init(py, || {
            let fields = [
                ("id", "<u8", offset_of!(ActorState, id)),
                ("kind", "<u4", offset_of!(ActorState, kind)),
                ("flags", "<u4", offset_of!(ActorState, flags)),
                ("position", "(3,)<f4", offset_of!(ActorState, position)),
                ("rotation", "(4,)<f4", offset_of!(ActorState, rotation)),
                (
                    "linear_velocity",
                    "(3,)<f4",
                    offset_of!(ActorState, linear_velocity),
                ),
                (
                    "angular_velocity",
                    "(3,)<f4",
                    offset_of!(ActorState, angular_velocity),
                ),
                (
                    "acceleration",
                    "(3,)<f4",
                    offset_of!(ActorState, acceleration),
                ),
                ("extent", "(3,)<f4", offset_of!(ActorState, extent)),
                ("detail", "<u4", offset_of!(ActorState, detail)),
            ];
            structured_dtype(py, &fields, size_of::<ActorState>()).map(Bound::unbind)
        })
        .map(|dtype| dtype.bind(py))
}

/// The poses' dtype: the wire layout of [`ActorPose`], field by field.
pub(crate) fn pose_dtype(py: Python<'_>) -> PyResult<&Bound<'_, PyAny>> {
    static DTYPE: PyOnceLock<Py<PyAny>> = PyOnceLock::new();
    DTYPE
        .get_or_try_init(py, || {
            let fields = [
                ("id", "<u8", offset_of!(ActorPose, id)),
                ("kind", "<u4", offset_of!(ActorPose, kind)),
                ("flags", "<u4", offset_of!(ActorPose, flags)),
                ("position", "(3,)<f4", offset_of!(ActorPose, position)),
                ("rotation", "(4,)<f4", offset_of!(ActorPose, rotation)),
            ];
            structured_dtype(py, &fields, size_of::<ActorPose>()).map(Bound::unbind)
        })
        .map(|dtype| dtype.bind(py))
}

/// A frame's arrays, copied (a frame from `copy()`).
#[derive(Debug)]
struct Owned {
    actors: Py<PyAny>,
    poses: Py<PyAny>,
}

/// One frame: its header's values, and its actors and poses over shared memory
/// while the frame is held (`release()`, the end of a `with` block, or
/// `copy()` to keep them).
#[pyclass(module = "simbus", unsendable)]
#[derive(Debug)]
pub(crate) struct Frame {
    header: FrameHeader,
    missed: u64,
    digest: u64,
    /// The sample, while held; `None` once released.
    loan: Option<Py<Loan>>,
    /// The arrays, copied (a frame from `copy()`).
    owned: Option<Owned>,
}

/// A part of a frame's payload.
#[derive(Debug, Clone, Copy)]
enum Part {
    Actors,
    Poses,
}

impl Frame {
    /// A frame over `view`, lent until released.
    pub(crate) fn lent(py: Python<'_>, view: sim_client::FrameView) -> PyResult<Self> {
        let (header, missed, digest) = (*view.header(), view.missed(), view.digest());
        let loan = Py::new(
            py,
            Loan {
                sample: Lent::Frame(view),
            },
        )?;
        Ok(Self {
            header,
            missed,
            digest,
            loan: Some(loan),
            owned: None,
        })
    }

    /// `part` of the held frame as a numpy array over shared memory.
    fn view_part<'py>(&self, py: Python<'py>, part: Part) -> PyResult<Bound<'py, PyAny>> {
        let Some(loan) = &self.loan else {
            return Err(released(self.frame()));
        };
        let loan = loan.bind(py);
        let (actors, poses) = match &loan.borrow().sample {
            Lent::Frame(view) => (view.actors().len(), view.poses().len()),
            Lent::Capture(_) => (0, 0),
        };
        let actor_bytes = actors * size_of::<ActorState>();
        match part {
            Part::Actors => view_as(loan, 0..actor_bytes, actor_dtype(py)?),
            Part::Poses => view_as(
                loan,
                actor_bytes..actor_bytes + poses * size_of::<ActorPose>(),
                pose_dtype(py)?,
            ),
        }
    }
}

#[pymethods]
impl Frame {
    /// The frame id.
    #[getter]
    fn frame(&self) -> u64 {
        self.header.timestamp.frame
    }

    /// Simulation time since the episode began, in integer nanoseconds.
    #[getter]
    fn elapsed_ns(&self) -> u64 {
        self.header.timestamp.elapsed_ns
    }

    /// Simulation time since the episode began, in seconds.
    #[getter]
    fn elapsed_seconds(&self) -> f64 {
        self.header.timestamp.elapsed_seconds()
    }

    /// The step from the previous frame, in seconds.
    #[getter]
    fn delta_seconds(&self) -> f64 {
        self.header.timestamp.delta_seconds()
    }

    /// Wall-clock time at which the server published the frame (seconds).
    #[getter]
    fn timestamp(&self) -> f64 {
        self.header.timestamp.platform_timestamp
    }

    /// The episode (a load or reload starts the next).
    #[getter]
    fn episode(&self) -> u64 {
        self.header.episode
    }

    /// Whether physics advanced less than `delta_seconds` (the substep
    /// rule "clamp", CARLA's, with a frame longer than substepping allows).
    #[getter]
    fn physics_clamped(&self) -> bool {
        self.header.is_physics_clamped()
    }

    /// The simulation seconds physics advanced in this frame:
    /// `delta_seconds`, or less for a clamped frame.
    #[getter]
    fn physics_seconds(&self) -> f64 {
        self.header.physics_seconds()
    }

    /// Frames published between the previous frame this client took and
    /// this one that it did not see.
    #[getter]
    fn missed(&self) -> u64 {
        self.missed
    }

    /// The frame's digest: equal digests, bit-identical worlds.
    #[getter]
    fn digest(&self) -> u64 {
        self.digest
    }

    /// The actors: a read-only numpy structured array (`id`, `kind`,
    /// `flags`, `position`, `rotation`, `linear_velocity`,
    /// `angular_velocity`, `acceleration`, `extent`) over the frame's
    /// shared memory. It keeps the frame lent while it lives.
    #[getter]
    fn actors<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        if let Some(owned) = &self.owned {
            return Ok(owned.actors.bind(py).clone());
        }
        self.view_part(py, Part::Actors)
    }

    /// The actors' poses, in the order of `actors`, packed: a read-only
    /// numpy structured array (`id`, `kind`, `flags`, `position`,
    /// `rotation`) over the frame's shared memory, half the bytes of
    /// `actors` (what a reader that needs only where things are should
    /// read). It keeps the frame lent while it lives.
    #[getter]
    fn poses<'py>(&self, py: Python<'py>) -> PyResult<Bound<'py, PyAny>> {
        if let Some(owned) = &self.owned {
            return Ok(owned.poses.bind(py).clone());
        }
        self.view_part(py, Part::Poses)
    }

    /// Whether the frame's shared memory is still lent to this frame.
    #[getter]
    fn held(&self) -> bool {
        self.loan.is_some() || self.owned.is_some()
    }

    /// A frame with the same values and its own copy of the actors and
    /// poses: it holds no shared memory.
    fn copy(&self, py: Python<'_>) -> PyResult<Frame> {
        let actors = self.actors(py)?.call_method0("copy")?.unbind();
        let poses = self.poses(py)?.call_method0("copy")?.unbind();
        Ok(Frame {
            header: self.header,
            missed: self.missed,
            digest: self.digest,
            loan: None,
            owned: Some(Owned { actors, poses }),
        })
    }

    /// Gives the frame's shared memory back to the server. Raises
    /// `BufferError` while numpy arrays still view it (delete them, or
    /// `copy()` first); afterwards `actors` raises `simbus.ReleasedError`.
    fn release(&mut self) -> PyResult<()> {
        let frame = self.frame();
        give_back(&mut self.loan, || format!("frame {frame}"))
    }

    fn __enter__(slf: PyRef<'_, Self>) -> PyRef<'_, Self> {
        slf
    }

    fn __exit__(
        &mut self,
        _kind: Option<Bound<'_, PyAny>>,
        _value: Option<Bound<'_, PyAny>>,
        _traceback: Option<Bound<'_, PyAny>>,
    ) -> PyResult<()> {
        self.release()
    }

    fn __repr__(&self) -> String {
        format!(
            "<simbus.Frame {} elapsed={}s actors={}{}>",
            self.frame(),
            self.elapsed_seconds(),
            self.header.actor_count,
            if self.held() { "" } else { " released" }
        )
    }
}

fn released(frame: u64) -> PyErr {
    raise(
        "ReleasedError",
        format!("frame {frame} was released: its shared memory went back to the server (copy() a frame to keep it)"),
    )
}
