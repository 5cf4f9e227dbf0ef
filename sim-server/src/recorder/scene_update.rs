//! A frame as Foxglove's 3D panel draws it: a `foxglove.SceneUpdate`.

use serde::Serialize;
use serde_json::json;
use shared_types::{ActorKind, ActorState, FrameHeader};

/// A `foxglove.SceneUpdate` (JSON encoding) with one entity per actor: a
/// cube for boxes, statics and vehicles, a sphere, or a cylinder for a
/// capsule. Foxglove's frame is Z up, simbus's Y up: positions become
/// (x, -z, y). Typed and serialized straight into the writer's buffer (a
/// `serde_json::Value` tree per actor cost more than the rest of recording).
pub(super) fn scene_update(
    out: &mut Vec<u8>,
    header: &FrameHeader,
    actors: &[ActorState],
    log_ns: u64,
) {
    let stamp = Time {
        sec: log_ns / 1_000_000_000,
        nsec: (log_ns % 1_000_000_000) as u32,
    };
    let frame = header.timestamp.frame;
    let entities = actors.iter().map(|a| entity(a, stamp, frame));
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
