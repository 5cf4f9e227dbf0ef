//! One ray cast per camera pose per frame: depth, RGB, semantic and
//! instance segmentation cameras on the same parent, at the same relative
//! transform, with the same size, field of view and range, read the same
//! [`Hit`]s. The buffers are kept from frame to frame (no allocation once
//! they have grown), and the rays cast are counted for the frame's header.

use rapier3d::prelude::{Pose, RigidBodyHandle};
use shared_types::scene::SceneName;
use shared_types::{SensorKind, SensorSpec};

use super::camera::{self, CastSpec, Hit, Intrinsics};
use super::ground::GroundMap;
use super::renderer::Renderer;
use crate::world::World;

/// What makes two cameras' casts the same: parent, relative pose and
/// every camera parameter, bit for bit.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
struct CastKey {
    attach_to: u64,
    bits: [u32; 15],
}

impl CastKey {
    fn of(spec: &SensorSpec) -> Self {
        let mut bits = [0; 15];
        let values = spec
            .position
            .iter()
            .chain(&spec.rotation)
            .chain(&spec.params);
        for (slot, v) in bits.iter_mut().zip(values) {
            *slot = v.to_bits();
        }
        Self {
            attach_to: spec.attach_to,
            bits,
        }
    }
}

/// The body a camera does not see: its parent when the camera is inside
/// it. A camera sees its parent otherwise, as CARLA's do (a camera behind
/// a car films the car); inside it, faces seen from inside are not drawn.
fn seen_from_inside(world: &World, spec: &SensorSpec, pose: Pose) -> Option<RigidBodyHandle> {
    world
        .body_of(spec.attach_to)
        .filter(|&body| world.body_contains(body, pose.translation))
}

/// One shared cast of this frame.
#[derive(Debug)]
struct Slot {
    key: CastKey,
    /// An RGB camera reads it: colours and light are worked out.
    lit: bool,
    /// The cameras that read it this frame.
    cameras: usize,
    /// Cast this frame already.
    done: bool,
    hits: Vec<Hit>,
}

/// The frame's casts, and the ground they colour.
#[derive(Debug, Default)]
pub(super) struct Casts {
    slots: Vec<Slot>,
    /// Slots planned this frame (the rest keep their buffers for later).
    used: usize,
    /// The painted ground of the scene last seen.
    ground: Option<(SceneName, GroundMap)>,
    /// Rays cast this frame, by every sensor.
    pub(super) rays: u64,
}

impl Casts {
    /// Starts a frame: one slot per distinct pose among `cameras` (each
    /// camera due now, with its kind).
    pub(super) fn plan<'a>(&mut self, cameras: impl Iterator<Item = (&'a SensorSpec, SensorKind)>) {
        self.used = 0;
        self.rays = 0;
        for (spec, kind) in cameras {
            let key = CastKey::of(spec);
            let lit = kind == SensorKind::Rgb;
            if let Some(slot) = self.slots[..self.used].iter_mut().find(|s| s.key == key) {
                slot.lit |= lit;
                slot.cameras += 1;
                continue;
            }
            let slot = Slot {
                key,
                lit,
                cameras: 1,
                done: false,
                hits: Vec::new(),
            };
            match self.slots.get_mut(self.used) {
                Some(old) => {
                    let hits = std::mem::take(&mut old.hits);
                    *old = Slot { hits, ..slot };
                }
                None => self.slots.push(slot),
            }
            self.used += 1;
        }
    }

    /// Paints `scene`'s ground unless it is the one painted.
    fn paint(&mut self, scene: SceneName) {
        if self.ground.as_ref().is_none_or(|(name, _)| *name != scene) {
            let network = shared_types::roads::network(scene);
            self.ground = Some((scene, GroundMap::paint(&network)));
        }
    }

    /// The painted ground of `scene`, what tags the ground a semantic
    /// lidar meets (painted once per scene).
    pub(super) fn ground(&mut self, scene: SceneName) -> &GroundMap {
        self.paint(scene);
        &self.ground.as_ref().expect("painted above").1
    }

    /// Casts depth camera `spec` at `pose` straight into `slots` if no
    /// other camera reads its cast this frame (then no hits are kept);
    /// false, and nothing written, otherwise.
    pub(super) fn depth_alone(
        &mut self,
        (world, scene): (&World, SceneName),
        spec: &SensorSpec,
        pose: Pose,
        renderer: &Renderer,
        slots: &mut [std::mem::MaybeUninit<f32>],
    ) -> bool {
        let key = CastKey::of(spec);
        let Some(index) = self.slots[..self.used].iter().position(|s| s.key == key) else {
            return false;
        };
        let (Some(camera), slot) = (spec.camera(), &self.slots[index]) else {
            return false;
        };
        let pixels = camera.width as usize * camera.height as usize;
        if slot.cameras != 1 || slot.done || slots.len() < pixels {
            return false;
        }
        self.paint(scene);
        let ground = &self.ground.as_ref().expect("painted above").1;
        let cast = CastSpec {
            intrinsics: Intrinsics::of(&camera),
            far: camera.range,
            exclude: seen_from_inside(world, spec, pose),
            lit: false,
        };
        renderer.run(|| camera::cast_depth(world, &cast, pose, ground, slots));
        self.slots[index].done = true;
        self.rays += pixels as u64;
        true
    }

    /// The hits of camera `spec` at `pose`: cast now unless a camera of
    /// the same pose was cast this frame.
    pub(super) fn hits(
        &mut self,
        world: &World,
        scene: SceneName,
        spec: &SensorSpec,
        pose: Pose,
        renderer: &Renderer,
    ) -> &[Hit] {
        let key = CastKey::of(spec);
        let Some(index) = self.slots[..self.used].iter().position(|s| s.key == key) else {
            return &[];
        };
        if !self.slots[index].done {
            self.paint(scene);
            let ground = &self.ground.as_ref().expect("painted above").1;
            let camera = spec.camera().unwrap_or(shared_types::Camera {
                width: 0,
                height: 0,
                fov: 90.0,
                range: 1.0,
            });
            let slot = &mut self.slots[index];
            let cast = CastSpec {
                intrinsics: Intrinsics::of(&camera),
                far: camera.range,
                exclude: seen_from_inside(world, spec, pose),
                lit: slot.lit,
            };
            renderer.run(|| camera::cast(world, &cast, pose, ground, &mut slot.hits));
            slot.done = true;
            self.rays += slot.hits.len() as u64;
        }
        &self.slots[index].hits
    }
}
