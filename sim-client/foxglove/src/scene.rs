//! Frames as Foxglove's scene: every actor a `foxglove.SceneUpdate`
//! entity in frame `world`, stamped with the frame's simulation time.

use foxglove::messages::line_primitive::Type as LineType;
use foxglove::messages::{
    Color, CubePrimitive, CylinderPrimitive, LinePrimitive, Point3, Pose, Quaternion, SceneEntity,
    SpherePrimitive, TextPrimitive, Timestamp, Vector3,
};
use shared_types::{ActorKind, ActorState, DebugShape, LightState, ShapeKind, NANOS_PER_SECOND};
use simbus_pose::compose;

/// A frame's simulation time as a Foxglove timestamp.
pub(crate) fn stamp(elapsed_ns: u64) -> Timestamp {
    Timestamp::new(
        u32::try_from(elapsed_ns / NANOS_PER_SECOND).unwrap_or(u32::MAX),
        (elapsed_ns % NANOS_PER_SECOND) as u32,
    )
}

fn vector(v: [f32; 3]) -> Vector3 {
    Vector3 {
        x: f64::from(v[0]),
        y: f64::from(v[1]),
        z: f64::from(v[2]),
    }
}

pub(crate) fn pose(position: [f32; 3], rotation: [f32; 4]) -> Pose {
    let [x, y, z, w] = rotation.map(f64::from);
    Pose {
        position: Some(vector(position)),
        orientation: Some(Quaternion { x, y, z, w }),
    }
}

/// No rotation (x, y, z, w).
pub(crate) const IDENTITY: [f32; 4] = [0.0, 0.0, 0.0, 1.0];

/// An actor's colour: its kind's, a traffic light's by what it shows.
fn colour(actor: &ActorState) -> Color {
    if let Some(light) = actor.light() {
        let (r, g, b) = match light.state {
            LightState::Red => (0.9, 0.12, 0.12),
            LightState::Yellow => (0.95, 0.77, 0.1),
            LightState::Green => (0.12, 0.82, 0.28),
            LightState::Off => (0.17, 0.17, 0.17),
        };
        return Color { r, g, b, a: 1.0 };
    }
    let (r, g, b) = match ActorKind::from_u32(actor.kind) {
        Some(ActorKind::Static) => (0.55, 0.55, 0.55),
        Some(ActorKind::Box) => (0.85, 0.55, 0.25),
        Some(ActorKind::Sphere) => (0.25, 0.55, 0.85),
        Some(ActorKind::Capsule) => (0.35, 0.75, 0.35),
        Some(ActorKind::Vehicle) => (0.85, 0.2, 0.2),
        Some(ActorKind::Walker) => (0.95, 0.75, 0.2),
        Some(ActorKind::TrafficLight) => (0.17, 0.17, 0.17),
        Some(ActorKind::TrafficSign) => (0.82, 0.19, 0.19),
        None => (1.0, 0.0, 1.0),
    };
    Color { r, g, b, a: 1.0 }
}

/// One actor as a scene entity: its body as primitives in the body's frame.
pub(crate) fn entity(actor: &ActorState, time: Timestamp) -> SceneEntity {
    let kind = ActorKind::from_u32(actor.kind);
    let [ex, ey, ez] = actor.extent;
    let color = Some(colour(actor));
    let mut entity = SceneEntity {
        timestamp: Some(time),
        frame_id: "world".into(),
        id: actor.id.to_string(),
        ..Default::default()
    };
    let body = Some(pose(actor.position, actor.rotation));
    match kind {
        Some(ActorKind::Sphere) => entity.spheres.push(SpherePrimitive {
            pose: body,
            size: Some(vector([2.0 * ex; 3])),
            color,
        }),
        Some(k @ (ActorKind::Capsule | ActorKind::Walker)) => {
            // A capsule (radius, half height): a cylinder along the body's Y
            // (Foxglove's run along Z: a quarter turn about X) and a sphere
            // at each end, placed in the world through the body's pose. A
            // walker's half height counts its round ends.
            let radius = ex;
            let half = if k == ActorKind::Walker {
                (ey - ex).max(0.0)
            } else {
                ey
            };
            let quarter = std::f32::consts::FRAC_1_SQRT_2;
            entity.cylinders.push(CylinderPrimitive {
                pose: Some(placed(actor, ([0.0; 3], [quarter, 0.0, 0.0, quarter]))),
                size: Some(vector([2.0 * radius, 2.0 * radius, 2.0 * half])),
                bottom_scale: 1.0,
                top_scale: 1.0,
                color,
            });
            for end in [-half, half] {
                entity.spheres.push(SpherePrimitive {
                    pose: Some(placed(actor, ([0.0, end, 0.0], IDENTITY))),
                    size: Some(vector([2.0 * radius; 3])),
                    color,
                });
            }
        }
        _ => entity.cubes.push(CubePrimitive {
            pose: body,
            size: Some(vector([2.0 * ex, 2.0 * ey, 2.0 * ez])),
            color,
        }),
    }
    entity
}

/// Something at `offset` (position, rotation) in the body of `actor`, in
/// the world frame.
pub(crate) fn placed(actor: &ActorState, offset: ([f32; 3], [f32; 4])) -> Pose {
    let (position, rotation) = compose((actor.position, actor.rotation), offset);
    pose(position, rotation)
}

/// The debug shapes clients drew, as one entity (`debug`): points as
/// spheres, lines, arrows and boxes as line lists, texts as billboards;
/// none without shapes.
pub(crate) fn debug_entity(shapes: &[DebugShape], time: Timestamp) -> Option<SceneEntity> {
    if shapes.is_empty() {
        return None;
    }
    let mut entity = SceneEntity {
        timestamp: Some(time),
        frame_id: "world".into(),
        id: "debug".into(),
        ..Default::default()
    };
    let point = |p: [f32; 3]| Point3 {
        x: f64::from(p[0]),
        y: f64::from(p[1]),
        z: f64::from(p[2]),
    };
    for s in shapes {
        let [r, g, b, a] = s.color.map(|c| f64::from(c) / 255.0);
        let color = Some(Color { r, g, b, a });
        let lines = |points: Vec<Point3>| LinePrimitive {
            r#type: LineType::LineList as i32,
            pose: Some(pose([0.0; 3], IDENTITY)),
            thickness: f64::from(s.size.max(0.01)),
            scale_invariant: false,
            points,
            color,
            ..Default::default()
        };
        match s.shape_kind() {
            Some(ShapeKind::Point) => entity.spheres.push(SpherePrimitive {
                pose: Some(pose(s.a, IDENTITY)),
                size: Some(vector([s.size; 3])),
                color,
            }),
            Some(ShapeKind::Line) => entity.lines.push(lines(vec![point(s.a), point(s.b)])),
            Some(ShapeKind::Arrow) => {
                let mut points = vec![point(s.a), point(s.b)];
                points.extend(s.arrow_head().into_iter().flatten().map(point));
                entity.lines.push(lines(points));
            }
            Some(ShapeKind::Box) => {
                entity.lines.push(lines(s.box_edges().map(point).to_vec()));
            }
            Some(ShapeKind::Text) => entity.texts.push(TextPrimitive {
                pose: Some(pose(s.a, IDENTITY)),
                billboard: true,
                font_size: 14.0,
                scale_invariant: true,
                color,
                text: s.text.to_string_lossy(),
            }),
            None => {}
        }
    }
    Some(entity)
}
