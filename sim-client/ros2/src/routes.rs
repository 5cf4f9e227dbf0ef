//! What the adapter publishes and under which names: simbus's own scheme
//! (`sim-client ros2`: `<namespace>/sensor_<id>/image`, frames named from
//! the actor's kind and id) or CARLA's (the gateway: `/carla/<parent's
//! ros_name>/<ros_name>/image`, only the sensors a script enabled).

use std::collections::{BTreeMap, BTreeSet};

use shared_types::{ActorKind, ActorState, SensorKind};

/// How topics and frames are named.
#[derive(Debug, Clone, PartialEq, Eq)]
pub enum Naming {
    /// simbus's: topics under a namespace (`/simbus`), frames
    /// `<kind>_<id>` (`vehicle_15`) and `sensor_<id>`, or the name given.
    Simbus {
        /// The namespace, absolute, without a trailing `/` (`""`: the root).
        namespace: String,
    },
    /// CARLA 0.9.16's native ROS 2: `/carla/<parent>/<sensor>/…`, frames
    /// named by `ros_name` (else `role_name`, else the id).
    Carla,
}

/// Which sensors and vehicles take part, and the names scripts gave them.
/// The gateway changes it while the adapter runs (`enable_for_ros`).
#[derive(Debug, Clone, PartialEq, Eq, Default)]
pub struct Selection {
    /// Sensors published: `None`, every sensor of the world.
    pub sensors: Option<BTreeSet<u64>>,
    /// Vehicles driven from ROS: `None`, every vehicle.
    pub vehicles: Option<BTreeSet<u64>>,
    /// Names given to actors (by actor id) and sensors (by sensor id, in
    /// `sensor_names`): frame ids and topic segments.
    pub actor_names: BTreeMap<u64, String>,
    /// Names given to sensors, by sensor id.
    pub sensor_names: BTreeMap<u64, String>,
}

impl Naming {
    /// The frame of actor `actor`: its given name, else `<kind>_<id>`
    /// (`None` for the static ground and props, which never move).
    pub fn actor_frame(&self, actor: &ActorState, selection: &Selection) -> Option<String> {
        if let Some(name) = selection.actor_names.get(&actor.id) {
            return Some(name.clone());
        }
        match actor.actor_kind()? {
            ActorKind::Static => None,
            kind => Some(format!("{}_{}", kind.name(), actor.id)),
        }
    }

    /// The frame of an actor known only by id (a sensor's parent).
    pub fn parent_frame(&self, id: u64, actors: &[ActorState], selection: &Selection) -> String {
        if let Some(name) = selection.actor_names.get(&id) {
            return name.clone();
        }
        actors
            .iter()
            .find(|a| a.id == id)
            .and_then(|a| self.actor_frame(a, selection))
            .unwrap_or_else(|| format!("actor_{id}"))
    }

    /// The frame of sensor `id`.
    pub fn sensor_frame(&self, id: u64, selection: &Selection) -> String {
        selection
            .sensor_names
            .get(&id)
            .cloned()
            .unwrap_or_else(|| format!("sensor_{id}"))
    }

    /// The topics' prefix for sensor `id` mounted on `parent` (its frame,
    /// if any): `/simbus/sensor_3` or `/carla/hero/rgb`.
    pub fn sensor_topic(&self, id: u64, parent: Option<&str>, selection: &Selection) -> String {
        let frame = self.sensor_frame(id, selection);
        match self {
            Self::Simbus { namespace } => format!("{namespace}/{frame}"),
            Self::Carla => match parent {
                Some(parent) => format!("/carla/{parent}/{frame}"),
                None => format!("/carla/{frame}"),
            },
        }
    }

    /// The topics' prefix for vehicle `frame` (its odometry, its control).
    pub fn vehicle_topic(&self, frame: &str) -> String {
        match self {
            Self::Simbus { namespace } => format!("{namespace}/{frame}"),
            Self::Carla => format!("/carla/{frame}"),
        }
    }

    /// The topic of a sensor's data under its prefix `base`, and its
    /// camera model's for a camera: simbus's `image`, `point_cloud`,
    /// `imu`, `gnss`, `collision`; CARLA's `image` and `point_cloud`, the
    /// others on the prefix itself.
    pub fn data_topics(&self, base: &str, kind: SensorKind) -> (String, Option<String>) {
        let leaf = match kind {
            SensorKind::Rgb | SensorKind::Depth | SensorKind::Semantic | SensorKind::Instance => {
                return (format!("{base}/image"), Some(format!("{base}/camera_info")));
            }
            SensorKind::Lidar | SensorKind::SemanticLidar | SensorKind::Radar => "point_cloud",
            SensorKind::Imu => "imu",
            SensorKind::Gnss => "gnss",
            SensorKind::Collision => "collision",
            SensorKind::Obstacle => "obstacle",
        };
        match self {
            Self::Simbus { .. } => (format!("{base}/{leaf}"), None),
            Self::Carla if leaf == "point_cloud" => (format!("{base}/{leaf}"), None),
            Self::Carla => (base.to_owned(), None),
        }
    }

    /// The frame a camera's images are in: simbus's optical frame
    /// (`<frame>_optical`, REP 103), CARLA's the sensor's own.
    pub fn image_frame(&self, frame: &str) -> String {
        match self {
            Self::Simbus { .. } => format!("{frame}_optical"),
            Self::Carla => frame.to_owned(),
        }
    }

    /// The control topics of a vehicle under `base`: simbus's array (if
    /// any), CARLA's message, the Ackermann target.
    pub fn control_topics(&self, base: &str) -> (Option<String>, String, String) {
        match self {
            Self::Simbus { .. } => (
                Some(format!("{base}/control")),
                format!("{base}/vehicle_control_cmd"),
                format!("{base}/ackermann_cmd"),
            ),
            Self::Carla => (
                None,
                format!("{base}/vehicle_control_cmd"),
                format!("{base}/ackermann_control_cmd"),
            ),
        }
    }

    /// A topic of the whole world (`markers`, `tick`).
    pub fn world_topic(&self, leaf: &str) -> String {
        match self {
            Self::Simbus { namespace } => format!("{namespace}/{leaf}"),
            Self::Carla => format!("/carla/{leaf}"),
        }
    }
}

/// A namespace ROS cannot have.
#[derive(Debug, Clone, PartialEq, Eq, thiserror::Error)]
#[error("{given:?} is not a ROS namespace: each part is letters, digits and _, starting with a letter or _")]
pub struct NamespaceError {
    /// What was given.
    pub given: String,
}

/// A namespace as given on the command line (`simbus`, `/simbus/`, `/`)
/// in the form topics are built from (`/simbus`, `""`), or why not: ROS
/// names are letters, digits and `_`, each part starting with a letter or
/// `_`.
///
/// # Errors
///
/// Why `given` is not a namespace.
pub fn namespace(given: &str) -> Result<String, NamespaceError> {
    let trimmed = given.trim_matches('/');
    if trimmed.is_empty() {
        return Ok(String::new());
    }
    for part in trimmed.split('/') {
        let mut chars = part.chars();
        let starts_well = chars
            .next()
            .is_some_and(|c| c.is_ascii_alphabetic() || c == '_');
        if !starts_well || !part.chars().all(|c| c.is_ascii_alphanumeric() || c == '_') {
            return Err(NamespaceError {
                given: given.to_owned(),
            });
        }
    }
    Ok(format!("/{trimmed}"))
}

/// Whether `name` can be a ROS name segment (a `ros_name`, a role).
pub fn is_segment(name: &str) -> bool {
    namespace(name).is_ok_and(|n| !n.is_empty() && !name.contains('/'))
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn namespaces_are_absolute_without_a_trailing_slash() {
        assert_eq!(namespace("simbus").unwrap(), "/simbus");
        assert_eq!(namespace("/a/b/").unwrap(), "/a/b");
        assert_eq!(namespace("/").unwrap(), "");
        assert!(namespace("9lives").is_err());
        assert!(namespace("a b").is_err());
    }

    #[test]
    fn carla_names_sensors_under_their_parent() {
        let mut selection = Selection::default();
        selection.sensor_names.insert(3, "rgb".into());
        assert_eq!(
            Naming::Carla.sensor_topic(3, Some("hero"), &selection),
            "/carla/hero/rgb"
        );
        let simbus = Naming::Simbus {
            namespace: "/simbus".into(),
        };
        assert_eq!(
            simbus.sensor_topic(4, Some("hero"), &selection),
            "/simbus/sensor_4"
        );
    }
}
