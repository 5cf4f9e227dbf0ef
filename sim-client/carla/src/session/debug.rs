//! CARLA's debug drawing (`world.debug.draw_point`, `draw_line`,
//! `draw_arrow`, `draw_box`, `draw_string`, `draw_hud_*`): each call's
//! `rpc::DebugShape` becomes a simbus debug shape the world keeps for its
//! `life_time` and the Foxglove view and recordings show.

use rmpv::Value;
use shared_types::{DebugShape, FixedText, ShapeKind};

use super::Session;
use crate::commands::{number, vector};
use crate::convert;
use crate::error::CallError;
use crate::rpc::Answer;

const METHOD: &str = "draw_debug_shape";

/// CARLA 0.9.16's `rpc::DebugShape`: `[primitive, color, life_time,
/// persistent_lines]`, the primitive a variant `[index, value]` of
/// `Point, Line, Arrow, Box, String, HUDPoint, HUDLine, HUDArrow, HUDBox`.
pub(crate) fn debug_shape(v: &Value) -> Option<DebugShape> {
    let [primitive, color, life, ..] = v.as_array()?.as_slice() else {
        return None;
    };
    let [index, value] = primitive.as_array()?.as_slice() else {
        return None;
    };
    let index = index.as_u64()?;
    let fields = value.as_array()?;
    let field = |i: usize| fields.get(i);
    let f32_at = |i: usize| field(i).and_then(number).map(|x| x as f32);
    let at = |i: usize| field(i).and_then(vector).map(convert::vector);
    let hud = index >= 5;
    let mut shape = DebugShape::default();
    match index {
        0 | 5 => {
            shape.kind = ShapeKind::Point as u32;
            shape.a = at(0)?;
            shape.size = f32_at(1)?;
        }
        1 | 6 => {
            shape.kind = ShapeKind::Line as u32;
            (shape.a, shape.b, shape.size) = line(value)?;
        }
        2 | 7 => {
            shape.kind = ShapeKind::Arrow as u32;
            (shape.a, shape.b, shape.size) = line(field(0)?)?;
            shape.arrow_size = f32_at(1)?;
        }
        3 | 8 => {
            // [[location, extent, rotation, actor_id], rotation, thickness]
            let bounds = field(0)?.as_array()?;
            shape.kind = ShapeKind::Box as u32;
            shape.a = convert::vector(vector(bounds.first()?)?);
            shape.b = convert::vector(vector(bounds.get(1)?)?);
            shape.rotation = convert::quaternion(vector(field(1)?)?);
            shape.size = f32_at(2)?;
        }
        4 => {
            shape.kind = ShapeKind::Text as u32;
            shape.a = at(0)?;
            shape.text = FixedText::new(field(1)?.as_str()?);
        }
        _ => return None,
    }
    if hud {
        shape.flags |= DebugShape::HUD;
    }
    let rgb = color.as_array()?;
    let channel = |i: usize| {
        rgb.get(i)
            .and_then(Value::as_u64)
            .and_then(|c| u8::try_from(c).ok())
    };
    shape.color = [
        channel(0)?,
        channel(1)?,
        channel(2)?,
        channel(3).unwrap_or(255),
    ];
    Some(shape.lasting(number(life)?))
}

/// CARLA's `Line`: `[begin, end, thickness]`, in simbus's axes.
fn line(v: &Value) -> Option<([f32; 3], [f32; 3], f32)> {
    let [begin, end, thickness] = v.as_array()?.as_slice() else {
        return None;
    };
    Some((
        convert::vector(vector(begin)?),
        convert::vector(vector(end)?),
        number(thickness)? as f32,
    ))
}

impl Session {
    /// Draws one debug shape (CARLA sends each without waiting).
    pub(super) fn on_draw_debug_shape(&mut self, args: &[Value]) -> Result<Answer, CallError> {
        let shape = args
            .first()
            .and_then(debug_shape)
            .ok_or(CallError::Argument {
                method: METHOD,
                index: 0,
                expected: "a DebugShape",
            })?;
        self.client()?
            .draw_debug(shape)
            .map_err(CallError::simbus)?;
        Ok(Answer::Done)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    fn location(x: f64, y: f64, z: f64) -> Value {
        Value::Array(vec![x.into(), y.into(), z.into()])
    }

    fn shape(index: u64, value: Value, life: f64) -> Value {
        Value::Array(vec![
            Value::Array(vec![index.into(), value]),
            Value::Array(vec![255.into(), 128.into(), 0.into()]),
            life.into(),
            true.into(),
        ])
    }

    #[test]
    fn carlas_shapes_read_in_simbus_axes_with_their_life_and_colour() {
        let point = shape(
            0,
            Value::Array(vec![location(1.0, 2.0, 3.0), 0.2.into()]),
            -1.0,
        );
        let point = debug_shape(&point).unwrap();
        assert_eq!(point.shape_kind(), Some(ShapeKind::Point));
        // CARLA (x, y, z) is simbus (x, z, y).
        assert_eq!(point.a, [1.0, 3.0, 2.0]);
        assert_eq!(point.color, [255, 128, 0, 255]);
        assert_eq!((point.life_ns, point.is_permanent()), (0, false));
        let line = Value::Array(vec![
            location(0.0, 0.0, 0.0),
            location(1.0, 0.0, 0.0),
            0.1.into(),
        ]);
        let arrow = shape(7, Value::Array(vec![line, 0.3.into()]), 2.0);
        let arrow = debug_shape(&arrow).unwrap();
        assert_eq!(arrow.shape_kind(), Some(ShapeKind::Arrow));
        assert_eq!((arrow.b, arrow.arrow_size), ([1.0, 0.0, 0.0], 0.3));
        assert!(arrow.flags & DebugShape::HUD != 0, "draw_hud_arrow");
        assert_eq!(arrow.life_ns, 2_000_000_000);
        let text = shape(
            4,
            Value::Array(vec![location(0.0, 0.0, 1.0), "7".into(), false.into()]),
            0.0,
        );
        let text = debug_shape(&text).unwrap();
        assert_eq!(
            (text.text.to_string_lossy().as_str(), text.is_permanent()),
            ("7", true)
        );
        let bounds = Value::Array(vec![
            location(5.0, 0.0, 0.0),
            location(1.0, 2.0, 3.0),
            location(0.0, 0.0, 0.0),
            0.into(),
        ]);
        let cube = shape(
            3,
            Value::Array(vec![bounds, location(0.0, 90.0, 0.0), 0.1.into()]),
            1.0,
        );
        let cube = debug_shape(&cube).unwrap();
        assert_eq!((cube.a, cube.b), ([5.0, 0.0, 0.0], [1.0, 3.0, 2.0]));
        // Garbage is no shape.
        assert!(debug_shape(&shape(9, Value::Nil, 1.0)).is_none());
        assert!(debug_shape(&Value::from("point")).is_none());
        assert!(debug_shape(&shape(
            0,
            Value::Array(vec![location(f64::NAN, 0.0, 0.0), 0.1.into()]),
            1.0
        ))
        .is_none());
    }
}
