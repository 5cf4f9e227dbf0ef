//! Debug drawing: `client.draw_point(...)`, `draw_line`, `draw_arrow`,
//! `draw_box`, `draw_string`, `debug_shapes()`, `clear_debug_shapes()` —
//! shapes the world keeps for `life_time` seconds of simulation time (CARLA's
//! convention: below 0 one frame, 0 for good) and its viewers show. Points
//! are in simbus's axes (x, y up, z).

use pyo3::exceptions::PyValueError;
use pyo3::prelude::*;
use pyo3::types::PyDict;
use shared_types::{DebugShape, FixedText, ShapeKind};
use sim_client::DrawError;

use crate::client::Client;
use crate::errors::{message, request};
use crate::gil::detached;

type V3 = [f32; 3];

/// A colour given as (r, g, b) or (r, g, b, a), 0..=255.
fn colour(color: Vec<u8>) -> PyResult<[u8; 4]> {
    match *color.as_slice() {
        [r, g, b] => Ok([r, g, b, 255]),
        [r, g, b, a] => Ok([r, g, b, a]),
        _ => Err(PyValueError::new_err(
            "color: (r, g, b) or (r, g, b, a), each 0 to 255",
        )),
    }
}

fn draw_error(error: DrawError) -> PyErr {
    match error {
        DrawError::Request(e) => request(e),
        e => PyValueError::new_err(message(&e)),
    }
}

impl Client {
    fn draw(
        &self,
        py: Python<'_>,
        shape: DebugShape,
        color: Vec<u8>,
        life_time: f64,
    ) -> PyResult<()> {
        let shape = DebugShape {
            color: colour(color)?,
            ..shape
        }
        .lasting(life_time);
        detached(py, &self.inner, |c| c.draw_debug(shape)).map_err(draw_error)
    }
}

#[pymethods]
impl Client {
    /// Draws a dot `size` metres across at `location`.
    #[pyo3(signature = (location, size = 0.1, color = vec![255, 0, 0], life_time = -1.0))]
    fn draw_point(
        &self,
        py: Python<'_>,
        location: V3,
        size: f32,
        color: Vec<u8>,
        life_time: f64,
    ) -> PyResult<()> {
        let shape = DebugShape {
            kind: ShapeKind::Point as u32,
            a: location,
            size,
            ..DebugShape::default()
        };
        self.draw(py, shape, color, life_time)
    }

    /// Draws a line from `begin` to `end`, `thickness` metres thick.
    #[pyo3(signature = (begin, end, thickness = 0.1, color = vec![255, 0, 0], life_time = -1.0))]
    fn draw_line(
        &self,
        py: Python<'_>,
        begin: V3,
        end: V3,
        thickness: f32,
        color: Vec<u8>,
        life_time: f64,
    ) -> PyResult<()> {
        let shape = DebugShape {
            kind: ShapeKind::Line as u32,
            a: begin,
            b: end,
            size: thickness,
            ..DebugShape::default()
        };
        self.draw(py, shape, color, life_time)
    }

    /// Draws an arrow from `begin` to `end`, its head `arrow_size` long.
    #[pyo3(signature = (begin, end, thickness = 0.1, arrow_size = 0.1, color = vec![255, 0, 0], life_time = -1.0))]
    #[allow(clippy::too_many_arguments)]
    fn draw_arrow(
        &self,
        py: Python<'_>,
        begin: V3,
        end: V3,
        thickness: f32,
        arrow_size: f32,
        color: Vec<u8>,
        life_time: f64,
    ) -> PyResult<()> {
        let shape = DebugShape {
            kind: ShapeKind::Arrow as u32,
            a: begin,
            b: end,
            size: thickness,
            arrow_size,
            ..DebugShape::default()
        };
        self.draw(py, shape, color, life_time)
    }

    /// Draws the edges of a box centred at `center` with half extents
    /// `half_extents`, turned by `rotation` (a quaternion x, y, z, w).
    #[pyo3(signature = (center, half_extents, rotation = [0.0, 0.0, 0.0, 1.0], thickness = 0.1, color = vec![255, 0, 0], life_time = -1.0))]
    #[allow(clippy::too_many_arguments)]
    fn draw_box(
        &self,
        py: Python<'_>,
        center: V3,
        half_extents: V3,
        rotation: [f32; 4],
        thickness: f32,
        color: Vec<u8>,
        life_time: f64,
    ) -> PyResult<()> {
        let shape = DebugShape {
            kind: ShapeKind::Box as u32,
            a: center,
            b: half_extents,
            rotation,
            size: thickness,
            ..DebugShape::default()
        };
        self.draw(py, shape, color, life_time)
    }

    /// Writes `text` (at most 64 bytes) at `location`.
    #[pyo3(signature = (location, text, color = vec![255, 0, 0], life_time = -1.0))]
    fn draw_string(
        &self,
        py: Python<'_>,
        location: V3,
        text: &str,
        color: Vec<u8>,
        life_time: f64,
    ) -> PyResult<()> {
        if text.len() > 64 {
            return Err(PyValueError::new_err("a debug text holds at most 64 bytes"));
        }
        let shape = DebugShape {
            kind: ShapeKind::Text as u32,
            a: location,
            text: FixedText::new(text),
            ..DebugShape::default()
        };
        self.draw(py, shape, color, life_time)
    }

    /// The debug shapes the current frame shows, each a dict: `kind`
    /// ("point", "line", "arrow", "box", "text"), `color`, `a`, `b`,
    /// `size`, `text`, `permanent`, `life_time`.
    fn debug_shapes<'py>(&self, py: Python<'py>) -> PyResult<Vec<Bound<'py, PyDict>>> {
        let shapes = detached(py, &self.inner, |c| c.debug_shapes()).map_err(request)?;
        shapes
            .iter()
            .map(|s| {
                let d = PyDict::new(py);
                let kind = match s.shape_kind() {
                    Some(ShapeKind::Point) => "point",
                    Some(ShapeKind::Line) => "line",
                    Some(ShapeKind::Arrow) => "arrow",
                    Some(ShapeKind::Box) => "box",
                    Some(ShapeKind::Text) => "text",
                    None => "unknown",
                };
                d.set_item("kind", kind)?;
                d.set_item("color", s.color.map(u32::from).to_vec())?;
                d.set_item("a", s.a.to_vec())?;
                d.set_item("b", s.b.to_vec())?;
                d.set_item("size", s.size)?;
                d.set_item("text", s.text.to_string_lossy())?;
                d.set_item("permanent", s.is_permanent())?;
                d.set_item("life_time", s.life_ns as f64 / 1e9)?;
                Ok(d)
            })
            .collect()
    }

    /// Forgets every debug shape, from the next frame on.
    fn clear_debug_shapes(&self, py: Python<'_>) -> PyResult<()> {
        detached(py, &self.inner, |c| c.clear_debug_shapes()).map_err(request)
    }
}
