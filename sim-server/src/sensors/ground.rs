//! What the ground is at a point, for the image cameras: road, lane mark,
//! sidewalk or terrain, from the scene's road network (the map CARLA's
//! clients read). Painted once per scene into a raster of
//! [`CELL`]-metre cells over the roads' bounds.

use shared_types::roads::{RoadNetwork, LANE_WIDTH};
use shared_types::SemanticTag;

/// The raster's cell, metres.
const CELL: f64 = 0.1;
/// Cells per metre (a lookup multiplies: a division per pixel cost a
/// fifth of an RGB camera's time).
const PER_METRE: f64 = 1.0 / CELL;
/// The raster is stored in tiles of `TILE` x `TILE` cells, one cache line
/// each, so that a camera's neighbouring ground points, whichever way the
/// camera looks, share lines (row by row, the town's lookups missed the
/// cache whenever the camera looked across the raster's rows).
const TILE: usize = 8;
/// A sidewalk's width beside a road's outer lane edges, metres.
const SIDEWALK: f64 = 2.0;
/// How far either side of a mark's line it is painted, metres (CARLA's
/// marks are 0.15 m wide; a cell more keeps them unbroken at a distance).
const MARK_HALF: f64 = 0.1;

/// What covers the ground at a point.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
#[repr(u8)]
pub(super) enum Cover {
    Terrain = 0,
    Sidewalk = 1,
    Road = 2,
    /// A lane's edge mark (white).
    EdgeMark = 3,
    /// The centre line between the two directions (yellow).
    CentreMark = 4,
}

impl Cover {
    /// CARLA's tag for it.
    pub(super) fn tag(self) -> SemanticTag {
        match self {
            Self::Terrain => SemanticTag::Terrain,
            Self::Sidewalk => SemanticTag::Sidewalks,
            Self::Road => SemanticTag::Roads,
            Self::EdgeMark | Self::CentreMark => SemanticTag::RoadLines,
        }
    }

    /// Its colour (r, g, b) in an RGB image.
    pub(super) fn colour(self) -> [u8; 3] {
        match self {
            Self::Terrain => [96, 128, 64],
            Self::Sidewalk => [168, 164, 156],
            Self::Road => [72, 72, 76],
            Self::EdgeMark => [232, 232, 232],
            Self::CentreMark => [236, 196, 48],
        }
    }
}

/// A scene's ground, painted from its road network.
#[derive(Debug)]
pub(super) struct GroundMap {
    /// OpenDRIVE x and y of cell (0, 0)'s corner.
    origin: (f64, f64),
    columns: usize,
    rows: usize,
    cells: Vec<Cover>,
}

impl GroundMap {
    /// Paints `network`: sidewalks, then roads over them, then the marks of
    /// the roads outside junctions (connecting roads have none).
    pub(super) fn paint(network: &RoadNetwork) -> Self {
        let reach = LANE_WIDTH + SIDEWALK;
        let (mut low, mut high) = ((f64::MAX, f64::MAX), (f64::MIN, f64::MIN));
        for road in &network.roads {
            let step = (road.length() / 64.0).max(CELL);
            let mut s = 0.0;
            while s <= road.length() + step {
                let p = road.pose_at(s);
                low = (low.0.min(p.x - reach), low.1.min(p.y - reach));
                high = (high.0.max(p.x + reach), high.1.max(p.y + reach));
                s += step;
            }
        }
        if low.0 > high.0 {
            return Self {
                origin: (0.0, 0.0),
                columns: 0,
                rows: 0,
                cells: Vec::new(),
            };
        }
        let tiles = |metres: f64| (metres / CELL).ceil() as usize / TILE + 1;
        let (columns, rows) = (tiles(high.0 - low.0) * TILE, tiles(high.1 - low.1) * TILE);
        let mut map = Self {
            origin: low,
            columns,
            rows,
            cells: vec![Cover::Terrain; columns * rows],
        };
        let bands: [(f64, f64, Cover, bool); 4] = [
            (-reach, reach, Cover::Sidewalk, true),
            (-LANE_WIDTH, LANE_WIDTH, Cover::Road, true),
            (-MARK_HALF, MARK_HALF, Cover::CentreMark, false),
            (
                LANE_WIDTH - MARK_HALF,
                LANE_WIDTH + MARK_HALF,
                Cover::EdgeMark,
                false,
            ),
        ];
        for (from, to, cover, in_junctions) in bands {
            for road in &network.roads {
                let connecting = road.junction.is_some();
                if connecting && !in_junctions {
                    continue;
                }
                // Junctions' sidewalks would cover their own roads' ends.
                if connecting && cover == Cover::Sidewalk {
                    continue;
                }
                let sides: &[f64] = if cover == Cover::EdgeMark {
                    &[1.0, -1.0]
                } else {
                    &[1.0]
                };
                let length = road.length();
                let mut s = 0.0;
                while s <= length {
                    let pose = road.pose_at(s);
                    for &side in sides {
                        let mut t = from;
                        while t <= to {
                            let p = pose.lateral(side * t);
                            map.set(p.x, p.y, cover);
                            t += CELL / 2.0;
                        }
                    }
                    s += CELL / 2.0;
                }
            }
        }
        map
    }

    fn set(&mut self, x: f64, y: f64, cover: Cover) {
        if let Some(i) = self.index(x, y) {
            self.cells[i] = cover;
        }
    }

    fn index(&self, x: f64, y: f64) -> Option<usize> {
        let (c, r) = (
            (x - self.origin.0) * PER_METRE,
            (y - self.origin.1) * PER_METRE,
        );
        if !(c >= 0.0 && r >= 0.0) {
            return None;
        }
        let (c, r) = (c as usize, r as usize);
        let tile = (r / TILE) * (self.columns / TILE) + c / TILE;
        (c < self.columns && r < self.rows)
            .then(|| tile * TILE * TILE + (r % TILE) * TILE + c % TILE)
    }

    /// What covers the ground at simbus position (`x`, `z`) (OpenDRIVE's
    /// x = X, y = −Z).
    pub(super) fn at(&self, x: f32, z: f32) -> Cover {
        self.index(f64::from(x), -f64::from(z))
            .map_or(Cover::Terrain, |i| self.cells[i])
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared_types::scene::SceneName;

    #[test]
    fn the_town_s_roads_have_marks_on_their_centre_and_edges() {
        let network = shared_types::roads::network(SceneName::Town);
        let map = GroundMap::paint(&network);
        let road = network
            .roads
            .iter()
            .find(|r| r.junction.is_none() && r.length() > 30.0)
            .expect("a long road");
        let p = road.pose_at(road.length() / 2.0);
        // simbus's Z is OpenDRIVE's −y.
        let at = |t: f64| {
            let q = p.lateral(t);
            map.at(q.x as f32, -q.y as f32)
        };
        assert_eq!(at(0.0), Cover::CentreMark);
        assert_eq!(at(1.75), Cover::Road);
        assert_eq!(at(-1.75), Cover::Road);
        assert_eq!(at(LANE_WIDTH), Cover::EdgeMark);
        assert_eq!(at(-LANE_WIDTH), Cover::EdgeMark);
        assert_eq!(at(LANE_WIDTH + 1.0), Cover::Sidewalk);
        assert_eq!(at(LANE_WIDTH + SIDEWALK + 1.0), Cover::Terrain);
        assert_eq!(map.at(1e6, 1e6), Cover::Terrain);
    }
}
