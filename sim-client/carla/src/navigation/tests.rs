//! The town's navigation mesh: its polygons, and the file as Detour reads it.

use std::collections::{HashSet, VecDeque};

use shared_types::roads;
use shared_types::scene::SceneName;

use super::*;

fn i32_at(bytes: &[u8], at: usize) -> i32 {
    i32::from_le_bytes(bytes[at..at + 4].try_into().unwrap())
}

fn u16_at(bytes: &[u8], at: usize) -> u16 {
    u16::from_le_bytes(bytes[at..at + 2].try_into().unwrap())
}

/// The tile's polygons as the file holds them: (vertex count, area, neighbours).
fn tile_polygons(file: &[u8]) -> Vec<(usize, u8, Vec<u16>)> {
    assert_eq!(i32_at(file, 0), NAVMESH_SET_MAGIC);
    assert_eq!(
        (i32_at(file, 4), i32_at(file, 8)),
        (1, 1),
        "version 1, one tile"
    );
    let tile = &file[48..];
    assert_eq!(i32_at(file, 44) as usize, tile.len());
    assert_eq!((i32_at(tile, 0), i32_at(tile, 4)), (DT_NAVMESH_MAGIC, 7));
    let (polys, verts) = (i32_at(tile, 24) as usize, i32_at(tile, 28) as usize);
    let start = 100 + 12 * verts;
    (0..polys)
        .map(|p| {
            let at = start + 32 * p;
            let count = tile[at + 30] as usize;
            let neis = (0..count).map(|j| u16_at(tile, at + 16 + 2 * j)).collect();
            (count, tile[at + 31], neis)
        })
        .collect()
}

#[test]
fn the_towns_sidewalks_and_crosswalks_are_one_walkable_whole() {
    let network = roads::network(SceneName::Town);
    let polygons = polygons(&network);
    let sidewalk: f64 = polygons
        .iter()
        .filter(|p| p.area == Area::Sidewalk)
        .map(|p| {
            let c = &p.corners;
            (0..c.len())
                .map(|i| {
                    let (a, b) = (c[i], c[(i + 1) % c.len()]);
                    a[0] * b[1] - b[0] * a[1]
                })
                .sum::<f64>()
                .abs()
                / 2.0
        })
        .sum();
    let length: f64 = network
        .roads
        .iter()
        .filter(|r| r.junction.is_none())
        .map(|r| r.length())
        .sum();
    // A 2 m sidewalk on each side of every road, and the corners.
    assert!(
        sidewalk > 0.95 * 4.0 * length,
        "{sidewalk} m² along {length} m of road"
    );
    let file = navmesh(&polygons).expect("a navigation mesh");
    let tile = tile_polygons(&file);
    assert!(tile.len() > 500 && tile.iter().all(|(n, _, _)| (3..=6).contains(n)));
    assert!(tile
        .iter()
        .any(|(_, area, _)| *area == Area::Crosswalk as u8));
    // Neighbours name each other.
    for (p, (_, _, neis)) in tile.iter().enumerate() {
        for &n in neis.iter().filter(|&&n| n != 0) {
            assert!(
                tile[usize::from(n) - 1].2.contains(&((p + 1) as u16)),
                "{p} and {n}"
            );
        }
    }
    // Walking only on sidewalks and crosswalks (CARLA's walkers that do not
    // cross roads), every sidewalk reaches every other.
    let walkable = |p: usize| tile[p].1 != Area::Road as u8;
    let first = (0..tile.len()).find(|&p| walkable(p)).unwrap();
    let mut seen = HashSet::from([first]);
    let mut queue = VecDeque::from([first]);
    while let Some(p) = queue.pop_front() {
        for &n in &tile[p].2 {
            let q = usize::from(n).wrapping_sub(1);
            if n != 0 && walkable(q) && seen.insert(q) {
                queue.push_back(q);
            }
        }
    }
    let all = (0..tile.len()).filter(|&p| walkable(p)).count();
    assert_eq!(seen.len(), all, "walkable polygons reached from the first");
}

#[test]
fn every_scene_has_a_mesh_and_the_same_scene_the_same_bytes() {
    for scene in [SceneName::Town, SceneName::Default] {
        let a = navmesh(&polygons(&roads::network(scene))).unwrap();
        let b = navmesh(&polygons(&roads::network(scene))).unwrap();
        assert_eq!(a, b, "{scene}");
    }
    assert_eq!(navmesh(&[]), None);
}
