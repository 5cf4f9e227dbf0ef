//! The blueprint library the gateway offers (`world.get_blueprint_library()`)
//! and what a CARLA actor description spawns in simbus: a prop, a ray-cast
//! vehicle (simbus's own or one of CARLA's catalogue, [`catalog`]), or a
//! sensor. CARLA's walkers are listed and refused at spawn.

mod cameras;
mod catalog;
mod library;
mod sensors;

pub(crate) use catalog::Class;
use library::definition;
pub(crate) use library::{library, scene_description, spawned_extent, vehicle_build};

/// The class (car, truck, bus, ...) of catalog vehicle `id`, if it is one.
pub(crate) fn vehicle_class(id: &str) -> Option<Class> {
    catalog::vehicle(id).map(|v| v.class)
}

use std::collections::HashMap;

use rmpv::Value;
use shared_types::{Command, SensorKind, SensorSpec};

use crate::convert;
use crate::error::BlueprintError;
use crate::wire::{CarlaTransform, DEPTH_FAR_METRES};

/// CARLA's `ActorAttributeType`.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
enum Kind {
    Bool = 1,
    Int = 2,
    Float = 3,
    String = 4,
    RGBColor = 5,
}

/// One attribute of a blueprint: name, type, default, whether a script
/// may change it.
struct Attribute {
    id: &'static str,
    kind: Kind,
    default: &'static str,
    modifiable: bool,
}

const fn float(id: &'static str, default: &'static str) -> Attribute {
    Attribute {
        id,
        kind: Kind::Float,
        default,
        modifiable: true,
    }
}

const fn int(id: &'static str, default: &'static str) -> Attribute {
    Attribute {
        id,
        kind: Kind::Int,
        default,
        modifiable: true,
    }
}

const ROLE_NAME: Attribute = Attribute {
    id: "role_name",
    kind: Kind::String,
    default: "",
    modifiable: true,
};

/// One blueprint. Body blueprints' uids are simbus's `ActorKind` numbers.
struct Blueprint {
    uid: u32,
    id: &'static str,
    tags: &'static str,
    attributes: &'static [Attribute],
}

/// The blueprints. Sizes are half extents and radii in metres; sensor
/// attributes keep CARLA's names, units and defaults. The lidar's noise
/// and drop-off and the GNSS receiver's noise are CARLA's; the IMU's noise
/// attributes exist (scripts set them to 0) but simbus's IMU is exact:
/// other values are refused at spawn.
const LIBRARY: &[Blueprint] = &[
    Blueprint {
        uid: 2,
        id: "static.prop.box",
        tags: "static,prop",
        attributes: &[
            ROLE_NAME,
            float("extent_x", "0.5"),
            float("extent_y", "0.5"),
            float("extent_z", "0.5"),
        ],
    },
    Blueprint {
        uid: 3,
        id: "static.prop.sphere",
        tags: "static,prop",
        attributes: &[ROLE_NAME, float("radius", "0.5")],
    },
    Blueprint {
        uid: 4,
        id: "static.prop.capsule",
        tags: "static,prop",
        attributes: &[
            ROLE_NAME,
            float("radius", "0.3"),
            float("half_height", "0.5"),
        ],
    },
    Blueprint {
        uid: 5,
        id: "vehicle.simbus.car",
        tags: "vehicle,car,simbus",
        // Its attributes are a catalogue vehicle's ([`vehicle_attributes`]).
        attributes: &[ROLE_NAME],
    },
    Blueprint {
        uid: 6,
        id: "sensor.camera.depth",
        tags: "sensor,camera,depth",
        attributes: cameras::SEGMENTATION,
    },
    Blueprint {
        uid: 11,
        id: "sensor.camera.rgb",
        tags: "sensor,camera,rgb",
        attributes: cameras::RGB,
    },
    Blueprint {
        uid: 12,
        id: "sensor.camera.semantic_segmentation",
        tags: "sensor,camera,semantic_segmentation",
        attributes: cameras::SEGMENTATION,
    },
    Blueprint {
        uid: 13,
        id: "sensor.camera.instance_segmentation",
        tags: "sensor,camera,instance_segmentation",
        attributes: cameras::SEGMENTATION,
    },
    Blueprint {
        uid: 18,
        id: "sensor.camera.normals",
        tags: "sensor,camera,normals",
        attributes: cameras::SEGMENTATION,
    },
    Blueprint {
        uid: 19,
        id: "sensor.camera.optical_flow",
        tags: "sensor,camera,optical_flow",
        attributes: cameras::SEGMENTATION,
    },
    Blueprint {
        uid: 20,
        id: "sensor.camera.dvs",
        tags: "sensor,camera,dvs",
        attributes: cameras::DVS,
    },
    Blueprint {
        uid: 21,
        id: "sensor.camera.cosmos_visualization",
        tags: "sensor,camera,cosmos_visualization",
        attributes: cameras::SEGMENTATION,
    },
    Blueprint {
        uid: 7,
        id: "sensor.lidar.ray_cast",
        tags: "sensor,lidar,ray_cast",
        attributes: sensors::LIDAR,
    },
    Blueprint {
        uid: 16,
        id: "sensor.lidar.ray_cast_semantic",
        tags: "sensor,lidar,ray_cast_semantic",
        attributes: sensors::SEMANTIC_LIDAR,
    },
    Blueprint {
        uid: 17,
        id: "sensor.other.radar",
        tags: "sensor,other,radar",
        attributes: sensors::RADAR,
    },
    Blueprint {
        uid: 10,
        id: "sensor.other.gnss",
        tags: "sensor,other,gnss",
        attributes: &[
            ROLE_NAME,
            float("sensor_tick", "0.0"),
            float("noise_alt_bias", "0.0"),
            float("noise_alt_stddev", "0.0"),
            float("noise_lat_bias", "0.0"),
            float("noise_lat_stddev", "0.0"),
            float("noise_lon_bias", "0.0"),
            float("noise_lon_stddev", "0.0"),
            int("noise_seed", "0"),
        ],
    },
    Blueprint {
        uid: 14,
        id: "sensor.other.collision",
        tags: "sensor,other,collision",
        attributes: &[ROLE_NAME],
    },
    Blueprint {
        uid: 15,
        id: "sensor.other.obstacle",
        tags: "sensor,other,obstacle",
        attributes: sensors::OBSTACLE,
    },
    Blueprint {
        uid: 9,
        id: "sensor.other.lane_invasion",
        tags: "sensor,other,lane_invasion",
        attributes: &[ROLE_NAME],
    },
    Blueprint {
        uid: 8,
        id: "sensor.other.imu",
        tags: "sensor,other,imu",
        attributes: &[
            ROLE_NAME,
            float("sensor_tick", "0.0"),
            float("noise_accel_stddev_x", "0.0"),
            float("noise_accel_stddev_y", "0.0"),
            float("noise_accel_stddev_z", "0.0"),
            float("noise_gyro_stddev_x", "0.0"),
            float("noise_gyro_stddev_y", "0.0"),
            float("noise_gyro_stddev_z", "0.0"),
            float("noise_gyro_bias_x", "0.0"),
            float("noise_gyro_bias_y", "0.0"),
            float("noise_gyro_bias_z", "0.0"),
            int("noise_seed", "0"),
        ],
    },
];

/// The simbus actor kind a body blueprint's uid spawns (their uids are
/// simbus's `ActorKind` numbers).
pub(crate) fn kind_of_uid(uid: u64) -> u32 {
    u32::try_from(uid).unwrap_or(0)
}

/// What a description spawns.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) enum Spawn {
    /// A prop or the vehicle: one simbus command.
    Body(Command),
    /// A sensor, and the CARLA type id it reports.
    Sensor(SensorSpec),
    /// A sensor CARLA's client computes itself (the lane-invasion sensor:
    /// crossings of the map's lane marks by its parent's bounding box): a
    /// pose-only actor at this pose, no simbus sensor.
    ClientSide([f32; 3], [f32; 4]),
    /// `controller.ai.walker`: CARLA's client walks its walker itself
    /// (on the navigation mesh the gateway serves) and sends where it is
    /// every tick; the controller is an actor attached to the walker.
    Controller,
}

/// A parsed CARLA `ActorDescription` `[uid, id, [[id, type, value]]]`:
/// the blueprint id and every attribute's value (defaults filled in).
#[derive(Debug, Clone)]
pub(crate) struct Description {
    pub(crate) id: String,
    values: HashMap<String, String>,
}

impl Description {
    /// Reads a description; refuses blueprints simbus does not have.
    pub(crate) fn parse(value: &Value) -> Result<Self, BlueprintError> {
        let fields = value.as_array().ok_or(BlueprintError::NotArray)?;
        let id = fields
            .get(1)
            .and_then(Value::as_str)
            .ok_or(BlueprintError::NoId)?;
        let blueprint = definition(id).ok_or_else(|| BlueprintError::Unknown {
            id: id.to_string(),
            known: LIBRARY
                .iter()
                .map(|bp| bp.id)
                .chain(["CARLA's vehicle.*, walker.pedestrian.* and controller.ai.walker"])
                .collect::<Vec<_>>()
                .join(", "),
        })?;
        let mut values: HashMap<String, String> = blueprint
            .attributes
            .iter()
            .map(|a| (a.id.to_string(), a.value.clone()))
            .collect();
        for attribute in fields
            .get(2)
            .and_then(Value::as_array)
            .into_iter()
            .flatten()
        {
            let pair = attribute.as_array().and_then(|a| {
                Some((
                    a.first()?.as_str()?.to_string(),
                    a.get(2)?.as_str()?.to_string(),
                ))
            });
            if let Some((name, text)) = pair {
                values.insert(name, text);
            }
        }
        Ok(Self {
            id: id.to_string(),
            values,
        })
    }

    /// The value of attribute `name` (the script's, or the default).
    pub(crate) fn value(&self, name: &str) -> Option<&str> {
        self.values.get(name).map(String::as_str)
    }

    /// The description as an actor's record carries it: the blueprint's
    /// uid (a body's uid is its simbus kind), its id, and every attribute
    /// of the blueprint with the value the script set (or the default).
    pub(crate) fn record(&self) -> Value {
        let Some(d) = definition(&self.id) else {
            return Value::Array(vec![Value::from(0u8), Value::from(self.id.as_str())]);
        };
        let attributes = d
            .attributes
            .iter()
            .map(|a| {
                let value = self.values.get(a.id).unwrap_or(&a.value);
                Value::Array(vec![
                    Value::from(a.id),
                    Value::from(a.kind as u8),
                    Value::from(value.as_str()),
                ])
            })
            .collect();
        Value::Array(vec![
            Value::from(d.uid),
            Value::from(self.id.as_str()),
            Value::Array(attributes),
        ])
    }

    fn number(&self, name: &str) -> Result<f32, BlueprintError> {
        let text = self.values.get(name).map_or("", String::as_str);
        text.trim()
            .parse::<f32>()
            .ok()
            .filter(|v| v.is_finite())
            .ok_or_else(|| BlueprintError::NotANumber {
                blueprint: self.id.clone(),
                name: name.to_string(),
                text: text.to_string(),
            })
    }

    /// Refuses a non-zero value for an attribute simbus does not model.
    fn zero(&self, names: &[&str]) -> Result<(), BlueprintError> {
        for name in names {
            if self.values.contains_key(*name) && self.number(name)? != 0.0 {
                return Err(BlueprintError::NotZero {
                    blueprint: self.id.clone(),
                    name: name.to_string(),
                });
            }
        }
        Ok(())
    }

    /// What spawning this at `transform` (relative to the parent, if any)
    /// makes. Positions and sizes go through simbus's own checks at spawn.
    pub(crate) fn spawn(&self, transform: &CarlaTransform) -> Result<Spawn, BlueprintError> {
        let (position, rotation) = convert::pose(transform);
        let body = |command: Command| {
            Ok(Spawn::Body(Command {
                rotation,
                ..command
            }))
        };
        match self.id.as_str() {
            "static.prop.box" => {
                // CARLA's extent (x forward, y right, z up) in simbus's axes.
                let half = convert::vector([
                    self.number("extent_x")?,
                    self.number("extent_y")?,
                    self.number("extent_z")?,
                ]);
                body(Command::spawn_box(position, half))
            }
            "static.prop.sphere" => body(Command::spawn_sphere(position, self.number("radius")?)),
            "static.prop.capsule" => body(Command::spawn_capsule(
                position,
                self.number("radius")?,
                self.number("half_height")?,
            )),
            "vehicle.simbus.car" => body(Command::spawn_vehicle(position)),
            "controller.ai.walker" => Ok(Spawn::Controller),
            id if catalog::walker_of(id).is_some() => {
                let extent = catalog::walker_of(id).map_or([0.19, 0.19, 0.94], |w| w.extent);
                // CARLA's location is the capsule's centre; a walker whose
                // feet would be in the ground is stood on it by simbus.
                body(Command::spawn_walker(position, extent[0], extent[2]))
            }
            id if catalog::vehicle(id).is_some() => {
                let (mass, extent) = vehicle_build(id).unwrap_or_default();
                let half = convert::vector(extent);
                // CARLA's vehicle stands on the ground below its location:
                // simbus places the chassis's centre, so lift it by its
                // half height.
                let at = [position[0], position[1] + half[1], position[2]];
                body(Command::spawn_sized_vehicle(at, half, mass))
            }
            "sensor.camera.depth" => self.camera(SensorKind::Depth, position, rotation),
            "sensor.camera.rgb" => self.camera(SensorKind::Rgb, position, rotation),
            "sensor.camera.semantic_segmentation" => {
                self.camera(SensorKind::Semantic, position, rotation)
            }
            "sensor.camera.instance_segmentation" => {
                self.camera(SensorKind::Instance, position, rotation)
            }
            // Computed by the gateway from a simbus camera (`derived.rs`).
            id if crate::derived::Derived::source(id).is_some() => {
                let kind = crate::derived::Derived::source(id).unwrap_or(SensorKind::Depth);
                self.camera(kind, position, rotation)
            }
            "sensor.lidar.ray_cast" => self.lidar(SensorKind::Lidar, position, rotation),
            "sensor.lidar.ray_cast_semantic" => {
                self.lidar(SensorKind::SemanticLidar, position, rotation)
            }
            "sensor.other.radar" => self.radar(position, rotation),
            "sensor.other.lane_invasion" => Ok(Spawn::ClientSide(position, rotation)),
            "sensor.other.gnss" => self.gnss(position, rotation),
            "sensor.other.collision" => {
                let spec = SensorSpec::with_params(position, shared_types::Collision);
                Ok(Spawn::Sensor(SensorSpec { rotation, ..spec }))
            }
            "sensor.other.obstacle" => self.obstacle(position, rotation),
            _ => {
                self.zero(&[
                    "noise_accel_stddev_x",
                    "noise_accel_stddev_y",
                    "noise_accel_stddev_z",
                    "noise_gyro_stddev_x",
                    "noise_gyro_stddev_y",
                    "noise_gyro_stddev_z",
                    "noise_gyro_bias_x",
                    "noise_gyro_bias_y",
                    "noise_gyro_bias_z",
                ])?;
                self.sensor(SensorSpec::imu(position), rotation)
            }
        }
    }

    /// A camera of `kind`: CARLA's size and field of view, seeing as far
    /// as CARLA's depth camera reads.
    fn camera(
        &self,
        kind: SensorKind,
        position: [f32; 3],
        rotation: [f32; 4],
    ) -> Result<Spawn, BlueprintError> {
        let size = (self.number("image_size_x")?, self.number("image_size_y")?);
        // A size that is not a whole number reads as zero pixels: refused.
        let whole = |v: f32| if v.fract() == 0.0 { v as u32 } else { 0 };
        let spec = SensorSpec::camera_of(
            kind,
            position,
            (whole(size.0), whole(size.1)),
            self.number("fov")?,
            DEPTH_FAR_METRES,
        )
        .expect("a camera kind");
        self.sensor(spec, rotation)
    }

    fn sensor(&self, spec: SensorSpec, rotation: [f32; 4]) -> Result<Spawn, BlueprintError> {
        let tick = self.number("sensor_tick")?;
        let spec = SensorSpec { rotation, ..spec }.every(f64::from(tick));
        spec.check().map_err(|source| BlueprintError::Sensor {
            blueprint: self.id.clone(),
            source,
        })?;
        Ok(Spawn::Sensor(spec))
    }
}

#[cfg(test)]
mod tests;
