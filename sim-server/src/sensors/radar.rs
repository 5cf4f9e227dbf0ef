//! The radar and the semantic lidar's returns.
//!
//! A radar casts `points_per_second × Δt` rays per capture, each towards a
//! point drawn as CARLA's `Radar.cpp` draws it: a radius `r` uniform in
//! (0, 1] and an angle `θ` uniform around the axis, the ray aimed at
//! (`range`, `tan(h/2)·range·r·cos θ` right, `tan(v/2)·range·r·sin θ` up)
//! and traced that far. Each hit reports the velocity of what it met
//! relative to the sensor's parent, along the ray (negative: coming
//! closer), the ray's azimuth and altitude and the distance. The
//! generator is seeded with the radar's `noise_seed`, so a world run twice
//! with the same inputs draws the same rays.

use std::mem::MaybeUninit;

use rapier3d::prelude::{Pose, Vector};
use shared_types::{RadarDetection, SemanticLidarPoint, SensorSpec};

use super::camera::surface;
use super::capture::Return;
use super::culling::{self, View};
use super::ground::GroundMap;
use super::random::Random;
use crate::world::World;

/// A semantic lidar's point for `hit`: where (sensor frame), the cosine of
/// the angle the ray met the surface at, and the actor and tag it met.
pub(super) fn semantic_point(
    hit: &Return,
    sensor: Vector,
    ground: &GroundMap,
) -> SemanticLidarPoint {
    let point = hit.local * hit.distance;
    let normal = hit
        .target
        .normal(hit.direction, hit.distance)
        .unwrap_or(-hit.direction);
    let (tag, _) = surface(hit.target, sensor + hit.direction * hit.distance, ground);
    SemanticLidarPoint {
        x: point.x,
        y: point.y,
        z: point.z,
        cos_inc_angle: normal.dot(hit.direction).abs().min(1.0),
        object_idx: u32::try_from(hit.target.actor).unwrap_or(u32::MAX),
        object_tag: tag as u32,
    }
}

/// Casts `rays` radar rays from `pose` and writes a detection per hit at
/// the start of `slots` (the rest zeroed). Returns how many hit.
pub(super) fn radar_into(
    world: &World,
    spec: &SensorSpec,
    (pose, rays): (Pose, usize),
    random: &mut Random,
    slots: &mut [MaybeUninit<RadarDetection>],
) -> usize {
    let Some(radar) = spec.radar_params() else {
        slots.fill(MaybeUninit::new(RadarDetection::default()));
        return 0;
    };
    let half = |fov: f32| (fov.to_radians() / 2.0).tan();
    let (right_most, up_most) = (half(radar.horizontal_fov), half(radar.vertical_fov));
    let view = View::camera(right_most, up_most);
    // The longest ray: to a corner of the far plane.
    let far = radar.range * Vector::new(1.0, up_most, right_most).length();
    let targets = culling::targets(world, &view, &pose, far, world.body_of(spec.attach_to));
    let own_velocity = world.velocity_at(spec.attach_to, pose.translation);
    let mut hits = 0;
    for _ in 0..rays.min(slots.len()) {
        let r = random.uniform() as f32;
        let (sin, cos) = (random.uniform() * std::f64::consts::TAU).sin_cos();
        let (right, up) = (right_most * r * cos as f32, up_most * r * sin as f32);
        let aim = Vector::new(1.0, up, right);
        let (local, length) = (aim.normalize(), radar.range * aim.length());
        let direction = pose.rotation * local;
        let seen = targets.iter().filter(|t| t.bounds.contains(right, up));
        let Some((depth, target)) = culling::nearest_target(seen, direction, length) else {
            continue;
        };
        let point = pose.translation + direction * depth;
        let relative = world.velocity_at(target.actor, point) - own_velocity;
        slots[hits].write(RadarDetection {
            velocity: relative.dot(direction),
            azimuth: local.z.atan2(local.x),
            altitude: local.y.atan2(local.x.hypot(local.z)),
            depth,
        });
        hits += 1;
    }
    slots[hits..].fill(MaybeUninit::new(RadarDetection::default()));
    hits
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::sensors::capture::sensor_pose;
    use shared_types::Radar;

    fn cast(world: &World, spec: &SensorSpec, seed: u64, rays: usize) -> Vec<RadarDetection> {
        let pose = sensor_pose(world, spec).expect("a pose");
        let mut slots = vec![MaybeUninit::new(RadarDetection::default()); rays];
        let hits = radar_into(
            world,
            spec,
            (pose, rays),
            &mut Random::new(seed),
            &mut slots,
        );
        // SAFETY: radar_into writes every slot.
        slots[..hits]
            .iter()
            .map(|s| unsafe { s.assume_init() })
            .collect()
    }

    #[test]
    fn every_detection_lies_in_the_field_of_view_and_the_same_seed_draws_the_same() {
        let (world, _) = crate::sensors::default_world_in_motion();
        let radar = Radar {
            horizontal_fov: 60.0,
            vertical_fov: 20.0,
            range: 40.0,
            points_per_second: 1000,
            seed: 0,
        };
        // Low over the ground, looking along +X at the scene.
        let spec = SensorSpec::with_params([-10.0, 0.8, 0.0], radar);
        let a = cast(&world, &spec, 3, 1000);
        assert!(a.len() > 100, "{} hits", a.len());
        for d in &a {
            assert!(d.azimuth.abs() <= 30f32.to_radians() + 1e-4, "{d:?}");
            assert!(d.altitude.abs() <= 10f32.to_radians() + 1e-4, "{d:?}");
            assert!(d.depth > 0.0 && d.depth <= 40.0 / 0.8, "{d:?}");
            // Where the detection says, a ray meets something.
            let local = Vector::new(
                d.altitude.cos() * d.azimuth.cos(),
                d.altitude.sin(),
                d.altitude.cos() * d.azimuth.sin(),
            );
            let met = world.cast_ray(Vector::new(-10.0, 0.8, 0.0), local, 60.0, None);
            assert!(
                met.is_some_and(|m| (m - d.depth).abs() < 1e-3),
                "{d:?} {met:?}"
            );
        }
        assert_eq!(a, cast(&world, &spec, 3, 1000));
        assert_ne!(a, cast(&world, &spec, 4, 1000));
    }
}
