//! What sensors see: ray casting the rapier world for the depth camera and
//! the lidar, and the IMU's specific force. Each writes straight into the
//! loaned shared-memory sample it is given.

use std::mem::MaybeUninit;

use rapier3d::prelude::{Pose, Rotation, Vector};
use rayon::prelude::*;
use shared_types::{ImuMeasurement, LidarPoint, SensorSpec};

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

/// Ray-casts one planar depth per pixel straight into `slots`.
pub(super) fn depth_into(
    world: &World,
    spec: &SensorSpec,
    pose: Pose,
    slots: &mut [MaybeUninit<f32>],
) {
    let [w, h, fov, far, ..] = spec.params;
    let (width, height) = (w as usize, h as usize);
    let focal = (w / 2.0) / (fov.to_radians() / 2.0).tan();
    let exclude = world.body_of(spec.attach_to);
    // Rows in parallel, each written in place into the shared-memory sample.
    slots
        .par_chunks_mut(width)
        .take(height)
        .enumerate()
        .for_each(|(v, row)| {
            let up = h / 2.0 - v as f32 - 0.5;
            for (u, slot) in row.iter_mut().enumerate() {
                let right = u as f32 + 0.5 - w / 2.0;
                let direction = Vector::new(focal, up, right).normalize();
                let distance =
                    world.cast_ray(pose.translation, pose.rotation * direction, far, exclude);
                // Planar depth: distance along the optical axis (+X).
                slot.write(distance.map_or(far, |d| d * direction.x));
            }
        });
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
    let per_channel = spec.params[1] as usize;
    let frequency = f64::from(spec.params[5]);
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

/// Ray-casts `channels` × `sweep.columns` rays; writes the returns first,
/// then zeros. Returns how many returns there are.
pub(super) fn lidar_into(
    world: &World,
    spec: &SensorSpec,
    pose: Pose,
    sweep: Sweep,
    slots: &mut [MaybeUninit<LidarPoint>],
) -> usize {
    let [channels, _, range, upper, lower, ..] = spec.params;
    let (channels, per_channel) = (channels as usize, sweep.per_channel);
    let exclude = world.body_of(spec.attach_to);
    let mut hits = 0;
    for c in 0..channels {
        let elevation = if channels > 1 {
            upper - (upper - lower) * c as f32 / (channels - 1) as f32
        } else {
            upper
        }
        .to_radians();
        for column in sweep.start..sweep.start + sweep.columns {
            let i = column % per_channel;
            let azimuth = std::f32::consts::TAU * i as f32 / per_channel as f32;
            let direction = Vector::new(
                elevation.cos() * azimuth.cos(),
                elevation.sin(),
                elevation.cos() * azimuth.sin(),
            );
            if let Some(distance) =
                world.cast_ray(pose.translation, pose.rotation * direction, range, exclude)
            {
                let point = direction * distance;
                slots[hits].write(LidarPoint {
                    x: point.x,
                    y: point.y,
                    z: point.z,
                    intensity: 1.0 - distance / range,
                });
                hits += 1;
            }
        }
    }
    for slot in &mut slots[hits..] {
        slot.write(LidarPoint::default());
    }
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
}
