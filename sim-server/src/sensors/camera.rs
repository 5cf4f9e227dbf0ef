//! The depth camera: one ray per pixel, each cast only against the
//! colliders whose bounds on the image cover that pixel (see `culling`).

use std::mem::MaybeUninit;
use std::ops::RangeInclusive;

use rapier3d::prelude::{Pose, Vector};
use rayon::prelude::*;
use shared_types::{DepthCamera, SensorSpec};

use super::culling::{self, Target, View};
use crate::world::World;

/// The camera's intrinsics: image size and focal length in pixels. Pixel
/// (u, v) looks along (focal, h/2 − v − ½, u + ½ − w/2) in the camera frame
/// (+X forward, +Y up, +Z right).
#[derive(Clone, Copy)]
struct Intrinsics {
    width: usize,
    height: usize,
    focal: f32,
}

impl Intrinsics {
    fn of(camera: &DepthCamera) -> Self {
        Self {
            width: camera.width as usize,
            height: camera.height as usize,
            focal: (camera.width as f32 / 2.0) / (camera.fov.to_radians() / 2.0).tan(),
        }
    }

    /// The unit direction of pixel (u, v)'s ray in the camera frame.
    fn direction(&self, u: usize, v: usize) -> Vector {
        let (w, h) = (self.width as f32, self.height as f32);
        let up = h / 2.0 - v as f32 - 0.5;
        let right = u as f32 + 0.5 - w / 2.0;
        Vector::new(self.focal, up, right).normalize()
    }

    fn view(&self) -> View {
        View::camera(
            self.width as f32 / 2.0 / self.focal,
            self.height as f32 / 2.0 / self.focal,
        )
    }

    /// The columns and rows a target's bounds cover, a pixel wider each way.
    fn pixels(&self, target: &Target) -> Option<(RangeInclusive<usize>, RangeInclusive<usize>)> {
        let (w, h) = (self.width as f32, self.height as f32);
        let span = |low: f32, high: f32, size: usize| {
            let (low, high) = (low.floor() - 1.0, high.ceil() + 1.0);
            if high < 0.0 || low > (size - 1) as f32 {
                return None;
            }
            Some(low.max(0.0) as usize..=high.min((size - 1) as f32) as usize)
        };
        let b = &target.bounds;
        let columns = span(
            b.right.start() * self.focal + w / 2.0 - 0.5,
            b.right.end() * self.focal + w / 2.0 - 0.5,
            self.width,
        )?;
        let rows = span(
            h / 2.0 - 0.5 - b.up.end() * self.focal,
            h / 2.0 - 0.5 - b.up.start() * self.focal,
            self.height,
        )?;
        Some((columns, rows))
    }
}

/// Ray-casts one planar depth per pixel straight into `slots` (width ×
/// height of them), rows in parallel; `far` where nothing is hit.
pub(super) fn depth_into(
    world: &World,
    spec: &SensorSpec,
    pose: Pose,
    slots: &mut [MaybeUninit<f32>],
) {
    let Some(params) = spec.depth_camera() else {
        return;
    };
    let camera = Intrinsics::of(&params);
    let far = params.range;
    if camera.width == 0 || camera.height == 0 {
        return;
    }
    let exclude = world.body_of(spec.attach_to);
    let targets = culling::targets(world, &camera.view(), &pose, far, exclude);
    // Infinite bounds saturate to the whole image.
    let in_view: Vec<_> = targets
        .iter()
        .filter_map(|t| Some((t, camera.pixels(t)?)))
        .collect();
    slots
        .par_chunks_mut(camera.width)
        .take(camera.height)
        .enumerate()
        .for_each_init(Vec::new, |row_view, (v, row)| {
            row_view.clear();
            row_view.extend(
                in_view
                    .iter()
                    .filter(|(_, (_, rows))| rows.contains(&v))
                    .map(|(t, (columns, _))| (*t, columns)),
            );
            for (u, slot) in row.iter_mut().enumerate() {
                let direction = camera.direction(u, v);
                let seen = row_view
                    .iter()
                    .filter(|(_, columns)| columns.contains(&u))
                    .map(|(t, _)| *t);
                // Planar depth: distance along the optical axis (+X).
                slot.write(
                    culling::nearest(seen, pose.rotation * direction, far)
                        .map_or(far, |d| d * direction.x),
                );
            }
        });
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The image rapier's query pipeline gives, one ray at a time.
    fn pipeline_image(world: &World, spec: &SensorSpec, pose: Pose) -> Vec<f32> {
        let params = spec.depth_camera().expect("a depth camera");
        let camera = Intrinsics::of(&params);
        let far = params.range;
        let exclude = world.body_of(spec.attach_to);
        let mut image = Vec::new();
        for v in 0..camera.height {
            for u in 0..camera.width {
                let direction = camera.direction(u, v);
                let hit = world.cast_ray(pose.translation, pose.rotation * direction, far, exclude);
                image.push(hit.map_or(far, |d| d * direction.x));
            }
        }
        image
    }

    #[test]
    fn the_culled_camera_sees_what_the_query_pipeline_sees_bit_for_bit() {
        let (world, vehicle) = super::super::default_world_in_motion();
        let specs = [
            // Overlooking the scene, looking along +X.
            SensorSpec::depth([-4.0, 3.0, 0.0], 160, 120, 90.0, 100.0),
            // Wide, short range: boxes beside and behind the image plane.
            SensorSpec::depth([2.0, 1.0, 1.0], 96, 64, 150.0, 12.0),
            // On a vehicle, which it must not see itself.
            SensorSpec::depth([0.0, 1.0, 0.0], 64, 48, 90.0, 60.0).attached_to(vehicle),
        ];
        for spec in specs {
            let pose = crate::sensors::capture::sensor_pose(&world, &spec).expect("a pose");
            let expected = pipeline_image(&world, &spec, pose);
            let mut slots = vec![MaybeUninit::new(f32::NAN); expected.len()];
            depth_into(&world, &spec, pose, &mut slots);
            // SAFETY: every slot started initialised.
            let image: Vec<f32> = slots.iter().map(|s| unsafe { s.assume_init() }).collect();
            let far = spec.depth_camera().expect("a depth camera").range;
            let hits = expected.iter().filter(|&&d| d < far).count();
            assert!(
                hits > 0 && hits < expected.len(),
                "{:?}: hits and misses: {hits}",
                spec.position
            );
            for (i, (got, want)) in image.iter().zip(&expected).enumerate() {
                assert_eq!(
                    got.to_bits(),
                    want.to_bits(),
                    "{:?}: pixel {i}: {got} against {want}",
                    spec.position
                );
            }
        }
    }
}
