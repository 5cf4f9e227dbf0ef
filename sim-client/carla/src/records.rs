//! CARLA's `rpc::Actor` records the gateway answers for actors
//! (`get_actors_by_id`, a spawn's answer, a sensor's parent): a simbus
//! body's with the blueprint it was spawned from (or its kind's type id),
//! a sensor's with its stream's token, a walker controller's, a traffic
//! light's or sign's (its trigger volume for a bounding box, as CARLA's
//! client reads `trigger_volume`), and the spectator's.

use rmpv::Value;
use shared_types::ActorKind;

use crate::blueprints;
use crate::locks::lock;
use crate::stream::ActorInfo;
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

/// CARLA's semantic tags of an actor of `kind` spawned as `type_id`
/// (`actor.semantic_tags`): what its camera pixels say.
fn semantic_tags(kind: u32, type_id: &str) -> Vec<u8> {
    use shared_types::SemanticTag as T;
    let tag = match ActorKind::from_u32(kind) {
        Some(ActorKind::Vehicle) => match blueprints::vehicle_class(type_id) {
            Some(blueprints::Class::Truck | blueprints::Class::Van) => T::Truck,
            Some(blueprints::Class::Bus) => T::Bus,
            Some(blueprints::Class::Motorcycle) => T::Motorcycle,
            Some(blueprints::Class::Bicycle) => T::Bicycle,
            _ => T::Car,
        },
        Some(ActorKind::Walker) => T::Pedestrians,
        Some(ActorKind::TrafficLight) => T::TrafficLight,
        Some(ActorKind::TrafficSign) => T::TrafficSigns,
        Some(ActorKind::Box | ActorKind::Sphere | ActorKind::Capsule) => T::Dynamic,
        _ => T::Static,
    };
    vec![tag as u8]
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
    located_box(id, [0.0; 3], extent, [0.0; 3])
}

/// CARLA's `BoundingBox` of actor `id` centred at `location`, turned by
/// `rotation` (pitch, yaw, roll, degrees).
pub(crate) fn located_box(
    id: u32,
    location: [f32; 3],
    extent: [f32; 3],
    rotation: [f32; 3],
) -> Value {
    let vector = |v: [f32; 3]| Value::Array(v.iter().map(|&x| Value::F32(x)).collect());
    Value::Array(vec![
        vector(location),
        vector(extent),
        vector(rotation),
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
    let last = lock(&hub.actors).get(&id).copied();
    if let Some(record) = last.and_then(|a| signal_record(hub, id, &a)) {
        return Some(record);
    }
    let (kind, extent) = match last {
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
    let blueprint = description
        .as_array()
        .and_then(|d| d.get(1)?.as_str())
        .unwrap_or_default();
    let tags = semantic_tags(kind, blueprint);
    let mut record = actor_record(id, 0, description, extent, Value::Binary(Vec::new()));
    if let Value::Array(fields) = &mut record {
        fields[4] = Value::Binary(tags);
    }
    Some(record)
}

/// The `rpc::Actor` of traffic light or sign `id`: CARLA's type id for
/// it (`traffic.traffic_light`, `traffic.stop`, `traffic.speed_limit.30`)
/// and its trigger volume for a box (none for a speed-limit sign).
fn signal_record(hub: &crate::stream::Hub, id: u32, actor: &ActorInfo) -> Option<Value> {
    let signals = lock(&hub.signals);
    let type_id = signals.type_id(id)?;
    let description = blueprints::scene_description(actor.kind, &type_id);
    let (location, extent) = signals
        .trigger_volume(id, actor.position, actor.rotation)
        .unwrap_or(([0.0; 3], [0.0; 3]));
    Some(Value::Array(vec![
        Value::from(id),
        Value::from(0u32),
        description,
        located_box(id, location, extent, [0.0; 3]),
        Value::Binary(semantic_tags(actor.kind, &type_id)),
        Value::Binary(Vec::new()),
    ]))
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
