//! Sensors: a depth camera and a lidar that ray-cast the rapier world, and an
//! IMU. Each writes its capture **directly into the loaned shared-memory
//! sample** of its own iceoryx2 service — no intermediate buffer, no copy.

use std::mem::MaybeUninit;

use rayon::prelude::*;

use iceoryx2::port::publisher::Publisher;
use iceoryx2::prelude::*;
use rapier3d::prelude::{Pose, Rotation, Vector};
use shared_types::limits::SENSOR_SUBSCRIBER_BUFFER;
use shared_types::{
    seconds_to_nanos, ImuMeasurement, LidarPoint, SensorEnd, SensorHeader, SensorInfo, SensorKind,
    SensorSpec, ServiceNames,
};
use tracing::{debug, info, warn};

use crate::world::World;
use crate::ServerError;

type Port<T> = Publisher<ipc::Service, [T], SensorHeader>;

/// A sensor's publisher, typed by what it captures.
enum SensorPort {
    Depth(Port<f32>),
    Lidar(Port<LidarPoint>),
    Imu(Port<ImuMeasurement>),
}

/// One sensor.
struct Sensor {
    id: u64,
    spec: SensorSpec,
    port: SensorPort,
    /// Simulation time of the next capture, in nanoseconds.
    next_capture_ns: u64,
    /// Simulation time of the previous capture (or the spawn).
    last_capture_ns: u64,
    /// Lidar: the column (azimuth step) the next sweep starts at.
    lidar_column: usize,
    captures: u64,
}

/// Why a sensor could not be spawned (index into `shared_types::SENSOR_ERRORS`).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum SpawnRefusal {
    /// The spec breaks a rule.
    InvalidSpec = 1,
    /// `attach_to` names no actor.
    UnknownActor = 2,
    /// The shared memory for its captures could not be had.
    NoMemory = 4,
}

/// Every sensor of a world.
pub struct Sensors {
    list: Vec<Sensor>,
    next_id: u64,
    /// Readers each sensor admits (`--max-sensor-readers`).
    max_readers: usize,
}

fn open_port<T: std::fmt::Debug + ZeroCopySend + 'static>(
    node: &Node<ipc::Service>,
    name: &str,
    elements: usize,
    max_readers: usize,
) -> Result<Port<T>, ServerError> {
    let name =
        ServiceName::new(name).map_err(|e| ServerError::transport("sensor service name", e))?;
    node.service_builder(&name)
        .publish_subscribe::<[T]>()
        .user_header::<SensorHeader>()
        .max_publishers(1)
        .max_subscribers(max_readers)
        .subscriber_max_buffer_size(SENSOR_SUBSCRIBER_BUFFER)
        .subscriber_max_borrowed_samples(2)
        .history_size(0)
        .enable_safe_overflow(true)
        .max_nodes(max_readers + 16)
        .payload_alignment(Alignment::new(16).expect("16 is a power of two"))
        .open_or_create()
        .map_err(|e| ServerError::transport("sensor service", e))?
        .publisher_builder()
        .initial_max_slice_len(elements)
        .max_loaned_samples(1)
        .create()
        .map_err(|e| ServerError::transport("sensor publisher", e))
}

fn rotation_of(q: [f32; 4]) -> Rotation {
    if q == [0.0; 4] {
        Rotation::IDENTITY
    } else {
        Rotation::from_xyzw(q[0], q[1], q[2], q[3]).normalize()
    }
}

impl Sensors {
    /// No sensors yet; each will admit `max_readers` readers.
    pub fn new(max_readers: usize) -> Self {
        Self {
            list: Vec::new(),
            next_id: 0,
            max_readers,
        }
    }

    /// Builds a sensor from `spec` and opens its service.
    pub fn spawn(
        &mut self,
        node: &Node<ipc::Service>,
        names: &ServiceNames,
        spec: SensorSpec,
        world: &World,
        now_ns: u64,
    ) -> Result<Result<SensorInfo, SpawnRefusal>, ServerError> {
        let Some(kind) = spec.sensor_kind().filter(|_| spec.check().is_ok()) else {
            return Ok(Err(SpawnRefusal::InvalidSpec));
        };
        if spec.attach_to != 0 && world.body_of(spec.attach_to).is_none() {
            return Ok(Err(SpawnRefusal::UnknownActor));
        }
        let id = self.next_id + 1;
        let name = names.sensor(id);
        let elements = spec.elements();
        let port = match kind {
            SensorKind::Depth => {
                open_port(node, &name, elements, self.max_readers).map(SensorPort::Depth)
            }
            SensorKind::Lidar => {
                open_port(node, &name, elements, self.max_readers).map(SensorPort::Lidar)
            }
            SensorKind::Imu => open_port(node, &name, 1, self.max_readers).map(SensorPort::Imu),
        };
        let port = match port {
            Ok(port) => port,
            Err(e) => {
                warn!(id, "refused a sensor: {e}");
                return Ok(Err(SpawnRefusal::NoMemory));
            }
        };
        self.next_id = id;
        let next_capture_ns = next_capture_after(now_ns, &spec);
        info!(
            id,
            kind = kind.name(),
            attach_to = spec.attach_to,
            elements,
            "sensor spawned"
        );
        let sensor = Sensor {
            id,
            spec,
            port,
            next_capture_ns,
            last_capture_ns: now_ns,
            lidar_column: 0,
            captures: 0,
        };
        let info = sensor.info();
        self.list.push(sensor);
        Ok(Ok(info))
    }

    /// Removes sensor `id`, telling its readers; `false` if there is none.
    pub fn destroy(&mut self, id: u64, frame: u64, episode: u64) -> bool {
        let Some(index) = self.list.iter().position(|s| s.id == id) else {
            return false;
        };
        let sensor = self.list.remove(index);
        sensor.end(SensorEnd::Destroyed, frame, episode);
        true
    }

    /// Every sensor.
    pub fn list(&self) -> Vec<SensorInfo> {
        self.list.iter().map(Sensor::info).collect()
    }

    /// Ends the sensors whose parent actor is gone: a sensor dies with the
    /// actor it rides on, as in CARLA.
    pub fn end_orphans(&mut self, world: &World, frame: u64, episode: u64) {
        if !self
            .list
            .iter()
            .any(|s| s.spec.attach_to != 0 && world.body_of(s.spec.attach_to).is_none())
        {
            return;
        }
        let (orphans, living) = std::mem::take(&mut self.list)
            .into_iter()
            .partition(|s| s.spec.attach_to != 0 && world.body_of(s.spec.attach_to).is_none());
        self.list = living;
        for sensor in orphans {
            sensor.end(SensorEnd::ParentDestroyed, frame, episode);
        }
    }

    /// Ends every sensor, telling its readers `reason` (a new episode starts
    /// without sensors; the server stops). Sensor ids are not reused.
    pub fn end_all(&mut self, reason: SensorEnd, frame: u64, episode: u64) {
        for sensor in self.list.drain(..) {
            sensor.end(reason, frame, episode);
        }
    }

    /// Captures and publishes every sensor due at this frame.
    pub fn capture(&mut self, world: &World, frame: u64, elapsed_ns: u64, episode: u64) {
        for sensor in &mut self.list {
            if elapsed_ns < sensor.next_capture_ns {
                continue;
            }
            sensor.next_capture_ns = next_capture_after(elapsed_ns, &sensor.spec);
            let since_last_ns = elapsed_ns - sensor.last_capture_ns.min(elapsed_ns);
            sensor.last_capture_ns = elapsed_ns;
            let Some(pose) = sensor_pose(world, &sensor.spec) else {
                debug!(id = sensor.id, "sensor's actor is gone; no capture");
                continue;
            };
            sensor.captures += 1;
            let kind = sensor.spec.sensor_kind().expect("checked at spawn");
            let mut header = SensorHeader::new(kind, sensor.id);
            header.frame = frame;
            header.elapsed_ns = elapsed_ns;
            header.episode = episode;
            header.sequence = sensor.captures;
            header.position = pose.translation.to_array();
            header.rotation = pose.rotation.to_array();
            let p = sensor.spec.params;
            header.size = [p[0] as u32, p[1] as u32];
            let published = match &sensor.port {
                SensorPort::Depth(port) => publish(port, header, |slots, header| {
                    header.count = slots.len() as u32;
                    depth_into(world, &sensor.spec, pose, slots)
                }),
                SensorPort::Lidar(port) => {
                    let sweep = lidar_sweep(&sensor.spec, sensor.lidar_column, since_last_ns);
                    sensor.lidar_column = (sweep.start + sweep.columns) % sweep.per_channel;
                    publish(port, header, |slots, header| {
                        header.count = lidar_into(world, &sensor.spec, pose, sweep, slots) as u32;
                    })
                }
                SensorPort::Imu(port) => publish(port, header, |slots, header| {
                    header.count = 1;
                    header.size = [1, 1];
                    slots[0].write(imu(world, &sensor.spec, pose));
                }),
            };
            // A lost capture shows as a gap in the sequence; the world goes on.
            if let Err(e) = published {
                warn!(id = sensor.id, frame, "capture not published: {e}");
            }
        }
    }
}

impl Sensor {
    /// Publishes the empty last capture that tells readers why the stream
    /// ended, then drops the publisher.
    fn end(self, reason: SensorEnd, frame: u64, episode: u64) {
        info!(id = self.id, frame, "sensor ended: {reason}");
        let kind = self.spec.sensor_kind().unwrap_or(SensorKind::Imu);
        let mut header = SensorHeader::new(kind, self.id);
        header.frame = frame;
        header.episode = episode;
        header.sequence = self.captures + 1;
        header.flags = SensorHeader::END_OF_STREAM;
        header.end_reason = reason as u32;
        let sent = match &self.port {
            SensorPort::Depth(port) => send_end(port, header),
            SensorPort::Lidar(port) => send_end(port, header),
            SensorPort::Imu(port) => send_end(port, header),
        };
        if let Err(e) = sent {
            warn!(
                id = self.id,
                "could not tell the sensor's readers it ended: {e}"
            );
        }
    }

    fn info(&self) -> SensorInfo {
        SensorInfo {
            id: self.id,
            spec: self.spec,
            captures: self.captures,
        }
    }
}

/// When a sensor captures next after `now_ns`: the next frame (sensor_tick
/// 0), or the next multiple of its period, so captures land on multiples.
fn next_capture_after(now_ns: u64, spec: &SensorSpec) -> u64 {
    let period = seconds_to_nanos(spec.sensor_tick);
    now_ns
        .checked_div(period)
        .map_or(now_ns + 1, |periods| (periods + 1) * period)
}

/// Sends an empty sample with `header` (an end-of-stream marker).
fn send_end<T: std::fmt::Debug + ZeroCopySend + 'static>(
    port: &Port<T>,
    header: SensorHeader,
) -> Result<(), ServerError> {
    let mut sample = port
        .loan_slice_uninit(0)
        .map_err(|e| ServerError::transport("sensor loan", e))?;
    *sample.user_header_mut() = header;
    // SAFETY: the slice has no elements, so there is nothing to initialise.
    let sample = unsafe { sample.assume_init() };
    sample
        .send()
        .map_err(|e| ServerError::transport("sensor send", e))?;
    Ok(())
}

/// Loans a sample, lets `fill` write every element in place, and sends it.
fn publish<T: std::fmt::Debug + ZeroCopySend + 'static>(
    port: &Port<T>,
    header: SensorHeader,
    fill: impl FnOnce(&mut [MaybeUninit<T>], &mut SensorHeader),
) -> Result<(), ServerError> {
    let elements = port.initial_max_slice_len();
    let mut sample = port
        .loan_slice_uninit(elements)
        .map_err(|e| ServerError::transport("sensor loan", e))?;
    let mut header = header;
    fill(sample.payload_mut(), &mut header);
    header.platform_timestamp = std::time::SystemTime::now()
        .duration_since(std::time::UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64());
    *sample.user_header_mut() = header;
    // SAFETY: every `fill` above writes each of the `elements` slots (depth:
    // one value per pixel; lidar: the returns, then zeros; IMU: slot 0 of 1).
    let sample = unsafe { sample.assume_init() };
    sample
        .send()
        .map_err(|e| ServerError::transport("sensor send", e))?;
    Ok(())
}

/// The sensor's pose in the world: its parent's pose (or the origin) times
/// its relative pose.
fn sensor_pose(world: &World, spec: &SensorSpec) -> Option<Pose> {
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
fn depth_into(world: &World, spec: &SensorSpec, pose: Pose, slots: &mut [MaybeUninit<f32>]) {
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
struct Sweep {
    start: usize,
    columns: usize,
    per_channel: usize,
}

/// A lidar spinning at `rotation_frequency` Hz covers `frequency × Δt` of a
/// turn per capture (CARLA's partial scans); 0 Hz is a full turn every capture.
fn lidar_sweep(spec: &SensorSpec, start: usize, since_last_ns: u64) -> Sweep {
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
fn lidar_into(
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
fn imu(world: &World, spec: &SensorSpec, pose: Pose) -> ImuMeasurement {
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
