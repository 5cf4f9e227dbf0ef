//! The cameras: one ray per pixel, each cast only against the colliders
//! whose bounds on the image cover that pixel (see `culling`). A cast
//! records what each ray met ([`Hit`]); the depth, RGB, semantic and
//! instance segmentation images are each written from it, so cameras at
//! one pose share one cast.

use std::mem::MaybeUninit;
use std::ops::RangeInclusive;

use rapier3d::prelude::{Pose, RigidBodyHandle, Rotation, Vector};
use rayon::prelude::*;
use shared_types::{ActorKind, Bgra, Camera, LightState, SemanticTag, SensorKind, Sun};

use super::culling::{self, Target, View};
use super::ground::GroundMap;
use super::slab::{Face, Grid, Slab};
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

    /// How far above the image's centre row `v` looks, in pixels.
    fn up(&self, v: usize) -> f32 {
        self.height as f32 / 2.0 - v as f32 - 0.5
    }

    /// How far right of the image's centre column `u` looks, in pixels.
    fn right(&self, u: usize) -> f32 {
        u as f32 + 0.5 - self.width as f32 / 2.0
    }

    /// The unit direction of pixel (u, v)'s ray in the camera frame.
    #[cfg(test)]
    fn direction(&self, u: usize, v: usize) -> Vector {
        Vector::new(self.focal, self.up(v), self.right(u)).normalize()
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

/// What one pixel's ray met: 16 bytes, as every camera at the pose reads
/// every hit (a 24-byte hit cost a millisecond of memory traffic on three
/// 800x600 cameras).
#[derive(Debug, Clone, Copy)]
pub(super) struct Hit {
    /// Along the optical axis (planar depth), metres; infinite where
    /// nothing was met.
    depth: f32,
    /// The actor met (0: none).
    actor: u64,
    /// Its CARLA tag.
    tag: SemanticTag,
    /// Its colour, lit (RGB casts only).
    colour: [u8; 3],
}

const _: () = assert!(std::mem::size_of::<Hit>() == 16);

impl Hit {
    const NOTHING: Hit = Hit {
        depth: f32::INFINITY,
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

/// What a target's surface is: one tag and colour, or the ground's cover
/// where a ray meets it.
#[derive(Debug, Clone, Copy)]
enum Surface {
    Plain(SemanticTag, [u8; 3]),
    Ground,
}

impl Surface {
    fn of(target: &Target) -> Self {
        match target.kind {
            Some(ActorKind::Vehicle) => Self::Plain(SemanticTag::Car, [40, 88, 168]),
            Some(ActorKind::Box) => Self::Plain(SemanticTag::Dynamic, [200, 36, 28]),
            Some(ActorKind::Sphere) => Self::Plain(SemanticTag::Dynamic, [232, 200, 40]),
            Some(ActorKind::Capsule) => Self::Plain(SemanticTag::Dynamic, [64, 168, 96]),
            Some(ActorKind::Walker) => Self::Plain(SemanticTag::Pedestrians, [196, 120, 84]),
            Some(ActorKind::TrafficLight) => {
                let colour = match target.light {
                    Some(LightState::Red) => [230, 32, 32],
                    Some(LightState::Yellow) => [240, 196, 24],
                    Some(LightState::Green) => [32, 208, 72],
                    Some(LightState::Off) | None => [44, 44, 44],
                };
                Self::Plain(SemanticTag::TrafficLight, colour)
            }
            Some(ActorKind::TrafficSign) => Self::Plain(SemanticTag::TrafficSigns, [208, 48, 48]),
            Some(ActorKind::Static) if is_ground(target.extent) => Self::Ground,
            Some(ActorKind::Static) if target.extent[1] >= 2.0 => {
                Self::Plain(SemanticTag::Buildings, [150, 138, 124])
            }
            Some(ActorKind::Static) | None => Self::Plain(SemanticTag::Static, [128, 124, 136]),
        }
    }

    /// Its tag and colour at world point `point`.
    fn at(self, point: Vector, ground: &GroundMap) -> (SemanticTag, [u8; 3]) {
        match self {
            Self::Plain(tag, colour) => (tag, colour),
            Self::Ground => {
                let cover = ground.at(point.x, point.z);
                (cover.tag(), cover.colour())
            }
        }
    }
}

/// What `target` is at world point `point`: its tag and its colour.
pub(super) fn surface(
    target: &Target,
    point: Vector,
    ground: &GroundMap,
) -> (SemanticTag, [u8; 3]) {
    Surface::of(target).at(point, ground)
}

/// How bright daylight is: full with the sun over 10° up, a night's 0.15
/// with it over 10° down.
fn daylight(sun: &Sun) -> f32 {
    0.15 + 0.85 * ((sun.elevation() + 10.0) / 20.0).clamp(0.0, 1.0)
}

/// The light on a surface of unit normal `normal` (turned to the viewer):
/// Lambert, the sun over an ambient light, scaled by `daylight`.
fn lambert(normal: Vector, towards_sun: Vector, daylight: f32) -> f32 {
    daylight * (0.35 + 0.65 * normal.dot(towards_sun).max(0.0))
}

/// `colour` in `light` (at most 1), in 1/256ths: no float-to-byte
/// conversion per channel.
fn shade(colour: [u8; 3], light: f32) -> [u8; 3] {
    let light = (light.clamp(0.0, 1.0) * 256.0) as u32;
    colour.map(|c| ((u32::from(c) * light) >> 8).min(255) as u8)
}

/// The sky's colours by height: a gradient from the horizon up, in
/// [`Sky::STEPS`] steps of a ray's upward component, worked out once per
/// cast (a square root and three conversions per sky pixel were a tenth of
/// an RGB camera's time).
struct Sky([[u8; 3]; Sky::STEPS + 1]);

impl Sky {
    const STEPS: usize = 1024;

    /// The sky in `daylight`.
    fn new(daylight: f32) -> Self {
        let (horizon, zenith) = ([206.0, 222.0, 236.0], [72.0, 124.0, 200.0]);
        Self(std::array::from_fn(|step| {
            let up = (step as f32 / Self::STEPS as f32).sqrt();
            // Within 0..=255: daylight is at most 1.
            std::array::from_fn(|i| {
                ((horizon[i] + (zenith[i] - horizon[i]) * up) * daylight) as i32 as u8
            })
        }))
    }

    /// Its colour along unit world direction `d`.
    fn along(&self, d: Vector) -> [u8; 3] {
        self.0[(d.y.clamp(0.0, 1.0) * Self::STEPS as f32) as usize]
    }
}

/// A target in a camera's image, made ready for its rays: where on the
/// image, its slab test if it is a box, its surface, and each face's light.
struct InView<'t, 'a> {
    target: &'t Target<'a>,
    columns: RangeInclusive<usize>,
    rows: RangeInclusive<usize>,
    slab: Option<Slab>,
    surface: Surface,
    /// A box's faces' light, by [`Face`] + 3 (lit casts only).
    light: [f32; 7],
}

/// The light and sun of a lit cast.
#[derive(Debug, Clone, Copy)]
struct Lighting {
    towards_sun: Vector,
    daylight: f32,
}

impl<'t, 'a> InView<'t, 'a> {
    fn new(
        target: &'t Target<'a>,
        camera: &Intrinsics,
        rotation: Rotation,
        lighting: Option<Lighting>,
    ) -> Option<Self> {
        let (columns, rows) = camera.pixels(target)?;
        let slab = target.slab(rotation, camera.focal);
        let mut light = [0.0; 7];
        if let (Some(l), Some(_)) = (lighting, slab) {
            for (face, light) in (-3..=3).zip(&mut light) {
                *light = lambert(target.face_normal(face), l.towards_sun, l.daylight);
            }
        }
        Some(Self {
            target,
            columns,
            rows,
            slab,
            surface: Surface::of(target),
            light,
        })
    }

    /// Where the ray `right` of the centre of the row whose vector in this
    /// box's frame is `row` (unused for other shapes) meets this target
    /// within `nearest`: the distance and, for a box, the face. `unit` is
    /// the ray's world direction and `length` its unnormalised length.
    fn meet(
        &self,
        (row, right): (Vector, f32),
        (unit, length): (Vector, f32),
        nearest: f32,
    ) -> Option<(f32, Option<Face>)> {
        match &self.slab {
            Some(slab) => slab
                .cast(slab.grid.ray(row, right), nearest / length)
                .map(|(time, face)| (time * length, Some(face))),
            None => self.target.distance(unit, nearest).map(|d| (d, None)),
        }
    }
}

/// Ray-casts one [`Hit`] per pixel into `hits` (grown to width × height),
/// rows in parallel. The rays are the camera's grid (see `slab`); a box
/// is met by the slab test, any other shape by parry's cast.
pub(super) fn cast(
    world: &World,
    spec: &CastSpec,
    pose: Pose,
    ground: &GroundMap,
    hits: &mut Vec<Hit>,
) {
    let camera = spec.intrinsics;
    // Every hit is written below: the buffer is only made, not cleared.
    if hits.len() != camera.width * camera.height {
        hits.clear();
        hits.resize(camera.width * camera.height, Hit::NOTHING);
    }
    cast_into(world, spec, pose, ground, hits, |slot, hit| *slot = hit);
}

/// A depth camera's image cast straight into `slots` (width × height,
/// planar depth, `far` where nothing was met), when no other camera reads
/// its cast: no [`Hit`] buffer and no second pass, so an image touches
/// its own memory only (a 2048x1024 image went through 32 MiB of hits).
pub(super) fn cast_depth(
    world: &World,
    spec: &CastSpec,
    pose: Pose,
    ground: &GroundMap,
    slots: &mut [MaybeUninit<f32>],
) {
    let far = spec.far;
    cast_into(world, spec, pose, ground, slots, |slot, hit| {
        slot.write(hit.depth.min(far));
    });
}

/// Ray-casts one [`Hit`] per pixel of the first width × height of `out`,
/// rows in parallel, and hands each to `write` with its pixel.
fn cast_into<T: Send>(
    world: &World,
    spec: &CastSpec,
    pose: Pose,
    ground: &GroundMap,
    out: &mut [T],
    write: impl Fn(&mut T, Hit) + Sync,
) {
    let camera = spec.intrinsics;
    if camera.width == 0 || camera.height == 0 {
        return;
    }
    let out = &mut out[..camera.width * camera.height];
    let targets = culling::targets(world, &camera.view(), &pose, spec.far, spec.exclude);
    let sun = world.sun;
    let lighting = spec.lit.then(|| Lighting {
        towards_sun: Vector::from_array(sun.direction()),
        daylight: daylight(&sun),
    });
    // Infinite bounds saturate to the whole image.
    let in_view: Vec<_> = targets
        .iter()
        .filter_map(|t| InView::new(t, &camera, pose.rotation, lighting))
        .collect();
    let rays = Grid::new(pose.rotation, camera.focal);
    let sky = lighting.map(|l| Sky::new(l.daylight));
    out.par_chunks_mut(camera.width)
        .enumerate()
        .for_each_init(Vec::new, |row_view, (v, row)| {
            let up = camera.up(v);
            row_view.clear();
            row_view.extend(in_view.iter().filter(|t| t.rows.contains(&v)).map(|t| {
                let row = t.slab.map_or(Vector::ZERO, |s| s.grid.row(up));
                (t, row)
            }));
            let world_row = rays.row(up);
            for (u, slot) in row.iter_mut().enumerate() {
                let right = camera.right(u);
                let length = (camera.focal * camera.focal + up * up + right * right).sqrt();
                let unit = rays.ray(world_row, right) * length.recip();
                let mut nearest = spec.far;
                let mut met = None;
                for (t, local_row) in row_view.iter().filter(|(t, _)| t.columns.contains(&u)) {
                    if let Some((distance, face)) =
                        t.meet((*local_row, right), (unit, length), nearest)
                    {
                        if distance < nearest || met.is_none() {
                            met = Some((*t, face));
                        }
                        nearest = nearest.min(distance);
                    }
                }
                let Some((t, face)) = met.filter(|_| nearest < spec.far) else {
                    let mut hit = Hit::NOTHING;
                    if let Some(sky) = &sky {
                        hit.colour = sky.along(unit);
                    }
                    write(slot, hit);
                    continue;
                };
                let distance = nearest;
                let point = pose.translation + unit * distance;
                let (tag, colour) = t.surface.at(point, ground);
                let mut hit = Hit {
                    depth: distance / length * camera.focal,
                    actor: t.target.actor,
                    tag,
                    colour,
                };
                if let Some(l) = lighting {
                    let light = match face {
                        Some(face) if face != 0 => t.light[(face + 3) as usize],
                        // Another shape, or a box the camera is in: the
                        // face turned to the camera.
                        _ => {
                            let normal = t.target.normal(unit, distance).unwrap_or(-unit);
                            let normal = if normal.dot(unit) > 0.0 {
                                -normal
                            } else {
                                normal
                            };
                            lambert(normal, l.towards_sun, l.daylight)
                        }
                    };
                    hit.colour = shade(colour, light);
                }
                write(slot, hit);
            }
        });
}

/// The planar depth image of `hits` for a depth camera of range `far`
/// (`far` where nothing was met).
pub(super) fn depth_from(hits: &[Hit], far: f32, slots: &mut [MaybeUninit<f32>]) {
    slots
        .par_chunks_mut(4096)
        .zip(hits.par_chunks(4096))
        .for_each(|(slots, hits)| {
            for (slot, hit) in slots.iter_mut().zip(hits) {
                slot.write(hit.depth.min(far));
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
    depth_from(&hits, params.range, slots);
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
    fn the_culled_camera_sees_what_the_query_pipeline_sees() {
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
            // The same pixels meet something, at the same depth to within
            // rounding (the camera's rays are added up, the pipeline's
            // rotated one by one).
            for (i, (got, want)) in image.iter().zip(&expected).enumerate() {
                assert!(
                    (got - want).abs() <= 2e-6 * want,
                    "{:?}: pixel {i}: {got} against {want}",
                    spec.position
                );
            }
        }
    }

    #[test]
    fn a_depth_camera_cast_alone_is_the_same_bits_as_through_the_hits() {
        let (world, vehicle) = super::super::default_world_in_motion();
        let ground = GroundMap::paint(&shared_types::roads::RoadNetwork::new("none"));
        for spec in [
            SensorSpec::depth([-4.0, 3.0, 0.0], 160, 120, 90.0, 100.0),
            SensorSpec::depth([0.0, 1.0, 0.0], 64, 48, 90.0, 60.0).attached_to(vehicle),
        ] {
            let pose = crate::sensors::capture::sensor_pose(&world, &spec).expect("a pose");
            let params = spec.camera().expect("a depth camera");
            let mut through_hits = vec![MaybeUninit::new(f32::NAN); 160 * 120];
            depth_into(&world, &spec, pose, &mut through_hits);
            let cast_spec = CastSpec {
                intrinsics: Intrinsics::of(&params),
                far: params.range,
                exclude: world.body_of(spec.attach_to),
                lit: false,
            };
            let mut alone = vec![MaybeUninit::new(f32::NAN); 160 * 120];
            cast_depth(&world, &cast_spec, pose, &ground, &mut alone);
            let pixels = (params.width * params.height) as usize;
            let bits = |slots: &[MaybeUninit<f32>]| -> Vec<u32> {
                slots
                    .iter()
                    // SAFETY: every slot started initialised.
                    .map(|s| unsafe { s.assume_init() }.to_bits())
                    .collect()
            };
            assert_eq!(bits(&alone[..pixels]), bits(&through_hits[..pixels]));
            // Nothing past the image is written.
            assert!(bits(&alone[pixels..])
                .iter()
                .all(|&b| b == f32::NAN.to_bits()));
        }
    }
}
