//! A frame's captures: every sensor due at the frame casts or measures
//! straight into a loaned sample and publishes it; a copy goes to the
//! recorder when it records sensors. Event sensors publish only on frames
//! where something happened.

use std::mem::MaybeUninit;

use rapier3d::prelude::Pose;
use shared_types::scene::SceneName;
use shared_types::{Bgra, ObstacleDetection, SensorHeader};
use tracing::{debug, warn};

use super::publish::publish;
use super::renderer::Renderer;
use super::{camera, capture, casts, events, gnss, radar, Sensor, SensorPort, Sensors};
use crate::error::PortError;
use crate::world::World;

/// A capture's copy for the recorder, when it records sensors.
type Record<'r> = Option<&'r mut Vec<(SensorHeader, Vec<u8>)>>;

/// What one capture is taken of.
struct Shot<'w> {
    world: &'w World,
    scene: SceneName,
    pose: Pose,
    /// Simulation time since the sensor's previous capture, nanoseconds.
    since_last_ns: u64,
}

impl Sensors {
    /// Captures and publishes every sensor due at this frame of `scene`; a
    /// copy of each capture goes to `record` when it is given (a recording
    /// with sensors).
    pub(crate) fn capture(
        &mut self,
        world: &World,
        scene: SceneName,
        (frame, elapsed_ns, episode): (u64, u64, u64),
        mut record: Option<&mut Vec<(SensorHeader, Vec<u8>)>>,
    ) {
        let (renderer, casts) = (&self.renderer, &mut self.casts);
        casts.plan(
            self.list
                .iter()
                .filter(|s| elapsed_ns >= s.next_capture_ns)
                .filter_map(|s| Some((&s.spec, s.spec.sensor_kind()?)))
                .filter(|(_, kind)| kind.is_camera()),
        );
        for sensor in &mut self.list {
            if elapsed_ns < sensor.next_capture_ns {
                continue;
            }
            sensor.next_capture_ns = super::next_capture_after(elapsed_ns, &sensor.spec);
            let since_last_ns = elapsed_ns - sensor.last_capture_ns.min(elapsed_ns);
            sensor.last_capture_ns = elapsed_ns;
            let Some(pose) = capture::sensor_pose(world, &sensor.spec) else {
                debug!(id = sensor.id, "sensor's actor is gone; no capture");
                continue;
            };
            // Event sensors publish only on frames where something happened.
            let parent = sensor.spec.attach_to;
            let obstacle = match &sensor.port {
                SensorPort::Obstacle(_) => match events::obstacle(world, &sensor.spec, pose) {
                    Some(seen) => Some(seen),
                    None => continue,
                },
                SensorPort::Collision(_) if events::collisions(world, parent).next().is_none() => {
                    continue
                }
                _ => None,
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
            header.size = sensor.spec.sensor_params().map_or([0, 0], |p| p.size());
            let shot = Shot {
                world,
                scene,
                pose,
                since_last_ns,
            };
            let record = record.as_deref_mut();
            let published = match obstacle {
                Some(seen) => sensor.publish_obstacle(header, record, seen),
                None => sensor.publish(&shot, header, (casts, renderer), record),
            };
            // A lost capture shows as a gap in the sequence; the world goes on.
            if let Err(e) = published {
                warn!(id = sensor.id, frame, "capture not published: {e}");
            }
        }
    }
}

impl Sensor {
    /// Takes this sensor's capture of `shot` into a loaned sample and
    /// sends it.
    fn publish(
        &mut self,
        shot: &Shot,
        header: SensorHeader,
        (casts, renderer): (&mut casts::Casts, &Renderer),
        record: Record,
    ) -> Result<(), PortError> {
        let (world, pose) = (shot.world, shot.pose);
        match &self.port {
            // SAFETY: the cast (straight into the slots, or through the
            // hits, depth_from writing one value per hit) writes the
            // image's slots, and the slots past the image are written here.
            SensorPort::Depth(port) => unsafe {
                let camera = self.spec.camera().expect("checked at spawn");
                let spec = &self.spec;
                publish(port, header, record, |slots, header| {
                    header.count = slots.len() as u32;
                    let alone = (world, shot.scene);
                    let written = if casts.depth_alone(alone, spec, pose, renderer, slots) {
                        camera.width as usize * camera.height as usize
                    } else {
                        let hits = casts.hits(world, shot.scene, spec, pose, renderer);
                        let n = hits.len().min(slots.len());
                        renderer.run(|| camera::depth_from(hits, camera.range, &mut slots[..n]));
                        n
                    };
                    slots[written..].fill(MaybeUninit::new(camera.range));
                })
            },
            // SAFETY: as the depth camera's, with image_from.
            SensorPort::Image(port) => unsafe {
                let hits = casts.hits(world, shot.scene, &self.spec, pose, renderer);
                let kind = self.spec.sensor_kind().expect("checked at spawn");
                publish(port, header, record, |slots, header| {
                    header.count = slots.len() as u32;
                    let (cast, rest) = slots.split_at_mut(hits.len().min(slots.len()));
                    renderer.run(|| camera::image_from(kind, hits, cast));
                    rest.fill(MaybeUninit::new(Bgra::default()));
                })
            },
            SensorPort::Lidar(_) | SensorPort::SemanticLidar(_) => {
                self.publish_lidar(shot, header, (casts, renderer), record)
            }
            SensorPort::Radar(port) => {
                let rays = self
                    .spec
                    .radar_params()
                    .map_or(0, |r| r.rays_per_frame(shot.since_last_ns));
                casts.rays += rays as u64;
                let (spec, random) = (&self.spec, &mut self.random);
                // SAFETY: radar_into writes the detections, then zeros in
                // every remaining slot.
                unsafe {
                    publish(port, header, record, |slots, header| {
                        let hits = radar::radar_into(world, spec, (pose, rays), random, slots);
                        header.count = hits as u32;
                        header.size = [header.count, 1];
                    })
                }
            }
            // SAFETY: an IMU capture has one slot, written here.
            SensorPort::Imu(port) => unsafe {
                publish(port, header, record, |slots, header| {
                    header.count = 1;
                    header.size = [1, 1];
                    slots.fill(MaybeUninit::new(capture::imu(world, &self.spec, pose)));
                })
            },
            // SAFETY: every slot is written: the events, then zeros.
            SensorPort::Collision(port) => unsafe {
                let (id, parent) = (self.id, self.spec.attach_to);
                publish(port, header, record, |slots, header| {
                    let mut events = events::collisions(world, parent);
                    let mut count = 0;
                    for slot in slots.iter_mut() {
                        let event = events.next();
                        count += u32::from(event.is_some());
                        slot.write(event.unwrap_or_default());
                    }
                    let dropped = events.count();
                    if dropped > 0 {
                        let frame = header.frame;
                        warn!(id, frame, dropped, "more collisions than a capture holds");
                    }
                    header.count = count;
                    header.size = [count, 1];
                })
            },
            // Published by `publish_obstacle` when something is ahead.
            SensorPort::Obstacle(_) => Ok(()),
            // SAFETY: a GNSS capture has one slot, written here.
            SensorPort::Gnss(port) => unsafe {
                let params = self.spec.gnss_params().unwrap_or_default();
                let noise = &mut self.random;
                publish(port, header, record, |slots, header| {
                    header.count = 1;
                    header.size = [1, 1];
                    for slot in slots.iter_mut() {
                        slot.write(gnss::reading(&params, pose, noise));
                    }
                })
            },
        }
    }

    /// A lidar's (plain or semantic) part of a turn.
    fn publish_lidar(
        &mut self,
        shot: &Shot,
        header: SensorHeader,
        (casts, renderer): (&mut casts::Casts, &Renderer),
        record: Record,
    ) -> Result<(), PortError> {
        let sweep = capture::lidar_sweep(&self.spec, self.lidar_column, shot.since_last_ns);
        let [channels, _] = header.size;
        casts.rays += sweep.columns as u64 * u64::from(channels);
        self.lidar_column = (sweep.start + sweep.columns) % sweep.per_channel.max(1);
        let (spec, rays) = (&self.spec, &mut self.lidar_rays);
        let (world, at) = (shot.world, (shot.pose, sweep, self.captures));
        match &self.port {
            // SAFETY: lidar_into writes the returns, then zeros in every
            // remaining slot.
            SensorPort::Lidar(port) => unsafe {
                publish(port, header, record, |slots, header| {
                    let point = capture::lidar_point;
                    let hits =
                        renderer.run(|| capture::lidar_into(world, spec, rays, at, slots, point));
                    header.count = hits as u32;
                })
            },
            // SAFETY: as the lidar's.
            SensorPort::SemanticLidar(port) => unsafe {
                let ground = casts.ground(shot.scene);
                let origin = shot.pose.translation;
                publish(port, header, record, |slots, header| {
                    let point = |hit: &capture::Return| radar::semantic_point(hit, origin, ground);
                    let hits =
                        renderer.run(|| capture::lidar_into(world, spec, rays, at, slots, point));
                    header.count = hits as u32;
                })
            },
            _ => Ok(()),
        }
    }

    /// An obstacle detector's capture of what it saw ahead.
    fn publish_obstacle(
        &self,
        header: SensorHeader,
        record: Record,
        seen: ObstacleDetection,
    ) -> Result<(), PortError> {
        let SensorPort::Obstacle(port) = &self.port else {
            return Ok(());
        };
        // SAFETY: an obstacle capture has one slot, written here.
        unsafe {
            publish(port, header, record, |slots, header| {
                header.count = 1;
                header.size = [1, 1];
                slots.fill(MaybeUninit::new(seen));
            })
        }
    }
}
