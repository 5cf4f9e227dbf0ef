//! The cameras: one ray per pixel, each cast only against the colliders
//! whose bounds on the image cover that pixel (see `culling`). A cast
//! records what each ray met ([`Hit`]); the depth, RGB, semantic and
//! instance segmentation images are each written from it, so cameras at
//! one pose share one cast.

use std::mem::MaybeUninit;
use std::ops::RangeInclusive;

use rapier3d::prelude::{Pose, RigidBodyHandle, Vector};
use rayon::prelude::*;
use shared_types::{ActorKind, Bgra, Camera, SemanticTag, SensorKind, Sun};

use super::culling::{self, Target, View};
use super::ground::GroundMap;
use crate::world::World;

/// The camera's intrinsics: image size and focal length in pixels. Pixel
/// (u, v) looks along (focal, h/2 − v − ½, u + ½ − w/2) in the camera frame
/// (+X forward, +Y up, +Z right).
#[derive(Debug, Clone, Copy)]
pub(super) struct Intrinsics {
    width: usize,
    height: usize,
    focal: f32,
}

impl Intrinsics {
    pub(super) fn of(camera: &Camera) -> Self {
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

/// What one pixel's ray met.
#[derive(Debug, Clone, Copy)]
pub(super) struct Hit {
    /// Along the ray, metres; infinite where nothing was met.
    distance: f32,
    /// The actor met (0: none).
    actor: u64,
    /// Its CARLA tag.
    tag: SemanticTag,
    /// Its colour, lit (RGB casts only).
    colour: [u8; 3],
}

impl Hit {
    const NOTHING: Hit = Hit {
        distance: f32::INFINITY,
        actor: 0,
        tag: SemanticTag::Sky,
        colour: [0; 3],
    };
}

/// What a cast is for.
#[derive(Debug, Clone, Copy)]
pub(super) struct CastSpec {
    pub(super) intrinsics: Intrinsics,
    /// The cameras' range (cameras of different ranges cast apart).
    pub(super) far: f32,
    /// The body not seen (the parent of cameras inside it).
    pub(super) exclude: Option<RigidBodyHandle>,
    /// Whether an RGB camera shares it (colours and light are worked out).
    pub(super) lit: bool,
}

/// Whether a static body is a ground: flat and wide (the scenes' grounds
/// are 1 m thick slabs at least 20 m across).
fn is_ground(extent: [f32; 3]) -> bool {
    extent[1] <= 0.5 + 1e-3 && extent[0] >= 20.0 && extent[2] >= 20.0
}

/// What `target` is at world point `point`: its tag and its colour.
pub(super) fn surface(
    target: &Target,
    point: Vector,
    ground: &GroundMap,
) -> (SemanticTag, [u8; 3]) {
    match target.kind {
        Some(ActorKind::Vehicle) => (SemanticTag::Car, [40, 88, 168]),
        Some(ActorKind::Box) => (SemanticTag::Dynamic, [200, 36, 28]),
        Some(ActorKind::Sphere) => (SemanticTag::Dynamic, [232, 200, 40]),
        Some(ActorKind::Capsule) => (SemanticTag::Dynamic, [64, 168, 96]),
        Some(ActorKind::Static) if is_ground(target.extent) => {
            let cover = ground.at(point.x, point.z);
            (cover.tag(), cover.colour())
        }
        Some(ActorKind::Static) if target.extent[1] >= 2.0 => {
            (SemanticTag::Buildings, [150, 138, 124])
        }
        Some(ActorKind::Static) | None => (SemanticTag::Static, [128, 124, 136]),
    }
}

/// How bright daylight is: full with the sun over 10° up, a night's 0.15
/// with it over 10° down.
fn daylight(sun: &Sun) -> f32 {
    0.15 + 0.85 * ((sun.elevation() + 10.0) / 20.0).clamp(0.0, 1.0)
}

/// The sky's colour along world direction `d`: a gradient from the
/// horizon up.
/// `light` is the sun's [`daylight`] (worked out once per cast, not per
/// pixel: it takes an arcsine).
fn sky(d: Vector, light: f32) -> [u8; 3] {
    let (horizon, zenith) = ([206.0, 222.0, 236.0], [72.0, 124.0, 200.0]);
    let up = d.y.clamp(0.0, 1.0).sqrt();
    std::array::from_fn(|i| ((horizon[i] + (zenith[i] - horizon[i]) * up) * light) as u8)
}

/// Ray-casts one [`Hit`] per pixel into `hits` (grown to width × height),
/// rows in parallel.
pub(super) fn cast(
    world: &World,
    spec: &CastSpec,
    pose: Pose,
    ground: &GroundMap,
    hits: &mut Vec<Hit>,
) {
    let camera = spec.intrinsics;
    hits.clear();
    hits.resize(camera.width * camera.height, Hit::NOTHING);
    if camera.width == 0 || camera.height == 0 {
        return;
    }
    let targets = culling::targets(world, &camera.view(), &pose, spec.far, spec.exclude);
    // Infinite bounds saturate to the whole image.
    let in_view: Vec<_> = targets
        .iter()
        .filter_map(|t| Some((t, camera.pixels(t)?)))
        .collect();
    let sun = world.sun;
    let towards_sun = Vector::from_array(sun.direction());
    let light = daylight(&sun);
    hits.par_chunks_mut(camera.width)
        .enumerate()
        .for_each_init(Vec::new, |row_view, (v, row)| {
            row_view.clear();
            row_view.extend(
                in_view
                    .iter()
                    .filter(|(_, (_, rows))| rows.contains(&v))
                    .map(|(t, (columns, _))| (*t, columns)),
            );
            for (u, hit) in row.iter_mut().enumerate() {
                let direction = pose.rotation * camera.direction(u, v);
                let seen = row_view
                    .iter()
                    .filter(|(_, columns)| columns.contains(&u))
                    .map(|(t, _)| *t);
                let Some((distance, target)) = culling::nearest_target(seen, direction, spec.far)
                else {
                    if spec.lit {
                        hit.colour = sky(direction, light);
                    }
                    continue;
                };
                let point = pose.translation + direction * distance;
                let (tag, colour) = surface(target, point, ground);
                *hit = Hit {
                    distance,
                    actor: target.actor,
                    tag,
                    colour,
                };
                if spec.lit {
                    // Lambert: the face turned to the camera, lit by the sun
                    // over an ambient light.
                    let normal = target.normal(direction, distance).unwrap_or(-direction);
                    let normal = if normal.dot(direction) > 0.0 {
                        -normal
                    } else {
                        normal
                    };
                    let lambert = light * (0.35 + 0.65 * normal.dot(towards_sun).max(0.0));
                    hit.colour = colour.map(|c| (f32::from(c) * lambert).min(255.0) as u8);
                }
            }
        });
}

/// The planar depth image of `hits` for a depth camera of range `far`
/// (`far` where nothing was met).
pub(super) fn depth_from(
    hits: &[Hit],
    camera: &Intrinsics,
    far: f32,
    slots: &mut [MaybeUninit<f32>],
) {
    slots
        .par_chunks_mut(camera.width.max(1))
        .zip(hits.par_chunks(camera.width.max(1)))
        .enumerate()
        .for_each(|(v, (row, hits))| {
            for (u, (slot, hit)) in row.iter_mut().zip(hits).enumerate() {
                // Planar depth: distance along the optical axis (+X).
                slot.write(if hit.distance < far {
                    hit.distance * camera.direction(u, v).x
                } else {
                    far
                });
            }
        });
}

/// The image of `kind` (RGB, semantic or instance) of `hits`.
pub(super) fn image_from(kind: SensorKind, hits: &[Hit], slots: &mut [MaybeUninit<Bgra>]) {
    slots
        .par_chunks_mut(4096)
        .zip(hits.par_chunks(4096))
        .for_each(|(slots, hits)| {
            for (slot, hit) in slots.iter_mut().zip(hits) {
                let [r, g, b] = hit.colour;
                slot.write(match kind {
                    SensorKind::Semantic => Bgra::semantic(hit.tag),
                    SensorKind::Instance => Bgra::instance(hit.tag, hit.actor),
                    _ => Bgra::rgb(r, g, b),
                });
            }
        });
}

/// A depth camera's image, cast for it alone (what a camera of its own
/// pose costs).
#[cfg(test)]
pub(super) fn depth_into(
    world: &World,
    spec: &shared_types::SensorSpec,
    pose: Pose,
    slots: &mut [MaybeUninit<f32>],
) {
    let params = spec.camera().expect("a camera");
    let cast_spec = CastSpec {
        intrinsics: Intrinsics::of(&params),
        far: params.range,
        exclude: world.body_of(spec.attach_to),
        lit: false,
    };
    let mut hits = Vec::new();
    let ground = GroundMap::paint(&shared_types::roads::RoadNetwork::new("none"));
    cast(world, &cast_spec, pose, &ground, &mut hits);
    depth_from(&hits, &cast_spec.intrinsics, params.range, slots);
}

#[cfg(test)]
mod tests {
    use super::*;
    use shared_types::SensorSpec;

    /// The image rapier's query pipeline gives, one ray at a time.
    fn pipeline_image(world: &World, spec: &SensorSpec, pose: Pose) -> Vec<f32> {
        let params = spec.camera().expect("a depth camera");
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
            // On a vehicle, left out of the cast (as a lidar leaves out its
            // parent, and a camera the parent it sits inside).
            SensorSpec::depth([0.0, 1.0, 0.0], 64, 48, 90.0, 60.0).attached_to(vehicle),
        ];
        for spec in specs {
            let pose = crate::sensors::capture::sensor_pose(&world, &spec).expect("a pose");
            let expected = pipeline_image(&world, &spec, pose);
            let mut slots = vec![MaybeUninit::new(f32::NAN); expected.len()];
            depth_into(&world, &spec, pose, &mut slots);
            // SAFETY: every slot started initialised.
            let image: Vec<f32> = slots.iter().map(|s| unsafe { s.assume_init() }).collect();
            let far = spec.camera().expect("a depth camera").range;
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
