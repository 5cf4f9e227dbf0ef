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
use shared_types::limits::{
    WorldLimits, FRAME_SUBSCRIBER_BORROWED, FRAME_SUBSCRIBER_BUFFER, INITIAL_MAX_ACTORS,
    INITIAL_MAX_BATCH, MAX_BATCHES_IN_FLIGHT, SENSOR_SUBSCRIBER_BUFFER,
};
use shared_types::{
    ActorState, BatchHeader, BatchResponseHeader, Bus, Command, CommandResult, ControlRequest,
    ControlResponse, FrameHeader, ImuMeasurement, LidarPoint, LockstepRequest, LockstepResponse,
    RecorderRequest, RecorderResponse, SensorHeader, SensorInfo, SensorKind, SensorRequest,
    SensorResponseHeader, ServiceNames, TickRequest, TickResponse,
};

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
type FramePublisher = Publisher<Bus, [ActorState], FrameHeader>;
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

use crate::error::{Chain, LocalError};
use crate::export::service_name as name;

/// A service of the world that could not be created here.
fn create_failed(e: impl Into<crate::TransportError>) -> LocalError {
    LocalError::Create(e.into())
}

/// A local request that could not be received.
fn receive_failed(e: impl Into<crate::TransportError>) -> LocalError {
    LocalError::Transport {
        what: "receiving a local request".to_owned(),
        source: e.into(),
    }
}

/// A sensor's service that could not be created here.
fn sensor_failed(e: impl Into<crate::TransportError>) -> LocalError {
    LocalError::CreateSensor(e.into())
}

/// A node of this process, named `name`.
fn node(name: &str) -> Result<Node<Bus>, LocalError> {
    NodeBuilder::new()
        .name(&NodeName::new(name).map_err(|e| LocalError::transport("iceoryx2 node name", e))?)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<Bus>()
        .map_err(|e| LocalError::transport("iceoryx2 node", e))
}

/// A fixed-size request service's server, configured as the server's.
fn fixed<Req, Resp>(
    node: &Node<Bus>,
    service: &str,
    limits: &WorldLimits,
    max_clients: usize,
    (active, buffer): (usize, usize),
    fire_and_forget: bool,
) -> Result<FixedServer<Req, Resp>, LocalError>
where
    Req: std::fmt::Debug + ZeroCopySend + Copy + 'static,
    Resp: std::fmt::Debug + ZeroCopySend + Copy + 'static,
{
    node.service_builder(&name(service)?)
        .request_response::<Req, Resp>()
        .max_servers(1)
        .max_clients(max_clients)
        .max_nodes(limits.nodes())
        .max_active_requests_per_client(active)
        .max_response_buffer_size(buffer)
        .enable_fire_and_forget_requests(fire_and_forget)
        .create()
        .map_err(create_failed)?
        .server_builder()
        .create()
        .map_err(create_failed)
}

/// The frame publisher, the frame-ready notifier and the wake-up listener
/// of the world here, configured as the server's.
fn frame_ports(
    node: &Node<Bus>,
    names: &ServiceNames,
    limits: &WorldLimits,
) -> Result<(FramePublisher, Notifier<Bus>, Listener<Bus>), LocalError> {
    let frames = node
        .service_builder(&name(&names.frames)?)
        .publish_subscribe::<[ActorState]>()
        .user_header::<FrameHeader>()
        .max_publishers(1)
        .max_subscribers(limits.max_clients)
        .subscriber_max_buffer_size(FRAME_SUBSCRIBER_BUFFER)
        .subscriber_max_borrowed_samples(FRAME_SUBSCRIBER_BORROWED)
        .history_size(1)
        .enable_safe_overflow(true)
        .max_nodes(limits.nodes())
        .create()
        .map_err(create_failed)?
        .publisher_builder()
        .initial_max_slice_len(INITIAL_MAX_ACTORS)
        .allocation_strategy(AllocationStrategy::PowerOfTwo)
        .max_loaned_samples(2)
        .create()
        .map_err(create_failed)?;
    let ready = node
        .service_builder(&name(&names.frame_ready)?)
        .event()
        .max_listeners(limits.event_listeners())
        .max_notifiers(4)
        .max_nodes(limits.nodes())
        .open_or_create()
        .map_err(create_failed)?
        .notifier_builder()
        .create()
        .map_err(create_failed)?;
    let wake = node
        .service_builder(&name(&names.control_wake)?)
        .event()
        .max_listeners(limits.event_listeners())
        .max_notifiers(limits.max_clients)
        .max_nodes(limits.nodes())
        .open_or_create()
        .map_err(create_failed)?
        .listener_builder()
        .create()
        .map_err(create_failed)?;
    Ok((frames, ready, wake))
}

/// The batch and sensor servers of the world here, configured as the
/// server's.
fn slice_servers(
    node: &Node<Bus>,
    names: &ServiceNames,
    limits: &WorldLimits,
) -> Result<(BatchServer, SensorServer), LocalError> {
    let batch = node
        .service_builder(&name(&names.batch)?)
        .request_response::<[Command], [CommandResult]>()
        .request_user_header::<BatchHeader>()
        .response_user_header::<BatchResponseHeader>()
        .max_servers(1)
        .max_clients(limits.max_clients)
        .max_nodes(limits.nodes())
        .max_active_requests_per_client(MAX_BATCHES_IN_FLIGHT)
        .max_response_buffer_size(1)
        .enable_safe_overflow_for_requests(false)
        .enable_fire_and_forget_requests(true)
        .create()
        .map_err(create_failed)?
        .server_builder()
        .initial_max_slice_len(INITIAL_MAX_BATCH)
        .allocation_strategy(AllocationStrategy::PowerOfTwo)
        .create()
        .map_err(create_failed)?;
    let sensors = node
        .service_builder(&name(&names.sensors)?)
        .request_response::<SensorRequest, [SensorInfo]>()
        .response_user_header::<SensorResponseHeader>()
        .max_servers(1)
        .max_clients(limits.max_clients)
        .max_nodes(limits.nodes())
        .max_active_requests_per_client(2)
        .max_response_buffer_size(1)
        .create()
        .map_err(create_failed)?
        .server_builder()
        .initial_max_slice_len(16)
        .allocation_strategy(AllocationStrategy::PowerOfTwo)
        .create()
        .map_err(create_failed)?;
    Ok((batch, sensors))
}

impl LocalServices {
    /// Creates the world's services here. Fails if a server or another
    /// mirror of the world runs on this host.
    pub(super) fn create(names: &ServiceNames, limits: &WorldLimits) -> Result<Self, LocalError> {
        shared_types::environment::prepare()?;
        let node = node("zenoh-mirror")?;
        node.try_cleanup_dead_nodes();
        let (frames, ready, wake) = frame_ports(&node, names, limits)?;
        let control = fixed(
            &node,
            &names.control,
            limits,
            limits.max_clients,
            (2, 2),
            false,
        )?;
        let tick = fixed(&node, &names.tick, limits, 2, (4, 4), false)?;
        let lockstep = fixed(
            &node,
            &names.lockstep,
            limits,
            limits.max_clients,
            (4, 2),
            true,
        )?;
        let recorder = fixed(
            &node,
            &names.recorder,
            limits,
            limits.max_clients,
            (2, 2),
            false,
        )?;
        let (batch, sensors) = slice_servers(&node, names, limits)?;
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

    /// Sleeps until a local client sends a request or [`wake`] is called,
    /// at most `timeout`.
    pub(super) fn wait(&self, timeout: Duration) -> Result<(), LocalError> {
        self.wake
            .timed_wait(|_| {}, timeout)
            .map(drop)
            .map_err(|e| LocalError::transport("waiting for local requests", e))
    }

    /// Publishes a frame (kept as the one new subscribers get first).
    pub(super) fn publish_frame(
        &self,
        header: &FrameHeader,
        actors: &[ActorState],
    ) -> Result<(), LocalError> {
        let mut sample = self
            .frames
            .loan_slice_uninit(actors.len())
            .map_err(|e| LocalError::transport("frame loan", e))?;
        *sample.user_header_mut() = *header;
        sample
            .write_from_slice(actors)
            .send()
            .map_err(|e| LocalError::transport("frame send", e))?;
        Ok(())
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
    Lidar(Publisher<Bus, [LidarPoint], SensorHeader>),
    Imu(Publisher<Bus, [ImuMeasurement], SensorHeader>),
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
    service: &str,
    elements: usize,
    max_readers: usize,
) -> Result<Publisher<Bus, [T], SensorHeader>, LocalError> {
    node.service_builder(&name(service)?)
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
        .map_err(sensor_failed)?
        .publisher_builder()
        .initial_max_slice_len(elements.max(1))
        .allocation_strategy(AllocationStrategy::PowerOfTwo)
        .max_loaned_samples(1)
        .create()
        .map_err(sensor_failed)
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
        let (node, service, readers) = (&local.node, names.sensor(id), limits.max_sensor_readers);
        let port = match SensorKind::from_u32(kind) {
            Some(SensorKind::Depth) => {
                SensorPort::Depth(sensor_publisher(node, &service, elements, readers)?)
            }
            Some(SensorKind::Lidar) => {
                SensorPort::Lidar(sensor_publisher(node, &service, elements, readers)?)
            }
            Some(SensorKind::Imu) => {
                SensorPort::Imu(sensor_publisher(node, &service, elements, readers)?)
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
            SensorPort::Lidar(p) => publish(p, header, payload),
            SensorPort::Imu(p) => publish(p, header, payload),
        };
        if header.end().is_some() {
            self.ports.remove(&id);
        }
        published
    }
}

/// Wakes the mirror's main thread (blocked in [`LocalServices::wait`])
/// from any thread: Zenoh's callbacks call it after queueing an event.
/// iceoryx2 ports stay on the thread that made them, so each calling thread
/// opens its own notifier once.
pub(super) fn wake(names: &ServiceNames) {
    thread_local! {
        static NOTIFIER: std::cell::RefCell<Option<(Node<Bus>, Notifier<Bus>)>> =
            const { std::cell::RefCell::new(None) };
    }
    NOTIFIER.with(|cell| {
        let mut cell = cell.borrow_mut();
        if cell.is_none() {
            match wake_notifier(names) {
                Ok(ports) => *cell = Some(ports),
                Err(e) => tracing::warn!("cannot wake the mirror from this thread: {}", Chain(&e)),
            }
        }
        if let Some((_, notifier)) = cell.as_ref() {
            if let Err(e) = notifier.notify() {
                tracing::debug!("wake-up not delivered: {e:?}");
            }
        }
    });
}

fn wake_notifier(names: &ServiceNames) -> Result<(Node<Bus>, Notifier<Bus>), LocalError> {
    let node = node("zenoh-mirror-wake")?;
    let notifier = wake_notifier_on(&node, names)?;
    Ok((node, notifier))
}

/// A notifier of the world's wake-up event (what clients notify after a
/// request) on `node`.
pub(crate) fn wake_notifier_on(
    node: &Node<Bus>,
    names: &ServiceNames,
) -> Result<Notifier<Bus>, LocalError> {
    node.service_builder(&name(&names.control_wake)?)
        .event()
        .open()
        .map_err(|e| LocalError::transport("wake-up event", e))?
        .notifier_builder()
        .create()
        .map_err(|e| LocalError::transport("wake-up notifier", e))
}
