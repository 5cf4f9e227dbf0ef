//! Debug drawing: points, lines, arrows, boxes and text a client puts in
//! the world for a while (CARLA's `world.debug.draw_*`), kept by the server
//! until they expire in simulation time and shown by the viewers (the
//! Foxglove live view, a recording's scene). They have no body: sensors
//! and physics never see them.

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

use crate::wire::{wire_enum, FixedText, PROTOCOL_VERSION};

/// The most shapes a world keeps at once; a draw past it is refused.
pub const MAX_DEBUG_SHAPES: usize = 10_000;

/// The longest a shape may last, seconds (permanent shapes aside).
pub const MAX_DEBUG_LIFE_SECONDS: f64 = 1e6;

wire_enum! {
    /// What a [`DebugShape`] draws.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash)]
    pub enum ShapeKind {
        /// A dot at `a`, `size` metres across.
        Point = 0,
        /// A line from `a` to `b`, `size` metres thick.
        Line = 1,
        /// An arrow from `a` to `b`, `size` thick, its head `arrow_size`.
        Arrow = 2,
        /// A box centred at `a` with half extents `b`, turned by
        /// `rotation`, its edges `size` thick.
        Box = 3,
        /// `text` at `a`.
        Text = 4,
    }
}

/// One debug shape, in simbus's world axes (metres; Y up).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::DebugShape/1")]
pub struct DebugShape {
    /// [`ShapeKind`] as `u32`.
    pub kind: u32,
    /// [`DebugShape::HUD`], [`DebugShape::PERMANENT`].
    pub flags: u32,
    /// Red, green, blue, alpha.
    pub color: [u8; 4],
    /// Zero.
    pub reserved: u32,
    /// How long it lasts, nanoseconds of simulation time (0 and not
    /// permanent: until the next frame).
    pub life_ns: u64,
    /// A point's size, a line's, an arrow's or a box's thickness, metres.
    pub size: f32,
    /// An arrow's head, metres.
    pub arrow_size: f32,
    /// A point's place, a line's start, a box's centre, a text's place.
    pub a: [f32; 3],
    /// A line's end; a box's half extents.
    pub b: [f32; 3],
    /// A box's orientation (x, y, z, w).
    pub rotation: [f32; 4],
    /// A text's words.
    pub text: FixedText,
}

impl Default for DebugShape {
    fn default() -> Self {
        Self {
            kind: ShapeKind::Point as u32,
            flags: 0,
            color: [255, 0, 0, 255],
            reserved: 0,
            life_ns: 0,
            size: 0.1,
            arrow_size: 0.1,
            a: [0.0; 3],
            b: [0.0; 3],
            rotation: [0.0, 0.0, 0.0, 1.0],
            text: FixedText::new(""),
        }
    }
}

/// Why a shape is refused.
#[derive(Debug, Clone, Copy, PartialEq, Eq, thiserror::Error)]
pub enum DebugShapeError {
    /// An unknown kind.
    #[error("unknown debug shape kind {0}")]
    UnknownKind(u32),
    /// A coordinate, size or rotation that is not a finite number.
    #[error("a debug shape's coordinates, sizes and rotation must be finite numbers")]
    NotFinite,
    /// A negative size.
    #[error("a debug shape's sizes must not be negative")]
    NegativeSize,
    /// Text that is not UTF-8 or longer than its field.
    #[error("a debug text must be UTF-8 of at most 64 bytes")]
    BadText,
}

impl DebugShape {
    /// Drawn on the spectator's screen (CARLA's `draw_hud_*`); viewers
    /// without one draw it in the world.
    pub const HUD: u32 = 1;
    /// Lasts until cleared.
    pub const PERMANENT: u32 = 2;

    /// What it draws.
    pub fn shape_kind(&self) -> Option<ShapeKind> {
        ShapeKind::from_u32(self.kind)
    }

    /// Lasting `seconds` of simulation time: CARLA's `life_time` (below 0:
    /// one frame; 0: permanent; past [`MAX_DEBUG_LIFE_SECONDS`]: that).
    pub fn lasting(mut self, seconds: f64) -> Self {
        if seconds == 0.0 {
            self.flags |= Self::PERMANENT;
            self.life_ns = 0;
        } else if seconds > 0.0 {
            self.flags &= !Self::PERMANENT;
            self.life_ns = (seconds.min(MAX_DEBUG_LIFE_SECONDS) * 1e9) as u64;
        } else {
            self.flags &= !Self::PERMANENT;
            self.life_ns = 0;
        }
        self
    }

    /// Whether it lasts until cleared.
    pub fn is_permanent(&self) -> bool {
        self.flags & Self::PERMANENT != 0
    }

    /// Checks it can be drawn.
    ///
    /// # Errors
    ///
    /// Returns the [`DebugShapeError`] naming what is wrong.
    pub fn check(&self) -> Result<(), DebugShapeError> {
        if self.shape_kind().is_none() {
            return Err(DebugShapeError::UnknownKind(self.kind));
        }
        let numbers = [self.size, self.arrow_size]
            .into_iter()
            .chain(self.a)
            .chain(self.b)
            .chain(self.rotation);
        if !numbers.clone().all(f32::is_finite) {
            return Err(DebugShapeError::NotFinite);
        }
        if self.size < 0.0 || self.arrow_size < 0.0 {
            return Err(DebugShapeError::NegativeSize);
        }
        let text = self.text.bytes.get(..self.text.len as usize);
        if text.is_none_or(|t| std::str::from_utf8(t).is_err()) {
            return Err(DebugShapeError::BadText);
        }
        Ok(())
    }
}

impl DebugShape {
    /// A box's 12 edges as 24 end points (simbus's axes): its corners
    /// turned by `rotation` about its centre `a`.
    pub fn box_edges(&self) -> [[f32; 3]; 24] {
        let [hx, hy, hz] = self.b;
        let corner = |i: usize| {
            let local = [
                if i & 1 == 0 { -hx } else { hx },
                if i & 2 == 0 { -hy } else { hy },
                if i & 4 == 0 { -hz } else { hz },
            ];
            let p = rotate(self.rotation, local);
            [p[0] + self.a[0], p[1] + self.a[1], p[2] + self.a[2]]
        };
        // Corner pairs that differ in one axis bit.
        const EDGES: [(usize, usize); 12] = [
            (0, 1),
            (2, 3),
            (4, 5),
            (6, 7),
            (0, 2),
            (1, 3),
            (4, 6),
            (5, 7),
            (0, 4),
            (1, 5),
            (2, 6),
            (3, 7),
        ];
        let mut out = [[0.0; 3]; 24];
        for (k, (i, j)) in EDGES.iter().enumerate() {
            out[2 * k] = corner(*i);
            out[2 * k + 1] = corner(*j);
        }
        out
    }

    /// An arrow's head: two short strokes back from its tip `b`, in the
    /// plane of the arrow and the vertical (simbus's axes), `arrow_size`
    /// long; none for an arrow of no length.
    pub fn arrow_head(&self) -> Option<[[f32; 3]; 4]> {
        let d = [
            self.b[0] - self.a[0],
            self.b[1] - self.a[1],
            self.b[2] - self.a[2],
        ];
        let length = (d[0] * d[0] + d[1] * d[1] + d[2] * d[2]).sqrt();
        if length < 1e-6 {
            return None;
        }
        let back = d.map(|v| -v / length);
        // A side direction: across the arrow, horizontal where it can be.
        let mut side = [back[2], 0.0, -back[0]];
        let side_length = (side[0] * side[0] + side[2] * side[2]).sqrt();
        if side_length < 1e-6 {
            side = [1.0, 0.0, 0.0];
        } else {
            side = side.map(|v| v / side_length);
        }
        let s = self.arrow_size;
        let wing = |sign: f32| [0, 1, 2].map(|i| self.b[i] + s * (back[i] + sign * 0.5 * side[i]));
        Some([self.b, wing(1.0), self.b, wing(-1.0)])
    }
}

/// `v` turned by the unit quaternion `q` (x, y, z, w).
fn rotate(q: [f32; 4], v: [f32; 3]) -> [f32; 3] {
    let [x, y, z, w] = q;
    // t = 2 q.xyz × v; v' = v + w t + q.xyz × t
    let t = [
        2.0 * (y * v[2] - z * v[1]),
        2.0 * (z * v[0] - x * v[2]),
        2.0 * (x * v[1] - y * v[0]),
    ];
    [
        v[0] + w * t[0] + (y * t[2] - z * t[1]),
        v[1] + w * t[1] + (z * t[0] - x * t[2]),
        v[2] + w * t[2] + (x * t[1] - y * t[0]),
    ]
}

wire_enum! {
    /// What a [`DebugRequest`] asks for.
    #[derive(Debug, Clone, Copy, PartialEq, Eq)]
    pub enum DebugRequestKind {
        /// Keep `shape` until it expires.
        Draw = 1,
        /// Every shape kept now.
        List = 2,
        /// Forget every shape.
        Clear = 3,
    }
}

/// A request on the debug-drawing service.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::DebugRequest/1")]
pub struct DebugRequest {
    /// [`PROTOCOL_VERSION`] of the sender.
    pub protocol_version: u32,
    /// [`DebugRequestKind`] as `u32`.
    pub kind: u32,
    /// The shape to draw.
    pub shape: DebugShape,
}

impl DebugRequest {
    /// A request of `kind` (with `shape` for a draw).
    pub fn new(kind: DebugRequestKind, shape: DebugShape) -> Self {
        Self {
            protocol_version: PROTOCOL_VERSION,
            kind: kind as u32,
            shape,
        }
    }
}

/// The user header of a debug-service answer (its payload: the shapes
/// kept, for a list).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::DebugResponseHeader/1")]
pub struct DebugResponseHeader {
    /// [`PROTOCOL_VERSION`] of the server.
    pub protocol_version: u32,
    /// [`ResponseStatus`](crate::wire::ResponseStatus) as `u32`
    /// (`Refused`: a shape that is wrong, or one too many).
    pub status: u32,
    /// The frame the answer concerns: the next one for a draw.
    pub frame: u64,
}

crate::wire::responses!(DebugResponseHeader);

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn the_layouts_are_the_wire_chapters() {
        assert_eq!(std::mem::size_of::<DebugShape>(), 144);
        assert_eq!(std::mem::size_of::<DebugRequest>(), 152);
        assert_eq!(std::mem::size_of::<DebugResponseHeader>(), 16);
    }

    #[test]
    fn carlas_life_times_read_as_one_frame_permanent_or_seconds() {
        let one_frame = DebugShape::default().lasting(-1.0);
        assert!(!one_frame.is_permanent() && one_frame.life_ns == 0);
        let permanent = DebugShape::default().lasting(0.0);
        assert!(permanent.is_permanent());
        let timed = DebugShape::default().lasting(2.5);
        assert_eq!(
            (timed.is_permanent(), timed.life_ns),
            (false, 2_500_000_000)
        );
        let long = DebugShape::default().lasting(1e300);
        assert_eq!(long.life_ns, (MAX_DEBUG_LIFE_SECONDS * 1e9) as u64);
    }

    #[test]
    fn a_boxs_edges_and_an_arrows_head_are_where_they_should_be() {
        let cube = DebugShape {
            kind: ShapeKind::Box as u32,
            a: [10.0, 0.0, 0.0],
            b: [1.0, 2.0, 3.0],
            ..DebugShape::default()
        };
        let edges = cube.box_edges();
        for p in edges {
            assert_eq!(
                [(p[0] - 10.0).abs(), p[1].abs(), p[2].abs()],
                [1.0, 2.0, 3.0]
            );
        }
        // Each edge runs along one axis.
        for pair in edges.chunks(2) {
            let same = (0..3).filter(|&i| pair[0][i] == pair[1][i]).count();
            assert_eq!(same, 2, "{pair:?}");
        }
        let arrow = DebugShape {
            kind: ShapeKind::Arrow as u32,
            a: [0.0, 0.0, 0.0],
            b: [4.0, 0.0, 0.0],
            arrow_size: 1.0,
            ..DebugShape::default()
        };
        let head = arrow.arrow_head().unwrap();
        assert_eq!(head[0], [4.0, 0.0, 0.0]);
        assert_eq!(head[1], [3.0, 0.0, 0.5]);
        assert_eq!(head[3], [3.0, 0.0, -0.5]);
        assert!(DebugShape {
            b: [0.0; 3],
            ..arrow
        }
        .arrow_head()
        .is_none());
    }

    #[test]
    fn wrong_shapes_are_refused_with_what_is_wrong() {
        assert_eq!(DebugShape::default().check(), Ok(()));
        let unknown = DebugShape {
            kind: 99,
            ..DebugShape::default()
        };
        assert_eq!(unknown.check(), Err(DebugShapeError::UnknownKind(99)));
        let nan = DebugShape {
            a: [f32::NAN, 0.0, 0.0],
            ..DebugShape::default()
        };
        assert_eq!(nan.check(), Err(DebugShapeError::NotFinite));
        let negative = DebugShape {
            size: -1.0,
            ..DebugShape::default()
        };
        assert_eq!(negative.check(), Err(DebugShapeError::NegativeSize));
        let mut garbage = DebugShape::default();
        garbage.text.len = 1000;
        assert_eq!(garbage.check(), Err(DebugShapeError::BadText));
    }
}
