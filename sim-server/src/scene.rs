//! Scenes: the initial contents of a world.
//!
//! - `default`: ground, a ramp with a sphere rolling down it into a stack of
//!   boxes, boxes and a capsule falling and tumbling, two vehicles —
//!   something visibly moves for several seconds.
//! - `empty`: nothing at all (measures the bus, not the physics).
//! - `town`: a flat ground under `town`'s road network (a grid with
//!   junctions and a loop, `shared_types::roads`), buildings in the blocks
//!   between the roads.
//! - `flat`: a flat ground and nothing on it (CARLA's
//!   `generate_opendrive_world` builds its world on it).
//! - `boxes:N`: ground and N boxes dropped in a grid (physics load).

use std::fmt;
use std::str::FromStr;

use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use rapier3d::prelude::*;
use shared_types::ActorKind;

use shared_types::roads::{FLAT_GROUND_HALF_SIZE, TOWN_GROUND_HALF_SIZE};
use shared_types::scene::SceneName;
pub use shared_types::scene::MAX_SCENE_BOXES;

/// Why a scene name was refused (the grammar is shared with clients).
pub use shared_types::scene::SceneNameError as SceneError;

/// A scene a world can be loaded from.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Scene {
    /// The demo scene.
    Default,
    /// No actors.
    Empty,
    /// A ground under a town's roads.
    Town,
    /// A flat ground, nothing on it.
    Flat,
    /// Ground plus this many boxes.
    Boxes(u32),
}

impl From<SceneName> for Scene {
    fn from(name: SceneName) -> Self {
        match name {
            SceneName::Default => Self::Default,
            SceneName::Empty => Self::Empty,
            SceneName::Town => Self::Town,
            SceneName::Flat => Self::Flat,
            SceneName::Boxes(n) => Self::Boxes(n),
        }
    }
}

impl Scene {
    /// Its name (which also names its road network).
    pub fn name(&self) -> SceneName {
        match *self {
            Self::Default => SceneName::Default,
            Self::Empty => SceneName::Empty,
            Self::Town => SceneName::Town,
            Self::Flat => SceneName::Flat,
            Self::Boxes(n) => SceneName::Boxes(n),
        }
    }
}

impl FromStr for Scene {
    type Err = SceneError;

    fn from_str(s: &str) -> Result<Self, Self::Err> {
        s.parse::<SceneName>().map(Self::from)
    }
}

impl fmt::Display for Scene {
    fn fmt(&self, f: &mut fmt::Formatter<'_>) -> fmt::Result {
        match self {
            Self::Default => f.write_str("default"),
            Self::Empty => f.write_str("empty"),
            Self::Town => f.write_str("town"),
            Self::Flat => f.write_str("flat"),
            Self::Boxes(n) => write!(f, "boxes:{n}"),
        }
    }
}

/// One body a scene places, before it is given an actor id.
#[derive(Debug, Clone)]
pub struct Placement {
    /// What the actor is.
    pub kind: ActorKind,
    /// Half extents (box), radius (sphere), or (radius, half height, radius) (capsule).
    pub extent: Vector,
    /// Where the body starts.
    pub position: Vector,
    /// Initial orientation, as a scaled rotation axis (radians).
    pub rotation: Vector,
    /// Initial linear velocity.
    pub linear_velocity: Vector,
    /// Density, kg/m³ (ignored for static bodies).
    pub density: f32,
    /// A traffic light's junction and pole, or what a sign says.
    pub signal: Option<PlacedSignal>,
}

/// What a traffic light or sign placement is beyond its body.
#[derive(Debug, Clone, Copy, PartialEq)]
pub enum PlacedSignal {
    /// A light: its junction's group and its place in it.
    Light {
        /// The junction's id.
        junction: u32,
        /// Its pole index.
        pole: u32,
    },
    /// A sign and what it says.
    Sign(shared_types::SignReading),
}

impl Placement {
    fn new(kind: ActorKind, extent: Vector, position: Vector) -> Self {
        Self {
            kind,
            extent,
            position,
            rotation: Vector::ZERO,
            linear_velocity: Vector::ZERO,
            density: 1.0,
            signal: None,
        }
    }

    fn rotated(mut self, rotation: Vector) -> Self {
        self.rotation = rotation;
        self
    }

    fn density(mut self, density: f32) -> Self {
        self.density = density;
        self
    }

    /// Where this placement's body would be and its shape shrunk by
    /// `skin` on every side: what a spawn tests against the bodies already
    /// there, so a body placed resting on another (touching it) is not
    /// taken for one inside it.
    pub(crate) fn probe(&self, skin: f32) -> (Pose, SharedShape) {
        let e = self.extent;
        // Never below half the size, however thin the body.
        let shrunk = |v: f32| (v - skin).max(v * 0.5);
        let shape = match self.kind {
            ActorKind::Static
            | ActorKind::Box
            | ActorKind::Vehicle
            | ActorKind::TrafficLight
            | ActorKind::TrafficSign => SharedShape::cuboid(shrunk(e.x), shrunk(e.y), shrunk(e.z)),
            ActorKind::Sphere => SharedShape::ball(shrunk(e.x)),
            ActorKind::Capsule => SharedShape::capsule_y(shrunk(e.y), shrunk(e.x)),
            ActorKind::Walker => {
                let radius = shrunk(e.x);
                SharedShape::capsule_y((shrunk(e.y) - radius).max(0.0), radius)
            }
        };
        let pose = Pose::from_parts(self.position, Rotation::from_scaled_axis(self.rotation));
        (pose, shape)
    }

    /// The rapier body and collider of this placement.
    pub fn build(&self) -> (RigidBody, Collider) {
        let body = match self.kind {
            ActorKind::Static | ActorKind::TrafficLight | ActorKind::TrafficSign => {
                RigidBodyBuilder::fixed()
            }
            ActorKind::Walker => RigidBodyBuilder::kinematic_position_based(),
            _ => RigidBodyBuilder::dynamic(),
        }
        .translation(self.position)
        .rotation(self.rotation)
        .linvel(self.linear_velocity)
        .build();
        let e = self.extent;
        let collider = match self.kind {
            ActorKind::Static
            | ActorKind::Box
            | ActorKind::Vehicle
            | ActorKind::TrafficLight
            | ActorKind::TrafficSign => ColliderBuilder::cuboid(e.x, e.y, e.z),
            ActorKind::Sphere => ColliderBuilder::ball(e.x),
            ActorKind::Capsule => ColliderBuilder::capsule_y(e.y, e.x),
            ActorKind::Walker => {
                ColliderBuilder::new(SharedShape::new(crate::walkers::walker_shape(e.x, e.y)))
            }
        }
        .density(self.density)
        .friction(0.6)
        .restitution(0.1)
        // Contact starts are reported (to the recorder); this changes no dynamics.
        .active_events(ActiveEvents::COLLISION_EVENTS)
        .build();
        (body, collider)
    }
}

fn ground(half_size: f32) -> Placement {
    Placement::new(
        ActorKind::Static,
        Vector::new(half_size, 0.5, half_size),
        Vector::new(0.0, -0.5, 0.0),
    )
}

impl Scene {
    /// The bodies of this scene, in actor-id order. A non-zero `seed` moves
    /// every dynamic body by up to 0.2 m and turns it by up to 0.2 rad,
    /// the same way for the same seed.
    pub fn placements(&self, seed: u64) -> Vec<Placement> {
        let mut placements = match *self {
            Self::Empty => Vec::new(),
            Self::Default => default_scene(),
            Self::Town => town_scene(),
            Self::Flat => vec![ground(FLAT_GROUND_HALF_SIZE)],
            Self::Boxes(n) => boxes_scene(n),
        };
        if seed != 0 {
            let mut rng = ChaCha8Rng::seed_from_u64(seed);
            let mut jitter = |scale: f32| rng.random_range(-scale..=scale);
            for p in placements
                .iter_mut()
                .filter(|p| p.kind != ActorKind::Static)
            {
                p.position += Vector::new(jitter(0.2), 0.0, jitter(0.2));
                p.rotation += Vector::new(0.0, jitter(0.2), 0.0);
            }
        }
        placements
    }
}

fn default_scene() -> Vec<Placement> {
    let half = Vector::splat(0.5);
    let mut scene = vec![
        ground(50.0),
        // A ramp falling towards +x: high end near x = -10, low end near x = -2.
        Placement::new(
            ActorKind::Static,
            Vector::new(4.0, 0.2, 1.5),
            Vector::new(-6.0, 1.9, 0.0),
        )
        .rotated(Vector::new(0.0, 0.0, -0.45)),
        // A heavy sphere that lands on the top of the ramp and rolls down it.
        Placement::new(
            ActorKind::Sphere,
            Vector::splat(0.5),
            Vector::new(-9.2, 4.8, 0.0),
        )
        .density(4.0),
    ];
    // A stack of boxes in the sphere's path.
    scene.extend(
        (0..5).map(|i| Placement::new(ActorKind::Box, half, Vector::new(5.0, 0.5 + i as f32, 0.0))),
    );
    // Boxes dropped from height, tumbling onto each other.
    scene.extend((0..6).map(|i| {
        let i = i as f32;
        Placement::new(
            ActorKind::Box,
            Vector::new(0.4, 0.3, 0.5),
            Vector::new(9.0 + 0.3 * i, 3.0 + 1.5 * i, -3.0 + 0.2 * i),
        )
        .rotated(Vector::new(0.3 * i, 0.2, 0.5))
    }));
    // Two vehicles on open ground, facing +x (the autopilot drives them).
    scene.extend([-8.0, 8.0].map(|z| {
        Placement::new(
            ActorKind::Vehicle,
            Vector::new(1.0, 0.25, 0.5),
            Vector::new(-4.0, 1.0, z),
        )
        .density(100.0)
    }));
    // A capsule falling end over end.
    scene.push(
        Placement::new(
            ActorKind::Capsule,
            Vector::new(0.3, 0.6, 0.3),
            Vector::new(2.0, 6.0, 3.0),
        )
        .rotated(Vector::new(0.9, 0.0, 0.4)),
    );
    scene
}

/// `town`: its ground, a building in the middle of each block between
/// the roads (the grid lines run at ±40 m and ±120 m), and its road
/// network's traffic lights and signs.
fn town_scene() -> Vec<Placement> {
    let mut scene = vec![ground(TOWN_GROUND_HALF_SIZE)];
    let blocks = [-80.0, 0.0, 80.0];
    for x in blocks {
        scene.extend(blocks.map(|z| {
            Placement::new(
                ActorKind::Static,
                Vector::new(12.0, 4.0, 12.0),
                Vector::new(x, 4.0, z),
            )
        }));
    }
    scene.extend(signal_placements(&shared_types::roads::network(
        SceneName::Town,
    )));
    scene
}

/// A fixed box for every signal of `network`: a light's head or a sign's
/// plate, turned to face the traffic it speaks to.
fn signal_placements(network: &shared_types::roads::RoadNetwork) -> Vec<Placement> {
    use shared_types::roads::SignalKind;
    use shared_types::{SignKind, SignReading};
    network
        .signals
        .iter()
        .map(|signal| {
            let (kind, placed) = match signal.kind {
                SignalKind::TrafficLight => (
                    ActorKind::TrafficLight,
                    PlacedSignal::Light {
                        junction: signal.junction.unwrap_or(0),
                        pole: signal.pole,
                    },
                ),
                SignalKind::Stop => (
                    ActorKind::TrafficSign,
                    PlacedSignal::Sign(SignReading {
                        kind: SignKind::Stop,
                        value: 0,
                    }),
                ),
                SignalKind::SpeedLimit(kmh) => (
                    ActorKind::TrafficSign,
                    PlacedSignal::Sign(SignReading {
                        kind: SignKind::SpeedLimit,
                        value: kmh,
                    }),
                ),
            };
            let [along, up, across] = signal.half_extents().map(|v| v as f32);
            // OpenDRIVE's (x, y) is simbus's (x, -z); its heading a turn
            // about +Y.
            let p = signal.pose;
            let mut placement = Placement::new(
                kind,
                Vector::new(along, up, across),
                Vector::new(p.x as f32, signal.height() as f32, -p.y as f32),
            )
            .rotated(Vector::new(0.0, p.hdg as f32, 0.0));
            placement.signal = Some(placed);
            placement
        })
        .collect()
}

fn boxes_scene(n: u32) -> Vec<Placement> {
    // A cube of boxes: columns that land on each other and topple.
    let per_row = (f64::from(n).cbrt().ceil() as u32).clamp(1, 40);
    let per_layer = per_row * per_row;
    let spacing = 0.7;
    let offset = (per_row as f32 - 1.0) * spacing / 2.0;
    let mut scene = vec![ground(20.0 + per_row as f32)];
    scene.extend((0..n).map(|i| {
        let layer = i / per_layer;
        let row = (i % per_layer) / per_row;
        let col = i % per_row;
        Placement::new(
            ActorKind::Box,
            Vector::splat(0.25),
            Vector::new(
                col as f32 * spacing - offset,
                1.0 + layer as f32 * spacing,
                row as f32 * spacing - offset,
            ),
        )
        .rotated(Vector::new(0.0, 0.1 * (i % 7) as f32, 0.0))
    }));
    scene
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn seeds_move_dynamic_bodies_reproducibly() {
        let positions = |seed| {
            Scene::Default
                .placements(seed)
                .iter()
                .map(|p| p.position.to_array())
                .collect::<Vec<_>>()
        };
        assert_eq!(positions(7), positions(7));
        assert_ne!(positions(7), positions(8));
        assert_ne!(positions(7), positions(0));
        // Static geometry never moves.
        assert_eq!(positions(7)[..2], positions(0)[..2]);
    }

    #[test]
    fn scene_names_parse_and_print_back() {
        for name in ["default", "empty", "town", "flat", "boxes:1", "boxes:1000"] {
            assert_eq!(name.parse::<Scene>().unwrap().to_string(), name);
        }
    }

    #[test]
    fn bad_scene_names_are_refused_with_the_reason() {
        assert!(matches!(
            "town10".parse::<Scene>(),
            Err(SceneError::Unknown(_))
        ));
        for bad in ["boxes:", "boxes:0", "boxes:-3", "boxes:x", "boxes:100001"] {
            assert!(
                matches!(bad.parse::<Scene>(), Err(SceneError::BoxCount(_))),
                "{bad}"
            );
        }
    }

    #[test]
    fn every_scene_s_roads_lie_on_its_ground_and_clear_of_its_bodies() {
        for scene in [
            Scene::Default,
            Scene::Town,
            Scene::Flat,
            Scene::Boxes(1),
            Scene::Boxes(1000),
            Scene::Boxes(MAX_SCENE_BOXES),
        ] {
            let placements = scene.placements(0);
            let ground = &placements[0];
            assert_eq!(ground.kind, ActorKind::Static);
            assert_eq!(
                ground.position.y + ground.extent.y,
                0.0,
                "{scene}: ground top at 0"
            );
            let name = scene.to_string().parse().unwrap();
            let points = shared_types::roads::network(name).spawn_points();
            assert!(!points.is_empty(), "{scene}");
            for p in points {
                // CARLA's (x, y) is simbus's (x, z).
                let (x, z) = (p.location[0] as f32, p.location[1] as f32);
                // The lane's far edge (and a margin) on the ground.
                let edge = 3.5 + 1.0;
                assert!(
                    x.abs() + edge < ground.extent.x,
                    "{scene}: {p:?} off the ground"
                );
                assert!(
                    z.abs() + edge < ground.extent.z,
                    "{scene}: {p:?} off the ground"
                );
                // Nothing within 3 m of the lane (bodies' sizes counted)
                // but the signs and lights beside it (`roads` keeps
                // those off the lanes).
                let signals = [ActorKind::TrafficLight, ActorKind::TrafficSign];
                for body in placements[1..]
                    .iter()
                    .filter(|b| !signals.contains(&b.kind))
                {
                    let reach = body.extent.x.max(body.extent.z) + 3.0;
                    let (dx, dz) = (body.position.x - x, body.position.z - z);
                    assert!(
                        dx.abs() > reach || dz.abs() > reach,
                        "{scene}: {p:?} within 3 m of a {:?} at {:?}",
                        body.kind,
                        body.position
                    );
                }
            }
        }
    }

    #[test]
    fn scenes_hold_what_they_say() {
        assert!(Scene::Empty.placements(0).is_empty());
        let boxes = Scene::Boxes(1000).placements(0);
        assert_eq!(boxes.len(), 1001);
        assert_eq!(
            boxes.iter().filter(|p| p.kind == ActorKind::Box).count(),
            1000
        );
        let default = Scene::Default.placements(0);
        assert_eq!(
            default
                .iter()
                .filter(|p| p.kind == ActorKind::Vehicle)
                .count(),
            2
        );
        assert!(default.iter().any(|p| p.kind == ActorKind::Sphere));
        assert!(default.iter().any(|p| p.kind == ActorKind::Capsule));
        assert!(
            default
                .iter()
                .filter(|p| p.kind == ActorKind::Static)
                .count()
                >= 2
        );
    }
}
