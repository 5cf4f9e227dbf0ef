//! What sensors see: the lidar's ray casts (the depth camera's are in
//! `camera`), and the IMU's specific force. Each writes straight into the
//! loaned shared-memory sample it is given.

use std::mem::MaybeUninit;

use rapier3d::prelude::{Pose, Rotation, Vector};
use rayon::prelude::*;
use shared_types::{ImuMeasurement, LidarPoint, SensorSpec};

use super::culling;
use super::lidar_noise::Effects;
use crate::world::World;

/// `q` as a unit rotation; all zeros means identity.
fn rotation_of(q: [f32; 4]) -> Rotation {
    if q == [0.0; 4] {
        Rotation::IDENTITY
    } else {
        Rotation::from_xyzw(q[0], q[1], q[2], q[3]).normalize()
    }
}

/// The sensor's pose in the world: its parent's pose (or the origin) times
/// its relative pose.
pub(super) fn sensor_pose(world: &World, spec: &SensorSpec) -> Option<Pose> {
    let relative = Pose::from_parts(
        Vector::from_array(spec.position),
        rotation_of(spec.rotation),
    );
    if spec.attach_to == 0 {
        return Some(relative);
    }
    let parent = world.pose_of(spec.attach_to)?;
    Some(parent * relative)
}

/// The part of a lidar turn one capture covers: `columns` azimuth steps from
/// `start`, of `per_channel` in a full turn.
#[derive(Debug, Clone, Copy, PartialEq)]
pub(super) struct Sweep {
    pub(super) start: usize,
    pub(super) columns: usize,
    pub(super) per_channel: usize,
}

/// A lidar spinning at `rotation_frequency` Hz covers `frequency × Δt` of a
/// turn per capture (CARLA's partial scans); 0 Hz is a full turn every capture.
pub(super) fn lidar_sweep(spec: &SensorSpec, start: usize, since_last_ns: u64) -> Sweep {
    let lidar = spec.lidar_params();
    let per_channel = lidar.map_or(0, |l| l.points as usize);
    let frequency = lidar.map_or(0.0, |l| f64::from(l.rotation_hz));
    let columns = if frequency > 0.0 {
        let turns = frequency * since_last_ns as f64 * 1e-9;
        ((turns * per_channel as f64).round() as usize).clamp(1, per_channel)
    } else {
        per_channel
    };
    Sweep {
        start: start % per_channel.max(1),
        columns,
        per_channel,
    }
}

/// A lidar's ray directions in its own frame, channel by channel, one per
/// azimuth step of a full turn: the trigonometry done once, at spawn.
#[derive(Debug, Default)]
pub(super) struct LidarRays {
    per_channel: usize,
    directions: Vec<Vector>,
    /// Each direction's cube face and place on it (`culling::cube_face`).
    faces: Vec<(u8, f32, f32)>,
    /// Returns per channel of the last capture (kept: no allocation per frame).
    counts: Vec<usize>,
}

impl LidarRays {
    /// The directions of `spec` (channels × points per channel).
    pub(super) fn new(spec: &SensorSpec) -> Self {
        let Some(lidar) = spec.lidar_params() else {
            return Self::default();
        };
        let (upper, lower) = (lidar.upper_fov, lidar.lower_fov);
        let (channels, per_channel) = (lidar.channels as usize, lidar.points as usize);
        let azimuths: Vec<(f32, f32)> = (0..per_channel)
            .map(|i| (std::f32::consts::TAU * i as f32 / per_channel as f32).sin_cos())
            .collect();
        let mut directions = Vec::with_capacity(channels * per_channel);
        for c in 0..channels {
            let elevation = if channels > 1 {
                upper - (upper - lower) * c as f32 / (channels - 1) as f32
            } else {
                upper
            }
            .to_radians();
            let (sin_e, cos_e) = elevation.sin_cos();
            directions.extend(
                azimuths
                    .iter()
                    .map(|&(sin_a, cos_a)| Vector::new(cos_e * cos_a, sin_e, cos_e * sin_a)),
            );
        }
        Self {
            per_channel,
            faces: directions.iter().map(|&d| culling::cube_face(d)).collect(),
            directions,
            counts: Vec::with_capacity(channels),
        }
    }
}

/// What one lidar ray met: the direction in the sensor's frame and the
/// world's, how far along it (its noise added), the target, and the
/// return's intensity.
pub(super) struct Return<'t, 'a> {
    /// Unit direction, sensor frame.
    pub(super) local: Vector,
    /// Unit direction, world frame.
    pub(super) direction: Vector,
    pub(super) distance: f32,
    pub(super) target: &'t culling::Target<'a>,
    pub(super) intensity: f32,
}

/// A plain lidar's point for `hit`.
pub(super) fn lidar_point(hit: &Return) -> LidarPoint {
    let point = hit.local * hit.distance;
    LidarPoint {
        x: point.x,
        y: point.y,
        z: point.z,
        intensity: hit.intensity,
    }
}

/// Ray-casts `channels` × `sweep.columns` rays of capture number
/// `capture`, channels in parallel, each writing its returns (`point` of
/// each hit, its noise and drop-off applied: `lidar_noise`) at the start of
/// its own stretch of the sample; the stretches are then closed up in
/// channel order (the same points, in the same order, as one thread would
/// write), and the rest zeroed. Returns how many returns there are.
pub(super) fn lidar_into<T: Copy + Default + Send>(
    world: &World,
    spec: &SensorSpec,
    rays: &mut LidarRays,
    (pose, sweep, capture): (Pose, Sweep, u64),
    slots: &mut [MaybeUninit<T>],
    point: impl Fn(&Return) -> T + Sync,
) -> usize {
    let Some(lidar) = spec.lidar_params() else {
        slots.fill(MaybeUninit::new(T::default()));
        return 0;
    };
    let range = lidar.range;
    let effects = Effects::new(lidar.noise, range, capture);
    let per_channel = sweep.per_channel;
    let exclude = world.body_of(spec.attach_to);
    let columns = sweep.columns.min(per_channel);
    if columns == 0 || rays.per_channel != per_channel {
        slots.fill(MaybeUninit::new(T::default()));
        return 0;
    }
    let channels = (rays.directions.len() / per_channel).min(slots.len() / columns);
    // Each channel's returns, at the start of its `columns` slots.
    let LidarRays {
        directions,
        faces,
        counts,
        ..
    } = rays;
    let cube = culling::Cube::new(world, &pose, range, exclude);
    counts.clear();
    counts.par_extend(
        slots[..channels * columns]
            .par_chunks_mut(columns)
            .zip(directions.par_chunks(per_channel))
            .zip(faces.par_chunks(per_channel))
            .enumerate()
            .map(|(channel, ((stretch, directions), faces))| {
                let mut hits = 0;
                for column in sweep.start..sweep.start + columns {
                    let column = column % per_channel;
                    let ray = (channel, column);
                    if effects.drops_ray(ray) {
                        continue;
                    }
                    let (local, face) = (directions[column], faces[column]);
                    let direction = pose.rotation * local;
                    let Some((distance, target)) =
                        culling::nearest_target(cube.along(face), direction, range)
                    else {
                        continue;
                    };
                    let intensity = effects.intensity(distance);
                    if !effects.keeps(ray, intensity) {
                        continue;
                    }
                    let hit = Return {
                        local,
                        direction,
                        distance: (distance + effects.error(ray)).max(0.0),
                        target,
                        intensity,
                    };
                    stretch[hits].write(point(&hit));
                    hits += 1;
                }
                hits
            }),
    );
    let mut hits = 0;
    for (c, &count) in counts.iter().enumerate() {
        let from = c * columns;
        slots.copy_within(from..from + count, hits);
        hits += count;
    }
    slots[hits..].fill(MaybeUninit::new(T::default()));
    hits
}

/// Specific force and angular velocity of the parent, in the sensor frame.
pub(super) fn imu(world: &World, spec: &SensorSpec, pose: Pose) -> ImuMeasurement {
    let (acceleration, angular_velocity) = world.motion_of(spec.attach_to).unwrap_or_default();
    let gravity = Vector::new(0.0, -9.81, 0.0);
    let inverse = pose.rotation.inverse();
    ImuMeasurement {
        accelerometer: (inverse * (acceleration - gravity)).to_array(),
        gyroscope: (inverse * angular_velocity).to_array(),
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_spinning_lidar_covers_frequency_times_dt_of_a_turn() {
        let spec = SensorSpec::lidar([0.0; 3], 4, 1000, 50.0, 10.0, -10.0).rotating(10.0);
        // 10 Hz over 20 ms: a fifth of the turn.
        let sweep = lidar_sweep(&spec, 0, 20_000_000);
        assert_eq!((sweep.start, sweep.columns), (0, 200));
        let next = lidar_sweep(&spec, 900, 20_000_000);
        assert_eq!(
            (next.start, next.columns),
            (900, 200),
            "wraps around the turn"
        );
        // Never more than a full turn, never nothing.
        assert_eq!(lidar_sweep(&spec, 0, 5_000_000_000).columns, 1000);
        assert_eq!(lidar_sweep(&spec, 0, 1).columns, 1);
        let full = SensorSpec::lidar([0.0; 3], 4, 1000, 50.0, 10.0, -10.0);
        assert_eq!(lidar_sweep(&full, 0, 20_000_000).columns, 1000);
    }

    #[test]
    fn parallel_channels_give_the_points_rapiers_query_would_in_channel_order() {
        let mut world = World::new(&crate::scene::Scene::Default.placements(0), 1);
        let plan =
            crate::clock::SubstepPlan::new(10_000_000, &shared_types::WorldSettings::default());
        // One step puts the colliders in the query structures; more set
        // the sphere rolling and the boxes tumbling.
        world.step(&plan);
        lidar_matches_the_query_pipeline(
            &world,
            SensorSpec::lidar([0.0, 2.0, 0.0], 16, 256, 50.0, 10.0, -30.0),
            200,
            100,
        );
        let (world, vehicle) = super::super::default_world_in_motion();
        // Steep channels (the cube's top and bottom faces too), on a
        // vehicle it must not see, a whole turn; then among the boxes.
        let on_vehicle =
            SensorSpec::lidar([0.0, 1.5, 0.0], 24, 180, 30.0, 70.0, -80.0).attached_to(vehicle);
        lidar_matches_the_query_pipeline(&world, on_vehicle, 0, 180);
        lidar_matches_the_query_pipeline(
            &world,
            SensorSpec::lidar([6.0, 1.0, -1.0], 32, 360, 20.0, 60.0, -60.0),
            90,
            360,
        );
    }

    /// Casts `columns` of `spec`'s turn from `start` and compares every
    /// point, in order, with one ray at a time through rapier's query.
    fn lidar_matches_the_query_pipeline(
        world: &World,
        spec: SensorSpec,
        start: usize,
        columns: usize,
    ) {
        let lidar = spec.lidar_params().expect("a lidar");
        let range = lidar.range;
        let (channels, per_channel) = (lidar.channels as usize, lidar.points as usize);
        let mut rays = LidarRays::new(&spec);
        let pose = sensor_pose(world, &spec).expect("a pose");
        let exclude = world.body_of(spec.attach_to);
        let sweep = Sweep {
            start,
            columns,
            per_channel,
        };
        let mut slots = vec![MaybeUninit::new(LidarPoint::default()); channels * per_channel];
        let hits = lidar_into(
            world,
            &spec,
            &mut rays,
            (pose, sweep, 1),
            &mut slots,
            lidar_point,
        );
        let mut expected = Vec::new();
        for c in 0..channels {
            for column in start..start + columns {
                let direction = rays.directions[c * per_channel + column % per_channel];
                if let Some(d) =
                    world.cast_ray(pose.translation, pose.rotation * direction, range, exclude)
                {
                    expected.push((direction * d, 1.0 - d / range));
                }
            }
        }
        assert!(
            hits > 0 && hits < channels * columns,
            "{:?}: a scene with hits and misses: {hits}",
            spec.position
        );
        assert_eq!(hits, expected.len(), "{:?}", spec.position);
        for (i, slot) in slots.iter().enumerate() {
            // SAFETY: lidar_into initialised every slot (they also started so).
            let point = unsafe { slot.assume_init() };
            match expected.get(i) {
                Some((p, intensity)) => assert_eq!(
                    (point.x, point.y, point.z, point.intensity),
                    (p.x, p.y, p.z, *intensity),
                    "{:?}: point {i}",
                    spec.position
                ),
                None => assert_eq!(point, LidarPoint::default(), "slot {i} after the returns"),
            }
        }
    }
}
