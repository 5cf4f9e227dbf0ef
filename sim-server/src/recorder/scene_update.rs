//! A frame as Foxglove's 3D panel draws it: a `foxglove.SceneUpdate`.

use serde::Serialize;
use serde_json::json;
use shared_types::{ActorKind, ActorState, DebugShape, FrameHeader, ShapeKind};

/// A `foxglove.SceneUpdate` (JSON encoding) with one entity per actor: a
/// cube for boxes, statics and vehicles, a sphere, or a cylinder for a
/// capsule. Foxglove's frame is Z up, simbus's Y up: positions become
/// (x, -z, y). Typed and serialized straight into the writer's buffer (a
/// `serde_json::Value` tree per actor cost more than the rest of recording).
pub(super) fn scene_update(
    out: &mut Vec<u8>,
    header: &FrameHeader,
    (actors, shapes): (&[ActorState], &[DebugShape]),
    log_ns: u64,
) {
    let stamp = Time {
        sec: log_ns / 1_000_000_000,
        nsec: (log_ns % 1_000_000_000) as u32,
    };
    let frame = header.timestamp.frame;
    let entities = actors
        .iter()
        .map(|a| entity(a, stamp, frame))
        .chain(debug_entity(shapes, stamp));
    let update = SceneUpdate {
        deletions: [Deletion {
            timestamp: stamp,
            r#type: 1,
            id: "",
        }],
        entities: Entities(std::cell::Cell::new(Some(entities))),
    };
    // Serializing plain numbers and strings into a Vec cannot fail.
    let _ = serde_json::to_writer(out, &update);
}

/// The debug shapes as one entity (`debug`): points as spheres, lines,
/// arrows and boxes as line lists, texts as billboards; none without
/// shapes.
fn debug_entity(shapes: &[DebugShape], stamp: Time) -> Option<Entity> {
    if shapes.is_empty() {
        return None;
    }
    let at = |p: [f32; 3]| Xyz {
        x: p[0],
        y: -p[2],
        z: p[1],
    };
    let color = |s: &DebugShape| {
        let [r, g, b, a] = s.color.map(|c| f32::from(c) / 255.0);
        Color { r, g, b, a }
    };
    let placed = |p: [f32; 3]| Pose {
        position: at(p),
        orientation: Quaternion {
            x: 0.0,
            y: 0.0,
            z: 0.0,
            w: 1.0,
        },
    };
    let (mut spheres, mut lines, mut texts) = (Vec::new(), Vec::new(), Vec::new());
    for s in shapes {
        let line = |points: Vec<Xyz>| Line {
            r#type: 2,
            pose: placed([0.0; 3]),
            thickness: s.size.max(0.01),
            scale_invariant: false,
            points,
            color: color(s),
        };
        match s.shape_kind() {
            Some(ShapeKind::Point) => spheres.push(Primitive {
                pose: placed(s.a),
                size: Xyz {
                    x: s.size,
                    y: s.size,
                    z: s.size,
                },
                color: color(s),
            }),
            Some(ShapeKind::Line) => lines.push(line(vec![at(s.a), at(s.b)])),
            Some(ShapeKind::Arrow) => {
                let mut points = vec![at(s.a), at(s.b)];
                points.extend(s.arrow_head().into_iter().flatten().map(at));
                lines.push(line(points));
            }
            Some(ShapeKind::Box) => lines.push(line(s.box_edges().map(at).to_vec())),
            Some(ShapeKind::Text) => texts.push(TextPrimitive {
                pose: placed(s.a),
                billboard: true,
                font_size: 14.0,
                scale_invariant: true,
                color: color(s),
                text: s.text.to_string_lossy(),
            }),
            None => {}
        }
    }
    Some(Entity {
        timestamp: stamp,
        frame_id: "simbus",
        id: DEBUG_ENTITY,
        metadata: (
            KeyValue {
                key: "kind",
                value: Text("debug"),
            },
            KeyValue {
                key: "frame",
                value: Text(0),
            },
        ),
        cubes: None,
        spheres: None,
        cylinders: None,
        debug_spheres: spheres,
        lines,
        texts,
    })
}

/// One actor's entity, drawn as its kind's primitive in its kind's colour.
fn entity(a: &ActorState, stamp: Time, frame: u64) -> Entity {
    let [ex, ey, ez] = a.extent;
    let (pose, kind) = (pose(a), ActorKind::from_u32(a.kind));
    let color = color(kind);
    let size = |x: f32, y: f32, z: f32| Xyz {
        x: 2.0 * x,
        y: 2.0 * z,
        z: 2.0 * y,
    };
    let primitive = |size| Primitive { pose, size, color };
    let (cubes, spheres, cylinders) = match kind {
        Some(ActorKind::Sphere) => (None, Some(primitive(size(ex, ex, ex))), None),
        Some(ActorKind::Capsule) => (None, None, Some(primitive(size(ex, ey + ex, ex)))),
        Some(ActorKind::Walker) => (None, None, Some(primitive(size(ex, ey, ex)))),
        _ => (Some(primitive(size(ex, ey, ez))), None, None),
    };
    Entity {
        timestamp: stamp,
        frame_id: "simbus",
        id: a.id,
        metadata: (
            KeyValue {
                key: "kind",
                value: Text(kind.map_or("unknown", |k| k.name())),
            },
            KeyValue {
                key: "frame",
                value: Text(frame),
            },
        ),
        cubes,
        spheres,
        cylinders,
        debug_spheres: Vec::new(),
        lines: Vec::new(),
        texts: Vec::new(),
    }
}

/// An actor's pose in Foxglove's frame (Z up).
fn pose(a: &ActorState) -> Pose {
    let [x, y, z] = a.position;
    let [qx, qy, qz, qw] = a.rotation;
    Pose {
        position: Xyz { x, y: -z, z: y },
        orientation: Quaternion {
            x: qx,
            y: -qz,
            z: qy,
            w: qw,
        },
    }
}

/// Grey statics, red vehicles, blue the rest.
fn color(kind: Option<ActorKind>) -> Color {
    match kind {
        Some(ActorKind::Static) => Color {
            r: 0.5,
            g: 0.5,
            b: 0.5,
            a: 1.0,
        },
        Some(ActorKind::Vehicle) => Color {
            r: 0.9,
            g: 0.2,
            b: 0.2,
            a: 1.0,
        },
        Some(ActorKind::Walker) => Color {
            r: 0.95,
            g: 0.75,
            b: 0.2,
            a: 1.0,
        },
        _ => Color {
            r: 0.2,
            g: 0.5,
            b: 0.9,
            a: 1.0,
        },
    }
}

#[derive(Serialize, Clone, Copy)]
struct Time {
    sec: u64,
    nsec: u32,
}

#[derive(Serialize, Clone, Copy)]
struct Xyz {
    x: f32,
    y: f32,
    z: f32,
}

#[derive(Serialize, Clone, Copy)]
struct Quaternion {
    x: f32,
    y: f32,
    z: f32,
    w: f32,
}

#[derive(Serialize, Clone, Copy)]
struct Pose {
    position: Xyz,
    orientation: Quaternion,
}

#[derive(Serialize, Clone, Copy)]
struct Color {
    r: f32,
    g: f32,
    b: f32,
    a: f32,
}

#[derive(Serialize, Clone, Copy)]
struct Primitive {
    pose: Pose,
    size: Xyz,
    color: Color,
}

/// Anything printed as a JSON string.
struct Text<T>(T);

impl<T: std::fmt::Display> Serialize for Text<T> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_str(&self.0)
    }
}

#[derive(Serialize)]
struct KeyValue<V> {
    key: &'static str,
    value: V,
}

#[derive(Serialize)]
struct Entity {
    timestamp: Time,
    frame_id: &'static str,
    #[serde(serialize_with = "as_text")]
    id: u64,
    metadata: (KeyValue<Text<&'static str>>, KeyValue<Text<u64>>),
    // Fields left out are Foxglove's defaults (protobuf JSON): no lifetime
    // (forever), not frame-locked, no other primitives.
    #[serde(skip_serializing_if = "Option::is_none", serialize_with = "one")]
    cubes: Option<Primitive>,
    #[serde(skip_serializing_if = "Option::is_none", serialize_with = "one")]
    spheres: Option<Primitive>,
    #[serde(skip_serializing_if = "Option::is_none", serialize_with = "one")]
    cylinders: Option<Primitive>,
    /// The debug entity's points (Foxglove's `spheres`, many).
    #[serde(skip_serializing_if = "Vec::is_empty", rename = "spheres")]
    debug_spheres: Vec<Primitive>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    lines: Vec<Line>,
    #[serde(skip_serializing_if = "Vec::is_empty")]
    texts: Vec<TextPrimitive>,
}

/// The id of the debug shapes' entity (no actor has id 0).
const DEBUG_ENTITY: u64 = 0;

/// Foxglove's `LinePrimitive` (`type` 2: a list of segments).
#[derive(Serialize)]
struct Line {
    r#type: u32,
    pose: Pose,
    thickness: f32,
    scale_invariant: bool,
    points: Vec<Xyz>,
    color: Color,
}

/// Foxglove's `TextPrimitive`.
#[derive(Serialize)]
struct TextPrimitive {
    pose: Pose,
    billboard: bool,
    font_size: f32,
    scale_invariant: bool,
    color: Color,
    text: String,
}

/// A primitive as the one-element list Foxglove expects.
fn one<S: serde::Serializer>(primitive: &Option<Primitive>, s: S) -> Result<S::Ok, S::Error> {
    s.collect_seq(primitive)
}

fn as_text<S: serde::Serializer>(id: &u64, s: S) -> Result<S::Ok, S::Error> {
    s.collect_str(id)
}

#[derive(Serialize)]
struct Deletion {
    timestamp: Time,
    r#type: u32,
    id: &'static str,
}

/// The entities, serialized as a sequence straight from the iterator.
struct Entities<I>(std::cell::Cell<Option<I>>);

impl<I: Iterator<Item = Entity>> Serialize for Entities<I> {
    fn serialize<S: serde::Serializer>(&self, s: S) -> Result<S::Ok, S::Error> {
        s.collect_seq(self.0.take().into_iter().flatten())
    }
}

#[derive(Serialize)]
#[serde(bound(serialize = "I: Iterator<Item = Entity>"))]
struct SceneUpdate<I: Iterator<Item = Entity>> {
    deletions: [Deletion; 1],
    entities: Entities<I>,
}

/// A JSON schema for `foxglove.SceneUpdate` sufficient for Foxglove to
/// recognise the schema by name; the full one is Foxglove's.
pub(super) fn scene_update_schema() -> serde_json::Value {
    json!({
        "title": "foxglove.SceneUpdate",
        "type": "object",
        "properties": {
            "deletions": {"type": "array"},
            "entities": {"type": "array"}
        }
    })
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared_types::FixedText;

    #[test]
    fn debug_shapes_join_the_scene_as_one_entity_of_spheres_lines_and_texts() {
        let header = FrameHeader::default();
        let point = DebugShape::default();
        let arrow = DebugShape {
            kind: ShapeKind::Arrow as u32,
            b: [1.0, 0.0, 0.0],
            ..DebugShape::default()
        };
        let label = DebugShape {
            kind: ShapeKind::Text as u32,
            a: [1.0, 2.0, 3.0],
            text: FixedText::new("spawn 7"),
            ..DebugShape::default()
        };
        let mut out = Vec::new();
        scene_update(&mut out, &header, (&[], &[point, arrow, label]), 0);
        let json: serde_json::Value = serde_json::from_slice(&out).unwrap();
        let entities = json["entities"].as_array().unwrap();
        assert_eq!(entities.len(), 1);
        let debug = &entities[0];
        assert_eq!(debug["spheres"].as_array().unwrap().len(), 1);
        // The arrow: its shaft and its head's two strokes.
        assert_eq!(debug["lines"][0]["points"].as_array().unwrap().len(), 6);
        assert_eq!(debug["texts"][0]["text"], "spawn 7");
        // Foxglove's Z up: simbus's (1, 2, 3) is (1, -3, 2).
        let p = &debug["texts"][0]["pose"]["position"];
        assert_eq!(
            (p["x"].as_f64(), p["y"].as_f64(), p["z"].as_f64()),
            (Some(1.0), Some(-3.0), Some(2.0))
        );
        // No shapes: no debug entity.
        let mut empty = Vec::new();
        scene_update(&mut empty, &header, (&[], &[]), 0);
        let json: serde_json::Value = serde_json::from_slice(&empty).unwrap();
        assert!(json["entities"].as_array().unwrap().is_empty());
    }
}
