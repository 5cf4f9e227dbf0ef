//! The walkers' navigation mesh CARLA's client loads (`get_required_files`
//! `"Nav"`, then `request_file`): its walker AI (Recast/Detour's crowd, in
//! the client's process) walks pedestrians on it, and
//! `world.get_random_location_from_navigation()` picks its points from
//! its sidewalks.
//!
//! simbus generates it from the scene's roads, the same for the same
//! scene: along every road a sidewalk 2 m wide beside each outer lane edge
//! (where the cameras paint them), the two lanes as road, and the last
//! [`CROSSWALK`] metres of a road at a junction as a crosswalk; inside each
//! junction the road between its arms, and a sidewalk round each corner
//! from one arm's sidewalk to the next. Everything lies on the ground
//! (z = 0).
//!
//! The file is CARLA 0.9.16's: a `MSET` set of one Detour tile (Detour's
//! layout version 7, 32-bit references, at most 6 vertices a polygon), the
//! polygons' areas and flags as CARLA's (`carla/nav/Navigation.h`):
//! sidewalk 1, crosswalk 2, road 3. Detour builds the links between
//! polygons when it loads the tile, from each polygon's neighbours (edges
//! two polygons share, vertex for vertex); every polygon's detail mesh is
//! its own fan of triangles.

use std::collections::HashMap;
use std::f64::consts::PI;

use shared_types::roads::{Contact, Link, Pose2, Road, RoadNetwork, LANE_WIDTH};

/// A sidewalk's width beside a road's outer lane edge, metres (as the
/// cameras paint it).
const SIDEWALK: f64 = 2.0;
/// How long a crosswalk is along its road, metres.
const CROSSWALK: f64 = 3.0;
/// The longest a polygon is along its road, metres.
const PIECE: f64 = 4.0;

/// CARLA's navigation areas (`NavAreas`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Area {
    Sidewalk = 1,
    Crosswalk = 2,
    Road = 3,
}

impl Area {
    /// CARLA's polygon flag for the area (`SamplePolyFlags`).
    fn flag(self) -> u16 {
        match self {
            Self::Sidewalk => 0x02,
            Self::Crosswalk => 0x04,
            Self::Road => 0x08,
        }
    }
}

/// One walkable polygon: its corners in CARLA's axes (x, y, z up), metres.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Polygon {
    pub(crate) corners: Vec<[f64; 3]>,
    pub(crate) area: Area,
}

/// A point `t` metres to the left of `pose` (OpenDRIVE's axes), in
/// CARLA's (y flipped), on the ground.
fn at(pose: Pose2, t: f64) -> [f64; 3] {
    let p = pose.lateral(t);
    [p.x, -p.y, 0.0]
}

/// The lateral offsets of a road's bands, right to left: sidewalk, lane
/// -1, lane 1, sidewalk.
const BANDS: [f64; 5] = [
    -(LANE_WIDTH + SIDEWALK),
    -LANE_WIDTH,
    0.0,
    LANE_WIDTH,
    LANE_WIDTH + SIDEWALK,
];

/// Whether a road's end `contact` is at a junction.
fn at_junction(road: &Road, contact: Contact) -> bool {
    let link = match contact {
        Contact::Start => road.predecessor,
        Contact::End => road.successor,
    };
    matches!(link, Some(Link::Junction(_)))
}

/// The polygons of one road (not a junction's connecting road).
fn road_polygons(road: &Road, out: &mut Vec<Polygon>) {
    let length = road.length();
    let start_cross = at_junction(road, Contact::Start);
    let end_cross = at_junction(road, Contact::End);
    // Stations: the ends, the crosswalks' inner edges, and every PIECE.
    let mut stations = vec![0.0, length];
    if start_cross && length > 2.0 * CROSSWALK {
        stations.push(CROSSWALK);
    }
    if end_cross && length > 2.0 * CROSSWALK {
        stations.push(length - CROSSWALK);
    }
    let pieces = (length / PIECE).ceil().max(1.0) as usize;
    stations.extend((1..pieces).map(|i| length * i as f64 / pieces as f64));
    stations.sort_by(f64::total_cmp);
    stations.dedup_by(|a, b| (*a - *b).abs() < 0.5);
    if let Some(last) = stations.last_mut() {
        *last = length;
    }
    for pair in stations.windows(2) {
        let (s0, s1) = (pair[0], pair[1]);
        let (p0, p1) = (road.pose_at(s0), road.pose_at(s1));
        let crossing = (start_cross && s1 <= CROSSWALK + 1e-6)
            || (end_cross && s0 >= length - CROSSWALK - 1e-6);
        for (i, band) in BANDS.windows(2).enumerate() {
            let area = match i {
                0 | 3 => Area::Sidewalk,
                _ if crossing => Area::Crosswalk,
                _ => Area::Road,
            };
            out.push(Polygon {
                corners: vec![
                    at(p0, band[0]),
                    at(p1, band[0]),
                    at(p1, band[1]),
                    at(p0, band[1]),
                ],
                area,
            });
        }
    }
}

/// A point across an arm's end and the outer corner of its sidewalk (the
/// point itself on the centre line).
type EdgePoint = ([f64; 3], [f64; 3]);

/// One arm of a junction: its road's reference pose at the junction.
struct Arm {
    pose: Pose2,
}

/// The polygons inside junction `id`: the road between its arms (a fan
/// round its centre through every arm's lane edges and centre line) and a
/// sidewalk round each corner, from one arm's sidewalk to the next's.
fn junction_polygons(network: &RoadNetwork, id: u32, out: &mut Vec<Polygon>) {
    let arms: Vec<Arm> = network
        .roads
        .iter()
        .filter(|r| r.junction.is_none())
        .flat_map(|r| {
            let start =
                (r.predecessor == Some(Link::Junction(id))).then_some(Arm { pose: r.start });
            let end = (r.successor == Some(Link::Junction(id))).then(|| Arm {
                pose: r.pose_at(r.length()),
            });
            start.into_iter().chain(end)
        })
        .collect();
    if arms.len() < 2 {
        return;
    }
    let n = arms.len() as f64;
    let centre = arms.iter().fold([0.0, 0.0], |c, a| {
        let p = at(a.pose, 0.0);
        [c[0] + p[0] / n, c[1] + p[1] / n]
    });
    let angle = |p: [f64; 3]| (p[1] - centre[1]).atan2(p[0] - centre[0]);
    // Each arm's points across its end, ordered round the centre: the
    // lane edges and the centre line, each lane edge with its sidewalk's
    // outer corner.
    let mut ends: Vec<(f64, Vec<EdgePoint>)> = arms
        .iter()
        .map(|arm| {
            let mut points: Vec<EdgePoint> = [
                (BANDS[1], BANDS[0]),
                (BANDS[2], BANDS[2]),
                (BANDS[3], BANDS[4]),
            ]
            .iter()
            .map(|&(t, outer)| (at(arm.pose, t), at(arm.pose, outer)))
            .collect();
            let middle = angle(points[1].0);
            points.sort_by(|a, b| {
                let turn = |p: [f64; 3]| wrap(angle(p) - middle);
                turn(a.0).total_cmp(&turn(b.0))
            });
            (middle, points)
        })
        .collect();
    ends.sort_by(|a, b| a.0.total_cmp(&b.0));
    let ring: Vec<[f64; 3]> = ends
        .iter()
        .flat_map(|(_, points)| points.iter().map(|p| p.0))
        .collect();
    let centre = [centre[0], centre[1], 0.0];
    for (i, &a) in ring.iter().enumerate() {
        let b = ring[(i + 1) % ring.len()];
        out.push(Polygon {
            corners: vec![centre, a, b],
            area: Area::Road,
        });
    }
    for (i, (_, points)) in ends.iter().enumerate() {
        let (_, next) = &ends[(i + 1) % ends.len()];
        let (last, first) = (points[points.len() - 1], next[0]);
        out.push(Polygon {
            corners: vec![last.0, last.1, first.1, first.0],
            area: Area::Sidewalk,
        });
    }
}

/// `a` wrapped into (-π, π].
fn wrap(a: f64) -> f64 {
    let a = a.rem_euclid(2.0 * PI);
    if a > PI {
        a - 2.0 * PI
    } else {
        a
    }
}

/// Every walkable polygon of `network`.
pub(crate) fn polygons(network: &RoadNetwork) -> Vec<Polygon> {
    let mut out = Vec::new();
    for road in network.roads.iter().filter(|r| r.junction.is_none()) {
        road_polygons(road, &mut out);
    }
    for junction in &network.junctions {
        junction_polygons(network, junction.id, &mut out);
    }
    out
}

/// Detour's tile magic (`'D' 'N' 'A' 'V'`) and layout version.
const DT_NAVMESH_MAGIC: i32 = 0x444E_4156;
const DT_NAVMESH_VERSION: i32 = 7;
/// CARLA's set magic (`'M' 'S' 'E' 'T'`) and version.
const NAVMESH_SET_MAGIC: i32 = 0x4D53_4554;
const NAVMESH_SET_VERSION: i32 = 1;
/// Detour's most vertices a polygon.
const VERTS_PER_POLYGON: usize = 6;
/// Detour's flag of a detail triangle's edge on its polygon's boundary.
const DETAIL_EDGE_BOUNDARY: u8 = 1;

/// Twice the signed area of triangle (a, b, c) on Recast's ground plane
/// (x, z), as Detour's `dtTriArea2D` computes it.
fn tri_area_2d(a: [f32; 3], b: [f32; 3], c: [f32; 3]) -> f32 {
    (c[0] - a[0]) * (b[2] - a[2]) - (b[0] - a[0]) * (c[2] - a[2])
}

/// `polygons` as CARLA 0.9.16's navigation file: one `MSET` tile. `None`
/// when there is nothing walkable or more vertices than a tile holds.
pub(crate) fn navmesh(polygons: &[Polygon]) -> Option<Vec<u8>> {
    // Vertices in Recast's axes (x, up, z = CARLA's y), shared by key.
    let mut verts: Vec<[f32; 3]> = Vec::new();
    let mut index: HashMap<[i64; 3], u16> = HashMap::new();
    let mut polys: Vec<(Vec<u16>, Area)> = Vec::new();
    for polygon in polygons {
        let mut ids: Vec<u16> = Vec::new();
        for c in &polygon.corners {
            let v = [c[0] as f32, c[2] as f32, c[1] as f32];
            let key = [c[0], c[2], c[1]].map(|x| (x * 1000.0).round() as i64);
            let next = u16::try_from(verts.len()).ok()?;
            let id = *index.entry(key).or_insert_with(|| {
                verts.push(v);
                next
            });
            if ids.last() != Some(&id) && ids.first() != Some(&id) {
                ids.push(id);
            }
        }
        if ids.len() < 3 || ids.len() > VERTS_PER_POLYGON {
            continue;
        }
        let v = |i: usize| verts[usize::from(ids[i])];
        let area: f32 = (2..ids.len())
            .map(|j| tri_area_2d(v(0), v(j - 1), v(j)))
            .sum();
        if area.abs() < 1e-4 {
            continue;
        }
        if area < 0.0 {
            ids.reverse();
        }
        polys.push((ids, polygon.area));
    }
    if polys.is_empty() {
        return None;
    }
    // Each polygon's neighbour across each edge (0: none; k: polygon k-1).
    let mut edges: HashMap<(u16, u16), Vec<usize>> = HashMap::new();
    for (p, (ids, _)) in polys.iter().enumerate() {
        for j in 0..ids.len() {
            let (a, b) = (ids[j], ids[(j + 1) % ids.len()]);
            edges.entry((a.min(b), a.max(b))).or_default().push(p);
        }
    }
    let poly_count = polys.len();
    let vert_count = verts.len();
    let max_links: usize = polys.iter().map(|(ids, _)| ids.len()).sum();
    let tri_count: usize = polys.iter().map(|(ids, _)| ids.len() - 2).sum();
    let mut bmin = [f32::MAX; 3];
    let mut bmax = [f32::MIN; 3];
    for v in &verts {
        for k in 0..3 {
            bmin[k] = bmin[k].min(v[k]);
            bmax[k] = bmax[k].max(v[k]);
        }
    }
    let mut tile: Vec<u8> = Vec::new();
    let int = |out: &mut Vec<u8>, x: i32| out.extend_from_slice(&x.to_le_bytes());
    let float = |out: &mut Vec<u8>, x: f32| out.extend_from_slice(&x.to_le_bytes());
    let count = |n: usize| i32::try_from(n).ok();
    // dtMeshHeader, 100 bytes.
    for x in [DT_NAVMESH_MAGIC, DT_NAVMESH_VERSION, 0, 0, 0, 0] {
        int(&mut tile, x);
    }
    for x in [
        count(poly_count)?,
        count(vert_count)?,
        count(max_links)?,
        count(poly_count)?,
        0,
        count(tri_count)?,
        0,
        0,
        count(poly_count)?,
    ] {
        int(&mut tile, x);
    }
    // Walkable height, radius and climb: CARLA's agents'.
    for x in [1.8, 0.3, 0.3] {
        float(&mut tile, x);
    }
    for x in bmin.iter().chain(&bmax) {
        float(&mut tile, *x);
    }
    float(&mut tile, 1.0 / 0.3);
    for v in &verts {
        for x in v {
            float(&mut tile, *x);
        }
    }
    for (p, (ids, area)) in polys.iter().enumerate() {
        tile.extend_from_slice(&u32::MAX.to_le_bytes());
        let mut vs = [0u16; VERTS_PER_POLYGON];
        let mut neis = [0u16; VERTS_PER_POLYGON];
        for (j, &id) in ids.iter().enumerate() {
            vs[j] = id;
            let b = ids[(j + 1) % ids.len()];
            let shared = &edges[&(id.min(b), id.max(b))];
            neis[j] = shared
                .iter()
                .find(|&&q| q != p)
                .map_or(0, |&q| u16::try_from(q + 1).unwrap_or(0));
        }
        for x in vs.iter().chain(&neis) {
            tile.extend_from_slice(&x.to_le_bytes());
        }
        tile.extend_from_slice(&area.flag().to_le_bytes());
        tile.push(ids.len() as u8);
        tile.push(*area as u8);
    }
    tile.resize(tile.len() + 12 * max_links, 0);
    let mut tri_base = 0u32;
    for (ids, _) in &polys {
        tile.extend_from_slice(&0u32.to_le_bytes());
        tile.extend_from_slice(&tri_base.to_le_bytes());
        tile.extend_from_slice(&[0, (ids.len() - 2) as u8, 0, 0]);
        tri_base += (ids.len() - 2) as u32;
    }
    for (ids, _) in &polys {
        let n = ids.len();
        for j in 2..n {
            // Edge 0 (a-b) is the polygon's first edge for the first
            // triangle, edge 1 (b-c) always, edge 2 (c-a) for the last.
            let mut flags = DETAIL_EDGE_BOUNDARY << 2;
            if j == 2 {
                flags |= DETAIL_EDGE_BOUNDARY;
            }
            if j == n - 1 {
                flags |= DETAIL_EDGE_BOUNDARY << 4;
            }
            tile.extend_from_slice(&[0, (j - 1) as u8, j as u8, flags]);
        }
    }
    while !tile.len().is_multiple_of(4) {
        tile.push(0);
    }
    let max_polys = poly_count.next_power_of_two().max(2);
    let poly_bits = max_polys.trailing_zeros();
    let mut file: Vec<u8> = Vec::new();
    for x in [NAVMESH_SET_MAGIC, NAVMESH_SET_VERSION, 1] {
        int(&mut file, x);
    }
    // dtNavMeshParams: origin, tile width and height (on x and z), one
    // tile, its polygons.
    for x in bmin {
        float(&mut file, x);
    }
    float(&mut file, bmax[0] - bmin[0] + 1.0);
    float(&mut file, bmax[2] - bmin[2] + 1.0);
    int(&mut file, 1);
    int(&mut file, count(max_polys)?);
    file.extend_from_slice(&(1u32 << poly_bits).to_le_bytes());
    int(&mut file, count(tile.len())?);
    file.extend_from_slice(&tile);
    Some(file)
}

#[cfg(test)]
mod tests;
