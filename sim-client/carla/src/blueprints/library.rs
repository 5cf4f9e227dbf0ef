//! The library as CARLA lists it (`get_actor_definitions`): simbus's own
//! blueprints, CARLA's vehicles, walkers and walker controller, each with
//! CARLA's attributes; and the description a scene actor reports.

use std::sync::OnceLock;

use rmpv::Value;
use shared_types::ActorKind;

use super::{catalog, Attribute, Kind, LIBRARY};

/// One attribute of a listed blueprint: CARLA's `ActorAttribute`.
#[derive(Debug, Clone)]
pub(super) struct Attr {
    pub(super) id: &'static str,
    pub(super) kind: Kind,
    pub(super) value: String,
    recommended: Vec<String>,
    modifiable: bool,
    restricted: bool,
}

impl Attr {
    /// A simbus blueprint's attribute; one that may be set recommends its
    /// default, as CARLA's sensor attributes do (scripts read
    /// `recommended_values[0]`).
    fn of(a: &Attribute) -> Self {
        Self {
            id: a.id,
            kind: a.kind,
            value: a.default.to_string(),
            recommended: if a.modifiable {
                vec![a.default.to_string()]
            } else {
                Vec::new()
            },
            modifiable: a.modifiable,
            restricted: false,
        }
    }

    /// A fixed attribute.
    fn fixed(id: &'static str, kind: Kind, value: impl ToString) -> Self {
        Self {
            id,
            kind,
            value: value.to_string(),
            recommended: Vec::new(),
            modifiable: false,
            restricted: false,
        }
    }

    /// A modifiable attribute whose value starts as the first of
    /// `recommended` (as CARLA's do).
    fn choice(id: &'static str, kind: Kind, recommended: &[&str], restricted: bool) -> Self {
        Self {
            id,
            kind,
            value: recommended.first().copied().unwrap_or("").to_string(),
            recommended: recommended.iter().map(|r| r.to_string()).collect(),
            modifiable: true,
            restricted,
        }
    }
}

/// One blueprint of the library: CARLA's `ActorDefinition`.
#[derive(Debug, Clone)]
pub(super) struct Definition {
    pub(super) uid: u32,
    pub(super) id: String,
    tags: String,
    pub(super) attributes: Vec<Attr>,
}

/// CARLA's tags of a blueprint id: its parts.
fn tags_of(id: &str) -> String {
    id.split('.').collect::<Vec<_>>().join(",")
}

/// The attributes of a vehicle blueprint (CARLA's, in CARLA's order),
/// `role_name` starting as `role`.
fn vehicle_attributes(v: &catalog::Vehicle, role: &[&str]) -> Vec<Attr> {
    let flag = |b: bool| if b { "true" } else { "false" };
    let mut attributes = Vec::new();
    if !v.colors.is_empty() {
        attributes.push(Attr::choice("color", Kind::RGBColor, v.colors, false));
    }
    if !v.drivers.is_empty() {
        attributes.push(Attr::choice("driver_id", Kind::Int, v.drivers, true));
    }
    attributes.extend([
        Attr::fixed("generation", Kind::Int, v.generation),
        Attr::fixed("number_of_wheels", Kind::Int, v.class.number_of_wheels()),
        Attr::fixed("object_type", Kind::String, ""),
        Attr::fixed("base_type", Kind::String, v.class.base_type()),
        Attr::fixed("special_type", Kind::String, v.special_type),
        Attr::fixed("has_dynamic_doors", Kind::Bool, flag(v.doors)),
        Attr::fixed("has_lights", Kind::Bool, flag(v.lights)),
        Attr::choice("role_name", Kind::String, role, false),
        Attr::choice("sticky_control", Kind::Bool, &["true"], false),
        Attr::choice("terramechanics", Kind::Bool, &["false"], false),
    ]);
    attributes
}

/// simbus's own vehicle, as a catalogue row (a 2 × 1 m car).
const SIMBUS_CAR: catalog::Vehicle = catalog::Vehicle {
    id: "vehicle.simbus.car",
    class: catalog::Class::Car,
    generation: 2,
    extent: [1.0, 0.5, 0.25],
    mass: shared_types::DEFAULT_VEHICLE_MASS,
    special_type: "",
    doors: false,
    lights: false,
    colors: &[],
    drivers: &[],
};

/// CARLA's role names for vehicles (the first is the default).
const VEHICLE_ROLES: &[&str] = &["autopilot", "scenario", "ego_vehicle"];

/// Every blueprint: simbus's props, vehicle and sensors, CARLA's vehicles,
/// walkers and the walker controller.
pub(super) fn definitions() -> &'static [Definition] {
    static ALL: OnceLock<Vec<Definition>> = OnceLock::new();
    ALL.get_or_init(|| {
        let mut all: Vec<Definition> = LIBRARY
            .iter()
            .map(|bp| Definition {
                uid: bp.uid,
                id: bp.id.to_string(),
                tags: bp.tags.to_string(),
                attributes: match bp.id {
                    "vehicle.simbus.car" => vehicle_attributes(&SIMBUS_CAR, &[""]),
                    _ => bp.attributes.iter().map(Attr::of).collect(),
                },
            })
            .collect();
        let vehicle_uid = ActorKind::Vehicle as u32;
        all.extend(catalog::VEHICLES.iter().map(|v| Definition {
            uid: vehicle_uid,
            id: v.id.to_string(),
            tags: tags_of(v.id),
            attributes: vehicle_attributes(v, VEHICLE_ROLES),
        }));
        all.extend((1..=catalog::WALKERS).map(walker_definition));
        all.push(Definition {
            uid: 0,
            id: "controller.ai.walker".to_string(),
            tags: "controller,ai,walker".to_string(),
            attributes: vec![Attr::choice("role_name", Kind::String, &[""], false)],
        });
        // CARLA gives every blueprint its ROS 2 names (native ROS 2,
        // `--ros2`): the topic and frame names, and whether it sends /tf.
        for definition in &mut all {
            definition.attributes.extend([
                Attr::choice("ros_name", Kind::String, &[""], false),
                Attr::choice("ros_frame_id", Kind::String, &[""], false),
                Attr::choice("ros_publish_tf", Kind::Bool, &["true"], false),
            ]);
        }
        all
    })
}

/// Walker `n`'s blueprint.
fn walker_definition(n: u32) -> Definition {
    let w = catalog::walker(n);
    let mut attributes = vec![
        Attr::fixed("age", Kind::String, w.age),
        Attr::fixed("can_use_wheelchair", Kind::Bool, w.wheelchair),
        Attr::fixed("gender", Kind::String, w.gender),
        Attr::fixed("generation", Kind::Int, w.generation),
        Attr::choice("is_invincible", Kind::Bool, &["true"], false),
        Attr::choice("role_name", Kind::String, &["pedestrian"], false),
        Attr::choice("speed", Kind::Float, &w.speeds, false),
    ];
    // CARLA's switch on every walker, "true" recommended only where it
    // can use one (kept: the walker keeps its shape, simbus has no
    // wheelchair).
    let wheelchair: &[&str] = if w.wheelchair {
        &["false", "true"]
    } else {
        &["false"]
    };
    attributes.push(Attr::choice("use_wheelchair", Kind::Bool, wheelchair, true));
    Definition {
        uid: ActorKind::Walker as u32,
        tags: tags_of(&w.id),
        attributes,
        id: w.id,
    }
}

/// The blueprint `id`, if the library has it.
pub(super) fn definition(id: &str) -> Option<&'static Definition> {
    definitions().iter().find(|d| d.id == id)
}

/// The library as CARLA's `[ActorDefinition]`:
/// `[uid, id, tags, [[id, type, value, recommended, modifiable, restricted]]]`.
pub(crate) fn library() -> Value {
    Value::Array(
        definitions()
            .iter()
            .map(|d| {
                let attributes = d
                    .attributes
                    .iter()
                    .map(|a| {
                        Value::Array(vec![
                            Value::from(a.id),
                            Value::from(a.kind as u8),
                            Value::from(a.value.as_str()),
                            Value::Array(
                                a.recommended
                                    .iter()
                                    .map(|r| Value::from(r.as_str()))
                                    .collect(),
                            ),
                            Value::Boolean(a.modifiable),
                            Value::Boolean(a.restricted),
                        ])
                    })
                    .collect();
                Value::Array(vec![
                    Value::from(d.uid),
                    Value::from(d.id.as_str()),
                    Value::from(d.tags.as_str()),
                    Value::Array(attributes),
                ])
            })
            .collect(),
    )
}

/// The description a scene actor of simbus kind `kind` (CARLA type id
/// `type_id`) reports: `role_name` empty and its blueprint's fixed
/// attributes, as CARLA's `[uid, id, [[id, type, value]]]`.
pub(crate) fn scene_description(kind: u32, type_id: &str) -> Value {
    let value = |id: &str, kind: Kind, text: &str| {
        Value::Array(vec![
            Value::from(id),
            Value::from(kind as u8),
            Value::from(text),
        ])
    };
    let mut attributes = vec![value("role_name", Kind::String, "")];
    if let Some(d) = definition(type_id) {
        attributes.extend(
            d.attributes
                .iter()
                .filter(|a| !a.modifiable)
                .map(|a| value(a.id, a.kind, &a.value)),
        );
    }
    Value::Array(vec![
        Value::from(kind),
        Value::from(type_id),
        Value::Array(attributes),
    ])
}

/// The mass (kg) and CARLA extent of the catalogue vehicle `id`, if it
/// is one (simbus's own vehicle is built with all-zero params).
pub(crate) fn vehicle_build(id: &str) -> Option<(f32, [f32; 3])> {
    catalog::vehicle(id).map(|v| (v.mass, v.extent))
}

/// The CARLA extent an actor spawned from `description` will have, known
/// before its first frame (a catalogue vehicle's or walker's; zero for
/// the others).
pub(crate) fn spawned_extent(description: &Value) -> [f32; 3] {
    let id = description
        .as_array()
        .and_then(|fields| fields.get(1)?.as_str());
    id.and_then(vehicle_build)
        .map(|(_, extent)| extent)
        .or_else(|| id.and_then(catalog::walker_of).map(|w| w.extent))
        .unwrap_or([0.0; 3])
}
