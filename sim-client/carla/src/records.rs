//! CARLA's `rpc::Actor` records the gateway answers for actors
//! (`get_actors_by_id`, a spawn's answer, a sensor's parent): a simbus
//! body's with the blueprint it was spawned from (or its kind's type id),
//! a sensor's with its stream's token, a walker controller's, and the
//! spectator's.

use rmpv::Value;
use shared_types::ActorKind;

use crate::blueprints;
use crate::locks::lock;
use crate::wire::{token, SPECTATOR_ID};

/// CARLA's type id of a simbus actor kind.
pub(crate) fn type_id(kind: u32) -> &'static str {
    match ActorKind::from_u32(kind) {
        Some(ActorKind::Box) => "static.prop.box",
        Some(ActorKind::Sphere) => "static.prop.sphere",
        Some(ActorKind::Capsule) => "static.prop.capsule",
        Some(ActorKind::Vehicle) => "vehicle.simbus.car",
        Some(ActorKind::Walker) => "walker.pedestrian.0001",
        _ => "static.prop.fixed",
    }
}

/// The spectator's `rpc::Actor`: CARLA's type id `spectator`, no
/// attributes, no extent.
fn spectator_record() -> Value {
    let description = Value::Array(vec![
        Value::from(0u8),
        Value::from("spectator"),
        Value::Array(Vec::new()),
    ]);
    actor_record(
        SPECTATOR_ID,
        0,
        description,
        [0.0; 3],
        Value::Binary(Vec::new()),
    )
}

/// CARLA's `BoundingBox` of actor `id`: centred, `extent` half sizes.
pub(crate) fn bounding_box(id: u32, extent: [f32; 3]) -> Value {
    let vector = |v: [f32; 3]| Value::Array(v.iter().map(|&x| Value::F32(x)).collect());
    Value::Array(vec![
        vector([0.0; 3]),
        vector(extent),
        vector([0.0; 3]),
        Value::from(id),
    ])
}

/// CARLA's `rpc::Actor` of actor `id` (a sensor's with its stream's token
/// on `streaming_port`), if the world has it.
pub(crate) fn record_of(hub: &crate::stream::Hub, id: u32, streaming_port: u16) -> Option<Value> {
    if id == SPECTATOR_ID {
        return Some(spectator_record());
    }
    let registry = lock(&hub.registry);
    if let Some(sensor) = registry.sensors.get(&id) {
        // A walker's AI controller streams nothing: CARLA's client tells it
        // from a sensor by that (and then by its blueprint id).
        let controller = sensor
            .description
            .as_array()
            .and_then(|d| d.get(1)?.as_str())
            .is_some_and(|bp| bp == "controller.ai.walker");
        let stream = if controller {
            Vec::new()
        } else {
            token(id, streaming_port).to_vec()
        };
        return Some(actor_record(
            id,
            sensor.parent,
            sensor.description.clone(),
            [0.0; 3],
            Value::Binary(stream),
        ));
    }
    let (kind, extent) = match lock(&hub.actors).get(&id) {
        Some(a) => (a.kind, a.extent),
        None => {
            // Spawned through the gateway, not in a frame yet.
            let description = registry.descriptions.get(&id)?;
            let uid = description.as_array()?.first()?.as_u64()?;
            (
                blueprints::kind_of_uid(uid),
                blueprints::spawned_extent(description),
            )
        }
    };
    let description = registry
        .descriptions
        .get(&id)
        .cloned()
        .unwrap_or_else(|| blueprints::scene_description(kind, type_id(kind)));
    Some(actor_record(
        id,
        0,
        description,
        extent,
        Value::Binary(Vec::new()),
    ))
}

/// CARLA's `rpc::Actor`: id, parent, description, bounding box, no
/// semantic tags, and the stream token (sensors only).
fn actor_record(
    id: u32,
    parent: u32,
    description: Value,
    extent: [f32; 3],
    stream: Value,
) -> Value {
    Value::Array(vec![
        Value::from(id),
        Value::from(parent),
        description,
        bounding_box(id, extent),
        Value::Binary(Vec::new()),
        stream,
    ])
}
