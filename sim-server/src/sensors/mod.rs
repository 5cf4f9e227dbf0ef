//! The sensor domain: cameras (depth, RGB, semantic and instance
//! segmentation), lidars (plain and semantic) and a radar that ray-cast
//! the rapier world, an IMU, a GNSS receiver, and the event sensors
//! (collision, obstacle). Each writes its capture **directly into the loaned
//! shared-memory sample** of its own iceoryx2 service — no intermediate
//! buffer, no copy. The sensor service spawns, lists and destroys them; a
//! sensor ends with its parent actor, its episode and the server, and its
//! readers are told why.

mod camera;
mod capture;
mod casts;
mod culling;
mod events;
mod frame;
mod gnss;
mod ground;
mod lidar_noise;
mod publish;
mod radar;
mod random;
mod renderer;
mod slab;

use iceoryx2::service::port_factory::PortFactory as _;
use publish::send_end;

pub use renderer::RenderThreadsError;
pub(crate) use renderer::Renderer;

/// The default scene after 1.2 s (the sphere rolling, boxes tumbling, the
/// capsule falling) and the id of one of its vehicles: what the ray-casting
/// tests look at.
#[cfg(test)]
fn default_world_in_motion() -> (World, u64) {
    let mut world = World::new(&crate::scene::Scene::Default.placements(0), 1);
    let plan = crate::clock::SubstepPlan::new(10_000_000, &shared_types::WorldSettings::default());
    for _ in 0..120 {
        world.step(&plan);
    }
    let vehicle = world
        .states()
        .into_iter()
        .find(|a| a.kind == shared_types::ActorKind::Vehicle as u32)
        .expect("the default scene has vehicles")
        .id;
    (world, vehicle)
}

use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::server::Server as RequestServer;
use iceoryx2::prelude::*;
use shared_types::limits::WorldLimits;
use shared_types::{
    seconds_to_nanos, Bgra, CollisionEvent, GnssMeasurement, ImuMeasurement, LidarPoint,
    ObstacleDetection, RadarDetection, ResponseStatus, SemanticLidarPoint, SensorEnd, SensorHeader,
    SensorInfo, SensorKind, SensorRefusal, SensorRequest, SensorRequestKind, SensorResponseHeader,
    SensorSpec, PROTOCOL_VERSION,
};
use simbus_recording::RecordedSensor;
use simbus_transport::Bus;
use tracing::{debug, info, warn};

use crate::clock::Clock;
use crate::error::PortError;
use crate::ports::Transport;
use crate::world::World;

type Port<T> = Publisher<Bus, [T], SensorHeader>;
type SensorServer = RequestServer<Bus, SensorRequest, (), [SensorInfo], SensorResponseHeader>;

/// A sensor's publisher, typed by what it captures.
enum SensorPort {
    Depth(Port<f32>),
    /// RGB, semantic and instance segmentation.
    Image(Port<Bgra>),
    Lidar(Port<LidarPoint>),
    SemanticLidar(Port<SemanticLidarPoint>),
    Radar(Port<RadarDetection>),
    Imu(Port<ImuMeasurement>),
    Gnss(Port<GnssMeasurement>),
    Collision(Port<CollisionEvent>),
    Obstacle(Port<ObstacleDetection>),
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
    /// Lidar: its ray directions, computed once.
    lidar_rays: capture::LidarRays,
    /// GNSS: its error generator; radar: its rays' generator (seeded with
    /// their `noise_seed`).
    random: random::Random,
    captures: u64,
}

/// A sensor spawned or ended (the sensors domain notes them; the recorder
/// writes them when recording).
#[derive(Debug, Clone, Copy)]
pub(crate) enum SensorNote {
    Spawned(RecordedSensor),
    Ended { frame: u64, id: u64 },
}

/// Every sensor of a world, and the service that manages them.
pub(crate) struct Sensors {
    port: SensorServer,
    /// The previous server's clients (their requests are dropped).
    earlier: simbus_transport::EarlierClients,
    list: Vec<Sensor>,
    next_id: u64,
    /// The world's limits (each sensor admits `--max-sensor-readers`).
    limits: WorldLimits,
    /// Spawns and ends since the recorder last took them.
    journal: Vec<SensorNote>,
    /// The threads cameras and lidars render on.
    renderer: Renderer,
    /// The cameras' shared casts.
    casts: casts::Casts,
}

fn open_port<T: std::fmt::Debug + ZeroCopySend + 'static>(
    transport: &Transport,
    id: u64,
    elements: usize,
    limits: &WorldLimits,
) -> Result<Port<T>, PortError> {
    let spec = transport
        .services
        .sensor::<T>(id)
        .map_err(|e| PortError::transport("sensor service name", e))?;
    let service = spec
        .open_or_create(&transport.node, limits)
        .map_err(|e| PortError::transport("sensor service", e))?;
    spec.publisher(&service, elements)
        .map_err(|e| PortError::transport("sensor publisher", e))
}

impl std::fmt::Debug for Sensors {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Sensors")
            .field("sensors", &self.list.len())
            .field("next_id", &self.next_id)
            .field("max_readers", &self.limits.max_sensor_readers)
            .finish()
    }
}

impl Sensors {
    /// Opens the sensor service; no sensors yet, each will admit
    /// `limits.max_sensor_readers` readers, and their captures are cast
    /// on `renderer`'s threads.
    pub(crate) fn open(
        transport: &Transport,
        limits: &WorldLimits,
        renderer: Renderer,
    ) -> Result<Self, PortError> {
        let spec = &transport.services.sensors;
        let service = spec
            .open_or_create(&transport.node, limits)
            .map_err(|e| PortError::transport("sensor service", e))?;
        let earlier = simbus_transport::EarlierClients::of(service.dynamic_config());
        let port = spec
            .server(&service)
            .map_err(|e| PortError::transport("sensor server", e))?;
        Ok(Self {
            port,
            earlier,
            list: Vec::new(),
            next_id: 0,
            limits: *limits,
            journal: Vec::new(),
            renderer,
            casts: casts::Casts::default(),
        })
    }

    /// Spawns, destroys and lists sensors.
    /// During a replay, a sensor spawned without a parent rides on `follow`
    /// (0: none).
    pub(crate) fn handle(
        &mut self,
        transport: &Transport,
        world: &World,
        clock: &Clock,
        episode: u64,
        follow: u64,
    ) -> Result<(), PortError> {
        while let Some(request) = self
            .port
            .receive()
            .map_err(|e| PortError::transport("sensor receive", e))?
        {
            if self.earlier.sent(request.header()) {
                debug!("dropped a request from a client of the previous server");
                continue;
            }
            let payload = *request.payload();
            let (status, error, infos): (ResponseStatus, u32, Vec<SensorInfo>) = if payload
                .protocol_version
                != PROTOCOL_VERSION
            {
                (ResponseStatus::ProtocolMismatch, 0, Vec::new())
            } else {
                match SensorRequestKind::from_u32(payload.kind) {
                    Some(SensorRequestKind::Spawn) => {
                        let mut spec = payload.spec;
                        if spec.attach_to == 0 {
                            spec.attach_to = follow;
                        }
                        match self.spawn(transport, spec, world, clock) {
                            Ok(info) => (ResponseStatus::Ok, 0, vec![info]),
                            Err(refusal) => (ResponseStatus::Refused, refusal as u32, Vec::new()),
                        }
                    }
                    Some(SensorRequestKind::Destroy) => {
                        if self.destroy(payload.id, clock.frame(), episode) {
                            (ResponseStatus::Ok, 0, Vec::new())
                        } else {
                            let refusal = SensorRefusal::UnknownSensor;
                            (ResponseStatus::Refused, refusal as u32, Vec::new())
                        }
                    }
                    Some(SensorRequestKind::List) => (ResponseStatus::Ok, 0, self.list()),
                    None => (ResponseStatus::UnknownRequest, 0, Vec::new()),
                }
            };
            let response = request.loan_slice_uninit(infos.len()).map(|mut response| {
                *response.user_header_mut() = SensorResponseHeader {
                    protocol_version: PROTOCOL_VERSION,
                    status: status as u32,
                    error,
                    reserved: 0,
                };
                response.write_from_slice(&infos)
            });
            match response.map(|r| r.send()) {
                Ok(Ok(())) => {}
                Ok(Err(e)) => debug!("sensor response not delivered: {e:?}"),
                Err(e) => debug!("sensor response not loaned: {e:?}"),
            }
        }
        Ok(())
    }

    /// Builds a sensor from `spec` and opens its service.
    pub(crate) fn spawn(
        &mut self,
        transport: &Transport,
        spec: SensorSpec,
        world: &World,
        clock: &Clock,
    ) -> Result<SensorInfo, SensorRefusal> {
        let now_ns = clock.elapsed_ns();
        let Some(kind) = spec.sensor_kind().filter(|_| spec.check().is_ok()) else {
            return Err(SensorRefusal::InvalidSpec);
        };
        if spec.attach_to != 0 && world.body_of(spec.attach_to).is_none() {
            return Err(SensorRefusal::UnknownActor);
        }
        let id = self.next_id + 1;
        let (elements, limits) = (spec.elements(), &self.limits);
        let port = match kind {
            SensorKind::Depth => open_port(transport, id, elements, limits).map(SensorPort::Depth),
            SensorKind::Rgb | SensorKind::Semantic | SensorKind::Instance => {
                open_port(transport, id, elements, limits).map(SensorPort::Image)
            }
            SensorKind::Lidar => open_port(transport, id, elements, limits).map(SensorPort::Lidar),
            SensorKind::SemanticLidar => {
                open_port(transport, id, elements, limits).map(SensorPort::SemanticLidar)
            }
            SensorKind::Radar => open_port(transport, id, elements, limits).map(SensorPort::Radar),
            SensorKind::Imu => open_port(transport, id, 1, limits).map(SensorPort::Imu),
            SensorKind::Gnss => open_port(transport, id, 1, limits).map(SensorPort::Gnss),
            SensorKind::Collision => {
                open_port(transport, id, elements, limits).map(SensorPort::Collision)
            }
            SensorKind::Obstacle => open_port(transport, id, 1, limits).map(SensorPort::Obstacle),
        };
        let port = match port {
            Ok(port) => port,
            Err(e) => {
                warn!(id, "refused a sensor: {e}");
                return Err(SensorRefusal::NoMemory);
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
            lidar_rays: if kind.is_lidar() {
                capture::LidarRays::new(&spec)
            } else {
                capture::LidarRays::default()
            },
            random: random::Random::new(u64::from(
                spec.gnss_params()
                    .map(|g| g.seed)
                    .or(spec.radar_params().map(|r| r.seed))
                    .unwrap_or(0),
            )),
            captures: 0,
        };
        let info = sensor.info();
        self.journal.push(SensorNote::Spawned(RecordedSensor {
            frame: clock.frame(),
            id,
            spec,
        }));
        self.list.push(sensor);
        Ok(info)
    }

    /// [`Sensors::spawn`] under a given `id` (a journaled sensor coming
    /// back after a resume).
    pub(crate) fn respawn(
        &mut self,
        transport: &Transport,
        id: u64,
        spec: SensorSpec,
        world: &World,
        clock: &Clock,
    ) -> Result<SensorInfo, SensorRefusal> {
        let next = self.next_id;
        self.next_id = id.saturating_sub(1);
        let spawned = self.spawn(transport, spec, world, clock);
        self.next_id = next.max(self.next_id);
        spawned
    }

    /// Every living sensor's id and spec.
    pub(crate) fn alive(&self) -> Vec<(u64, SensorSpec)> {
        self.list.iter().map(|s| (s.id, s.spec)).collect()
    }

    /// New sensors get ids after `last` (a resumed journal's highest).
    pub(crate) fn go_on_after(&mut self, last: u64) {
        self.next_id = self.next_id.max(last);
    }

    /// Removes sensor `id`, telling its readers; `false` if there is none.
    pub(crate) fn destroy(&mut self, id: u64, frame: u64, episode: u64) -> bool {
        let Some(index) = self.list.iter().position(|s| s.id == id) else {
            return false;
        };
        let sensor = self.list.remove(index);
        self.journal.push(SensorNote::Ended { frame, id });
        sensor.end(SensorEnd::Destroyed, frame, episode);
        true
    }

    /// The spawns of every living sensor, as a recording starting at
    /// `frame` holds them.
    pub(crate) fn recorded_spawns(&self, frame: u64) -> Vec<SensorNote> {
        self.list
            .iter()
            .map(|s| {
                SensorNote::Spawned(RecordedSensor {
                    frame,
                    id: s.id,
                    spec: s.spec,
                })
            })
            .collect()
    }

    /// The spawns and ends since last taken, for the recording.
    pub(crate) fn take_journal(&mut self) -> std::vec::Drain<'_, SensorNote> {
        self.journal.drain(..)
    }

    /// Whether a collision sensor needs the world's contacts.
    pub(crate) fn watch_contacts(&self) -> bool {
        self.list
            .iter()
            .any(|s| matches!(s.port, SensorPort::Collision(_)))
    }

    /// Whether there is no sensor.
    pub(crate) fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// Every sensor.
    pub(crate) fn list(&self) -> Vec<SensorInfo> {
        self.list.iter().map(Sensor::info).collect()
    }

    /// Ends the sensors whose parent actor is gone: a sensor dies with the
    /// actor it rides on, as in CARLA.
    pub(crate) fn end_orphans(&mut self, world: &World, frame: u64, episode: u64) {
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
            self.journal.push(SensorNote::Ended {
                frame,
                id: sensor.id,
            });
            sensor.end(SensorEnd::ParentDestroyed, frame, episode);
        }
    }

    /// Ends every sensor, telling its readers `reason` (a new episode starts
    /// without sensors; the server stops). Sensor ids are not reused.
    pub(crate) fn end_all(&mut self, reason: SensorEnd, frame: u64, episode: u64) {
        for sensor in self.list.drain(..) {
            self.journal.push(SensorNote::Ended {
                frame,
                id: sensor.id,
            });
            sensor.end(reason, frame, episode);
        }
    }

    /// The rays the sensors cast for the last frame captured (saturates).
    pub(crate) fn rays(&self) -> u32 {
        u32::try_from(self.casts.rays).unwrap_or(u32::MAX)
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
            SensorPort::Image(port) => send_end(port, header),
            SensorPort::Lidar(port) => send_end(port, header),
            SensorPort::SemanticLidar(port) => send_end(port, header),
            SensorPort::Radar(port) => send_end(port, header),
            SensorPort::Imu(port) => send_end(port, header),
            SensorPort::Gnss(port) => send_end(port, header),
            SensorPort::Collision(port) => send_end(port, header),
            SensorPort::Obstacle(port) => send_end(port, header),
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
    // A collision sensor reports every contact, whatever its tick.
    if spec.sensor_kind() == Some(SensorKind::Collision) {
        return now_ns + 1;
    }
    let period = seconds_to_nanos(spec.sensor_tick);
    now_ns
        .checked_div(period)
        .map_or(now_ns + 1, |periods| (periods + 1) * period)
}
