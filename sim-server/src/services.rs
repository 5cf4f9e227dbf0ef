//! The server's iceoryx2 ports for one world: frame publisher, frame-ready
//! notifier, control server and its wake-up listener.

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::port::publisher::Publisher;
use iceoryx2::port::server::Server;
use iceoryx2::prelude::*;
use shared_types::limits::{
    WorldLimits, FRAME_SUBSCRIBER_BORROWED, FRAME_SUBSCRIBER_BUFFER, INITIAL_MAX_ACTORS,
    INITIAL_MAX_BATCH, MAX_BATCHES_IN_FLIGHT,
};
use shared_types::{
    ActorState, BatchHeader, BatchResponseHeader, Command, CommandResult, ControlRequest,
    ControlResponse, FrameHeader, LockstepRequest, LockstepResponse, SensorInfo, SensorRequest,
    SensorResponseHeader, ServiceNames, TickRequest, TickResponse, WorldName,
};
use tracing::{info, warn};

use crate::ServerError;

/// The publisher of frame snapshots.
pub type FramePublisher = Publisher<ipc::Service, [ActorState], FrameHeader>;
/// The server end of the control service.
pub type ControlServer = Server<ipc::Service, ControlRequest, (), ControlResponse, ()>;
/// The server end of the tick service.
pub type TickServer = Server<ipc::Service, TickRequest, (), TickResponse, ()>;
/// The server end of the batch service.
pub type BatchServer =
    Server<ipc::Service, [Command], BatchHeader, [CommandResult], BatchResponseHeader>;
/// The server end of the sensor service.
pub type SensorServer = Server<ipc::Service, SensorRequest, (), [SensorInfo], SensorResponseHeader>;
/// The server end of the lockstep service.
pub type LockstepServer = Server<ipc::Service, LockstepRequest, (), LockstepResponse, ()>;

/// Every port the server holds for its world.
pub struct ServerPorts {
    /// The server's iceoryx2 node (named `sim-server`).
    pub node: Node<ipc::Service>,
    /// Frame snapshots.
    pub frames: FramePublisher,
    /// Notified after every published frame.
    pub frame_ready: Notifier<ipc::Service>,
    /// Control requests.
    pub control: ControlServer,
    /// Woken by clients after they send a control or tick request.
    pub control_wake: Listener<ipc::Service>,
    /// Requests from the ticker (the service admits one client).
    pub tick: TickServer,
    /// Command batches.
    pub batch: BatchServer,
    /// Lockstep participants.
    pub lockstep: LockstepServer,
    /// Sensor spawn, destroy and list.
    pub sensors: SensorServer,
}

fn service_name(name: &str) -> Result<ServiceName, ServerError> {
    ServiceName::new(name).map_err(|e| ServerError::transport("service name", e))
}

impl ServerPorts {
    /// Creates the node, removes what dead processes left behind, and opens
    /// (or creates) every service of `world`. Fails with
    /// [`ServerError::AlreadyRunning`] when a live server holds the world.
    pub fn open(
        world: &WorldName,
        initial_actors: usize,
        limits: &WorldLimits,
    ) -> Result<Self, ServerError> {
        let (clients, nodes) = (limits.max_clients, limits.nodes());
        shared_types::environment::prepare().map_err(ServerError::SharedDirectory)?;
        let names = ServiceNames::new(world);
        let node_name =
            NodeName::new("sim-server").map_err(|e| ServerError::transport("node name", e))?;
        // Creating a node removes what dead processes left behind; count them
        // first so the log says it happened.
        let mut dead = 0u32;
        let _ = Node::<ipc::Service>::list(Config::global_config(), |state| {
            if let NodeState::Dead(_) = state {
                dead += 1;
            }
            CallbackProgression::Continue
        });
        if dead > 0 {
            info!("removing resources left by {dead} dead process(es)");
        }
        let node = NodeBuilder::new()
            .name(&node_name)
            .signal_handling_mode(SignalHandlingMode::Disabled)
            .create::<ipc::Service>()
            .map_err(|e| ServerError::transport("node", e))?;

        let cleanup = node.try_cleanup_dead_nodes();
        if cleanup.failed_cleanups > 0 {
            warn!(
                failed = cleanup.failed_cleanups,
                "could not remove the resources of some dead processes (permissions?)"
            );
        }

        let control_service = node
            .service_builder(&service_name(&names.control)?)
            .request_response::<ControlRequest, ControlResponse>()
            .max_servers(1)
            .max_clients(clients)
            .max_nodes(nodes)
            .max_active_requests_per_client(2)
            .max_response_buffer_size(2)
            .open_or_create()
            .map_err(|e| ServerError::transport("control service", e))?;
        let control = control_service.server_builder().create().map_err(|e| {
            use iceoryx2::service::port_factory::server::ServerCreateError;
            match e {
                ServerCreateError::ExceedsMaxSupportedServers => ServerError::AlreadyRunning {
                    world: world.to_string(),
                },
                e => ServerError::transport("control server", e),
            }
        })?;

        let tick = node
            .service_builder(&service_name(&names.tick)?)
            .request_response::<TickRequest, TickResponse>()
            .max_servers(1)
            .max_clients(1)
            .max_nodes(nodes)
            .max_active_requests_per_client(4)
            .max_response_buffer_size(4)
            .open_or_create()
            .map_err(|e| ServerError::transport("tick service", e))?
            .server_builder()
            .create()
            .map_err(|e| ServerError::transport("tick server", e))?;

        let batch = node
            .service_builder(&service_name(&names.batch)?)
            .request_response::<[Command], [CommandResult]>()
            .request_user_header::<BatchHeader>()
            .response_user_header::<BatchResponseHeader>()
            .max_servers(1)
            .max_clients(clients)
            .max_nodes(nodes)
            .max_active_requests_per_client(MAX_BATCHES_IN_FLIGHT)
            .max_response_buffer_size(1)
            // A batch is never dropped: a sender that outruns the server waits.
            .enable_safe_overflow_for_requests(false)
            .enable_fire_and_forget_requests(true)
            .open_or_create()
            .map_err(|e| ServerError::transport("batch service", e))?
            .server_builder()
            .initial_max_slice_len(INITIAL_MAX_BATCH)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
            .map_err(|e| ServerError::transport("batch server", e))?;

        let lockstep = node
            .service_builder(&service_name(&names.lockstep)?)
            .request_response::<LockstepRequest, LockstepResponse>()
            .max_servers(1)
            .max_clients(clients)
            .max_nodes(nodes)
            .max_active_requests_per_client(4)
            .max_response_buffer_size(2)
            .enable_fire_and_forget_requests(true)
            .open_or_create()
            .map_err(|e| ServerError::transport("lockstep service", e))?
            .server_builder()
            .create()
            .map_err(|e| ServerError::transport("lockstep server", e))?;

        let sensors = node
            .service_builder(&service_name(&names.sensors)?)
            .request_response::<SensorRequest, [SensorInfo]>()
            .response_user_header::<SensorResponseHeader>()
            .max_servers(1)
            .max_clients(clients)
            .max_nodes(nodes)
            .max_active_requests_per_client(2)
            .max_response_buffer_size(1)
            .open_or_create()
            .map_err(|e| ServerError::transport("sensor service", e))?
            .server_builder()
            .initial_max_slice_len(16)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
            .map_err(|e| ServerError::transport("sensor server", e))?;

        let control_wake = node
            .service_builder(&service_name(&names.control_wake)?)
            .event()
            .max_listeners(limits.event_listeners())
            .max_notifiers(clients)
            .max_nodes(nodes)
            .open_or_create()
            .map_err(|e| ServerError::transport("control wake-up service", e))?
            .listener_builder()
            .create()
            .map_err(|e| ServerError::transport("control wake-up listener", e))?;

        let frames = node
            .service_builder(&service_name(&names.frames)?)
            .publish_subscribe::<[ActorState]>()
            .user_header::<FrameHeader>()
            .max_publishers(1)
            .max_subscribers(clients)
            .subscriber_max_buffer_size(FRAME_SUBSCRIBER_BUFFER)
            .subscriber_max_borrowed_samples(FRAME_SUBSCRIBER_BORROWED)
            .history_size(1)
            .enable_safe_overflow(true)
            .max_nodes(nodes)
            .open_or_create()
            .map_err(|e| ServerError::transport("frames service", e))?
            .publisher_builder()
            .initial_max_slice_len(initial_actors.max(INITIAL_MAX_ACTORS))
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .max_loaned_samples(2)
            .create()
            .map_err(|e| ServerError::transport("frames publisher", e))?;

        let frame_ready = node
            .service_builder(&service_name(&names.frame_ready)?)
            .event()
            .max_listeners(limits.event_listeners())
            .max_notifiers(4)
            .max_nodes(nodes)
            .open_or_create()
            .map_err(|e| ServerError::transport("frame-ready service", e))?
            .notifier_builder()
            .create()
            .map_err(|e| ServerError::transport("frame-ready notifier", e))?;

        Ok(Self {
            node,
            frames,
            frame_ready,
            control,
            control_wake,
            tick,
            batch,
            lockstep,
            sensors,
        })
    }
}
