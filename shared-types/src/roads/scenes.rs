//! The road network of each scene: `town`'s grid and loop, a ring road
//! around the action of `default`, `boxes:N` and the others, on their
//! ground and clear of their bodies.

use std::collections::BTreeMap;
use std::f64::consts::FRAC_PI_2;

use super::{Contact, Pose2, RoadNetwork, Segment, SPEED_LIMIT_KMH};
use crate::scene::SceneName;

/// Half the side of `town`'s ground, metres: well past the network
/// (about ±122 m), so the positions CARLA's scripts hard-code for CARLA's
/// towns (a few hundred metres out) stand on ground instead of falling.
pub const TOWN_GROUND_HALF_SIZE: f32 = 1000.0;
/// Half the side of `flat`'s ground, metres (the world
/// `generate_opendrive_world` builds: roads of about 4 km across fit).
pub const FLAT_GROUND_HALF_SIZE: f32 = 2000.0;

/// Where `town`'s grid lines run (x and y), metres: four of them, 80 m
/// apart; the outer ones make the loop.
const TOWN_LINES: [f64; 4] = [-120.0, -40.0, 40.0, 120.0];
/// How far from a junction's centre its roads end, metres.
const JUNCTION_HALF: f64 = 10.0;
/// The radius of the loop's corners, metres.
const TOWN_CORNER_RADIUS: f64 = 20.0;

/// The road network of `scene`, the same every time.
pub fn network(scene: SceneName) -> RoadNetwork {
    match scene {
        SceneName::Town => town(),
        // The ground ends at 50 m; the ramp, the box tower and the
        // vehicles stay within 15 m of the origin.
        SceneName::Default | SceneName::Empty | SceneName::Flat => ring("default", 35.0, 10.0),
        SceneName::Boxes(n) => {
            // As the server builds it: a ground of 20 m + one per row of
            // boxes, the boxes within 14 m of the origin.
            let per_row = f64::from(n).cbrt().ceil().clamp(1.0, 40.0);
            let half = 0.7 * (20.0 + per_row);
            ring(&scene.to_string(), half, (half / 3.0).min(10.0))
        }
    }
}

/// A ring road around the origin: a square of side `2 × half` (road
/// centre) with corners rounded to `radius`, four roads joined end to end,
/// driven counter-clockwise on lane -1 (clockwise on lane 1).
fn ring(name: &str, half: f64, radius: f64) -> RoadNetwork {
    let mut network = RoadNetwork::new(name);
    let side = 2.0 * (half - radius);
    for k in 0..4 {
        let hdg = f64::from(k) * FRAC_PI_2;
        let (sin, cos) = hdg.sin_cos();
        let (x, y) = (-half + radius, -half);
        network.add_road(
            Pose2::new(x * cos - y * sin, x * sin + y * cos, hdg),
            vec![
                Segment::Line { length: side },
                Segment::Arc {
                    length: radius * FRAC_PI_2,
                    curvature: 1.0 / radius,
                },
            ],
        );
    }
    for k in 0..4 {
        network.join(k, (k + 1) % 4);
    }
    network
}

/// A grid node of `town`: indices into [`TOWN_LINES`].
type Node = (usize, usize);

/// Whether `node` is a corner of the loop (no junction there).
fn corner(node: Node) -> bool {
    let outer = |i: usize| i == 0 || i == TOWN_LINES.len() - 1;
    outer(node.0) && outer(node.1)
}

/// `town`: a 4 × 4 grid of two-lane roads 80 m apart whose outer lines
/// are a loop with rounded corners; four-way junctions inside, T
/// junctions on the loop.
fn town() -> RoadNetwork {
    let mut network = RoadNetwork::new("town");
    let mut arms: BTreeMap<Node, Vec<(u32, Contact)>> = BTreeMap::new();
    let last = TOWN_LINES.len() - 1;
    // The straight roads between two junctions, east- and northbound.
    for a in 0..=last {
        for b in 0..last {
            for (from, to, hdg) in [((b, a), (b + 1, a), 0.0), ((a, b), (a, b + 1), FRAC_PI_2)] {
                if corner(from) || corner(to) {
                    continue;
                }
                let start = Pose2::new(
                    TOWN_LINES[from.0] + JUNCTION_HALF * hdg.cos(),
                    TOWN_LINES[from.1] + JUNCTION_HALF * hdg.sin(),
                    hdg,
                );
                let length = TOWN_LINES[1] - TOWN_LINES[0] - 2.0 * JUNCTION_HALF;
                let id = network.add_road(start, vec![Segment::Line { length }]);
                arms.entry(from).or_default().push((id, Contact::Start));
                arms.entry(to).or_default().push((id, Contact::End));
            }
        }
    }
    // The loop's corners: from the junction before each corner to the one
    // after it, counter-clockwise.
    let corners = [(last, 0), (last, last), (0, last), (0, 0)];
    let mut corner_roads = Vec::new();
    let spacing = TOWN_LINES[1] - TOWN_LINES[0];
    let straight = spacing - JUNCTION_HALF - TOWN_CORNER_RADIUS;
    for (k, &(i, j)) in corners.iter().enumerate() {
        let hdg = k as f64 * FRAC_PI_2;
        let (sin, cos) = hdg.sin_cos();
        let (cx, cy) = (TOWN_LINES[i], TOWN_LINES[j]);
        let from = grid_node(cx - spacing * cos, cy - spacing * sin);
        let to = grid_node(cx - spacing * sin, cy + spacing * cos);
        let start = Pose2::new(
            cx - (spacing - JUNCTION_HALF) * cos,
            cy - (spacing - JUNCTION_HALF) * sin,
            hdg,
        );
        let id = network.add_road(
            start,
            vec![
                Segment::Line { length: straight },
                Segment::Arc {
                    length: TOWN_CORNER_RADIUS * FRAC_PI_2,
                    curvature: 1.0 / TOWN_CORNER_RADIUS,
                },
                Segment::Line { length: straight },
            ],
        );
        arms.entry(from).or_default().push((id, Contact::Start));
        arms.entry(to).or_default().push((id, Contact::End));
        corner_roads.push(id);
    }
    for node_arms in arms.values() {
        let id = network.add_junction(node_arms);
        // Lights where four roads meet; where a road from inside meets
        // the loop, the loop goes first.
        if node_arms.len() == 4 {
            network.add_lights(id);
        } else {
            network.add_stop_on_stem(id);
        }
    }
    // The corners are signed with the town's limit.
    for id in corner_roads {
        network.add_speed_limits(id, SPEED_LIMIT_KMH as u32);
    }
    network
}

/// The grid node at `x`, `y` (on the grid lines).
fn grid_node(x: f64, y: f64) -> Node {
    let index = |v: f64| {
        TOWN_LINES
            .iter()
            .position(|&line| (line - v).abs() < 1e-6)
            .unwrap_or(0)
    };
    (index(x), index(y))
}
