//! A mirror's side of this host's shared memory: the world's services,
//! created with the server's own configuration (so local clients open them
//! as they would a server's), the frames and captures published there, and
//! the local requests taken for forwarding.

use std::collections::HashMap;
use std::time::Duration;

use iceoryx2::active_request::ActiveRequest;
use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::server::Server;
use iceoryx2::port::update_connections::UpdateConnections;
use iceoryx2::prelude::*;
use shared_types::limits::{WorldLimits, INITIAL_MAX_ACTORS};
use shared_types::{
    frame_slice_len, ActorState, BatchHeader, BatchResponseHeader, Bgra, CollisionEvent, Command,
    CommandResult, ControlRequest, ControlResponse, FrameHeader, GnssMeasurement, ImuMeasurement,
    LidarPoint, LockstepRequest, LockstepResponse, ObstacleDetection, RadarDetection,
    RecorderRequest, RecorderResponse, SemanticLidarPoint, SensorHeader, SensorInfo, SensorKind,
    SensorRequest, SensorResponseHeader, ServiceNames, TickRequest, TickResponse,
};
use simbus_transport::frame_sample::{send_frame, FramePublisher};
use simbus_transport::spec::WorldServices;
use simbus_transport::Bus;

/// A fixed-size request waiting for its answer.
pub(super) type Active<Req, Resp> = ActiveRequest<Bus, Req, (), Resp, ()>;
/// A batch waiting for its answer.
pub(super) type ActiveBatch =
    ActiveRequest<Bus, [Command], BatchHeader, [CommandResult], BatchResponseHeader>;
/// A sensor request waiting for its answer.
pub(super) type ActiveSensors =
    ActiveRequest<Bus, SensorRequest, (), [SensorInfo], SensorResponseHeader>;

/// A local request taken for forwarding.
pub(super) enum Local {
    Control(Active<ControlRequest, ControlResponse>),
    /// With the request as forwarded (the sender's pid and `host/node` name).
    Tick(Active<TickRequest, TickResponse>, TickRequest),
    Lockstep(Active<LockstepRequest, LockstepResponse>),
    Recorder(Active<RecorderRequest, RecorderResponse>),
    Batch(ActiveBatch),
    Sensors(ActiveSensors),
}

type FixedServer<Req, Resp> = Server<Bus, Req, (), Resp, ()>;
type BatchServer = Server<Bus, [Command], BatchHeader, [CommandResult], BatchResponseHeader>;
type SensorServer = Server<Bus, SensorRequest, (), [SensorInfo], SensorResponseHeader>;

/// The world's services on this host.
pub(super) struct LocalServices {
    node: Node<Bus>,
    frames: FramePublisher,
    ready: Notifier<Bus>,
    control: FixedServer<ControlRequest, ControlResponse>,
    tick: FixedServer<TickRequest, TickResponse>,
    lockstep: FixedServer<LockstepRequest, LockstepResponse>,
    recorder: FixedServer<RecorderRequest, RecorderResponse>,
    batch: BatchServer,
    sensors: SensorServer,
    /// Woken by local clients after a request, and by [`wake`].
    wake: Listener<Bus>,
}

use crate::error::LocalError;
use crate::ports::{self, node, specs, Bell};

/// A service of the world that could not be created here.
fn create_failed(e: impl Into<crate::error::TransportError>) -> LocalError {
    LocalError::Create(e.into())
}

/// A local request that could not be received.
fn receive_failed(e: impl Into<crate::error::TransportError>) -> LocalError {
    LocalError::Transport {
        what: "receiving a local request".to_owned(),
        source: e.into(),
    }
}

/// A sensor's service that could not be created here.
fn sensor_failed(e: impl Into<crate::error::TransportError>) -> LocalError {
    LocalError::CreateSensor(e.into())
}

/// The world's services here, each created from its one description
/// ([`WorldServices`]), as the server creates them.
type Ports = (
    FramePublisher,
    Notifier<Bus>,
    Listener<Bus>,
    BatchServer,
    SensorServer,
);

fn world_ports(
    node: &Node<Bus>,
    specs: &WorldServices,
    limits: &WorldLimits,
) -> Result<Ports, LocalError> {
    let frames = specs.frames.create(node, limits).map_err(create_failed)?;
    let frames = specs
        .frames
        .publisher(&frames, frame_slice_len(INITIAL_MAX_ACTORS))
        .map_err(create_failed)?;
    let ready = specs
        .frame_ready
        .open_or_create(node, limits)
        .map_err(create_failed)?
        .notifier_builder()
        .create()
        .map_err(create_failed)?;
    let wake = specs
        .control_wake
        .open_or_create(node, limits)
        .map_err(create_failed)?
        .listener_builder()
        .create()
        .map_err(create_failed)?;
    let batch = specs.batch.create(node, limits).map_err(create_failed)?;
    let batch = specs.batch.server(&batch).map_err(create_failed)?;
    let sensors = specs.sensors.create(node, limits).map_err(create_failed)?;
    let sensors = specs.sensors.server(&sensors).map_err(create_failed)?;
    Ok((frames, ready, wake, batch, sensors))
}

impl LocalServices {
    /// Creates the world's services here. Fails if a server or another
    /// mirror of the world runs on this host.
    pub(super) fn create(names: &ServiceNames, limits: &WorldLimits) -> Result<Self, LocalError> {
        simbus_transport::environment::prepare()?;
        let node = node("zenoh-mirror")?;
        node.try_cleanup_dead_nodes();
        let specs = specs(names)?;
        let (frames, ready, wake, batch, sensors) = world_ports(&node, &specs, limits)?;
        macro_rules! server {
            ($spec:expr) => {
                $spec
                    .create(&node, limits)
                    .map_err(create_failed)?
                    .server_builder()
                    .create()
                    .map_err(create_failed)?
            };
        }
        let control = server!(specs.control);
        let tick = server!(specs.tick);
        let lockstep = server!(specs.lockstep);
        let recorder = server!(specs.recorder);
        Ok(Self {
            node,
            frames,
            ready,
            control,
            tick,
            lockstep,
            recorder,
            batch,
            sensors,
            wake,
        })
    }

    /// Waits until a local client sends a request or [`wake`] is called,
    /// at most `timeout`: looking for it, yielding the CPU, for the first
    /// `poll_for`, then asleep.
    pub(super) fn wait(&self, poll_for: Duration, timeout: Duration) -> Result<(), LocalError> {
        simbus_transport::hybrid::wait(&self.wake, poll_for, timeout)
            .map(drop)
            .map_err(|e| LocalError::transport("waiting for local requests", e))
    }

    /// Publishes a frame (kept as the one new subscribers get first).
    pub(super) fn publish_frame(
        &self,
        header: &FrameHeader,
        actors: &[ActorState],
    ) -> Result<(), LocalError> {
        send_frame(&self.frames, *header, actors.len(), |i| actors[i])
            .map_err(|e| LocalError::transport("frame send", e))
    }

    /// Publishes a frame whose actors `actor` gives, one by one, straight
    /// into the loaned sample, their poses after them (kept as the one new
    /// subscribers get first).
    pub(super) fn publish_frame_with(
        &self,
        header: &FrameHeader,
        actor: impl FnMut(usize) -> ActorState,
    ) -> Result<(), LocalError> {
        send_frame(&self.frames, *header, header.actor_count as usize, actor)
            .map_err(|e| LocalError::transport("frame send", e))
    }

    /// Wakes every local client blocked on the frame-ready event, after a
    /// frame, a capture or an answer; connects new frame subscribers.
    pub(super) fn notify(&self) {
        if let Err(e) = self.ready.notify() {
            tracing::debug!("frame-ready notify: {e:?}");
        }
    }

    /// Connects frame subscribers that joined since the last frame (in
    /// synchronous mode the next frame may be far).
    pub(super) fn connect_new_subscribers(&self) {
        if let Err(e) = self.frames.update_connections() {
            tracing::debug!("connecting new subscribers: {e:?}");
        }
    }

    /// Every local request waiting, in service order.
    pub(super) fn receive_requests(&self, out: &mut Vec<Local>) -> Result<(), LocalError> {
        while let Some(r) = self.control.receive().map_err(receive_failed)? {
            out.push(Local::Control(r));
        }
        while let Some(r) = self.tick.receive().map_err(receive_failed)? {
            let payload = *r.payload();
            out.push(Local::Tick(r, payload));
        }
        while let Some(r) = self.lockstep.receive().map_err(receive_failed)? {
            out.push(Local::Lockstep(r));
        }
        while let Some(r) = self.recorder.receive().map_err(receive_failed)? {
            out.push(Local::Recorder(r));
        }
        while let Some(r) = self.batch.receive().map_err(receive_failed)? {
            out.push(Local::Batch(r));
        }
        while let Some(r) = self.sensors.receive().map_err(receive_failed)? {
            out.push(Local::Sensors(r));
        }
        Ok(())
    }
}

impl std::fmt::Debug for LocalServices {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("LocalServices")
            .field("node", self.node.name())
            .finish()
    }
}

/// One sensor's publisher here, by the kind of its payload.
enum SensorPort {
    Depth(Publisher<Bus, [f32], SensorHeader>),
    Image(Publisher<Bus, [Bgra], SensorHeader>),
    Collision(Publisher<Bus, [CollisionEvent], SensorHeader>),
    Obstacle(Publisher<Bus, [ObstacleDetection], SensorHeader>),
    Lidar(Publisher<Bus, [LidarPoint], SensorHeader>),
    SemanticLidar(Publisher<Bus, [SemanticLidarPoint], SensorHeader>),
    Radar(Publisher<Bus, [RadarDetection], SensorHeader>),
    Imu(Publisher<Bus, [ImuMeasurement], SensorHeader>),
    Gnss(Publisher<Bus, [GnssMeasurement], SensorHeader>),
}

/// The sensors' publishers here, created when a sensor is first listed or
/// first captures.
#[derive(Default)]
pub(super) struct SensorPorts {
    ports: HashMap<u64, SensorPort>,
}

impl std::fmt::Debug for SensorPorts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("SensorPorts")
            .field("sensors", &self.ports.len())
            .finish()
    }
}

fn sensor_publisher<T: std::fmt::Debug + ZeroCopySend + 'static>(
    node: &Node<Bus>,
    names: &ServiceNames,
    id: u64,
    elements: usize,
    limits: &WorldLimits,
) -> Result<Publisher<Bus, [T], SensorHeader>, LocalError> {
    let spec = WorldServices::new(names)
        .and_then(|specs| specs.sensor::<T>(id))
        .map_err(sensor_failed)?;
    let service = spec.open_or_create(node, limits).map_err(sensor_failed)?;
    spec.publisher(&service, elements).map_err(sensor_failed)
}

fn publish<T: bytemuck::Pod + std::fmt::Debug + ZeroCopySend>(
    port: &Publisher<Bus, [T], SensorHeader>,
    header: &SensorHeader,
    payload: &[u8],
) -> Result<(), LocalError> {
    let size = std::mem::size_of::<T>();
    if !payload.len().is_multiple_of(size) {
        return Err(LocalError::PartialElement {
            len: payload.len(),
            size,
        });
    }
    let mut sample = port
        .loan_slice_uninit(payload.len() / size)
        .map_err(|e| LocalError::transport("capture loan", e))?;
    *sample.user_header_mut() = *header;
    let sample =
        sample.write_from_fn(|i| bytemuck::pod_read_unaligned(&payload[i * size..][..size]));
    sample
        .send()
        .map_err(|e| LocalError::transport("capture send", e))?;
    Ok(())
}

impl SensorPorts {
    /// Creates sensor `id`'s service here if it is not yet.
    pub(super) fn ensure(
        &mut self,
        names: &ServiceNames,
        limits: &WorldLimits,
        local: &LocalServices,
        id: u64,
        kind: u32,
        elements: usize,
    ) -> Result<(), LocalError> {
        if self.ports.contains_key(&id) {
            return Ok(());
        }
        let node = &local.node;
        let port = match SensorKind::from_u32(kind) {
            Some(SensorKind::Depth) => {
                SensorPort::Depth(sensor_publisher(node, names, id, elements, limits)?)
            }
            Some(SensorKind::Rgb | SensorKind::Semantic | SensorKind::Instance) => {
                SensorPort::Image(sensor_publisher(node, names, id, elements, limits)?)
            }
            Some(SensorKind::Collision) => {
                SensorPort::Collision(sensor_publisher(node, names, id, elements, limits)?)
            }
            Some(SensorKind::Obstacle) => {
                SensorPort::Obstacle(sensor_publisher(node, names, id, elements, limits)?)
            }
            Some(SensorKind::Lidar) => {
                SensorPort::Lidar(sensor_publisher(node, names, id, elements, limits)?)
            }
            Some(SensorKind::SemanticLidar) => {
                SensorPort::SemanticLidar(sensor_publisher(node, names, id, elements, limits)?)
            }
            Some(SensorKind::Radar) => {
                SensorPort::Radar(sensor_publisher(node, names, id, elements, limits)?)
            }
            Some(SensorKind::Imu) => {
                SensorPort::Imu(sensor_publisher(node, names, id, elements, limits)?)
            }
            Some(SensorKind::Gnss) => {
                SensorPort::Gnss(sensor_publisher(node, names, id, elements, limits)?)
            }
            None => return Err(LocalError::UnknownSensorKind(kind)),
        };
        self.ports.insert(id, port);
        Ok(())
    }

    /// Publishes a capture here; a sensor's last capture ends its service.
    pub(super) fn publish(
        &mut self,
        names: &ServiceNames,
        limits: &WorldLimits,
        local: &LocalServices,
        header: &SensorHeader,
        payload: &[u8],
    ) -> Result<(), LocalError> {
        let id = header.sensor_id;
        let elements = payload.len() / 4;
        self.ensure(names, limits, local, id, header.kind, elements)?;
        let published = match &self.ports[&id] {
            SensorPort::Depth(p) => publish(p, header, payload),
            SensorPort::Image(p) => publish(p, header, payload),
            SensorPort::Collision(p) => publish(p, header, payload),
            SensorPort::Obstacle(p) => publish(p, header, payload),
            SensorPort::Lidar(p) => publish(p, header, payload),
            SensorPort::SemanticLidar(p) => publish(p, header, payload),
            SensorPort::Radar(p) => publish(p, header, payload),
            SensorPort::Imu(p) => publish(p, header, payload),
            SensorPort::Gnss(p) => publish(p, header, payload),
        };
        if header.end().is_some() {
            self.ports.remove(&id);
        }
        published
    }
}

/// Wakes the mirror's main thread (blocked in [`LocalServices::wait`])
/// from any thread: Zenoh's callbacks call it after queueing an event.
pub(super) fn wake(names: &ServiceNames) {
    ports::ring(names, Bell::Wake);
}
