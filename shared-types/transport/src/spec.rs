//! One description of every service of a world: its name, payload types,
//! limits, history, overflow and buffer sizes. The server's domains, the
//! client library and the Zenoh mirror create and open each service from
//! its description, so no builder setting is written twice.
//!
//! A description ([`RequestSpec`], [`PubSubSpec`], [`EventSpec`]) holds the
//! limits as [`Limit`]s, resolved against the server's [`WorldLimits`] when
//! the service is created; opening needs no limits (a client does not know
//! the server's flags) and checks the payload types.

use core::fmt::Debug;
use core::marker::PhantomData;

use iceoryx2::node::Node;
use iceoryx2::prelude::{Alignment, AllocationStrategy, IceoryxSend, ServiceName};
use iceoryx2::service::builder::publish_subscribe::{
    Builder as PubSubBuilder, PublishSubscribeCreateError, PublishSubscribeOpenError,
    PublishSubscribeOpenOrCreateError,
};
use iceoryx2::service::builder::request_response::{
    Builder as RequestBuilder, RequestResponseCreateError, RequestResponseOpenError,
    RequestResponseOpenOrCreateError,
};
use iceoryx2::service::port_factory::{publish_subscribe, request_response};
use iceoryx2::service::service_name::ServiceNameError;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;

use crate::bus::Bus;
pub use crate::event_spec::EventSpec;
pub use crate::limit::Limit;
use shared_types::limits::{
    WorldLimits, FRAME_SUBSCRIBER_BORROWED, FRAME_SUBSCRIBER_BUFFER, INITIAL_MAX_BATCH,
    MAX_BATCHES_IN_FLIGHT, SENSOR_SUBSCRIBER_BUFFER,
};
use shared_types::{
    ActorState, BatchHeader, BatchResponseHeader, Command, CommandResult, ControlRequest,
    ControlResponse, DebugRequest, DebugResponseHeader, DebugShape, Doorbell, FrameHeader,
    LockstepRequest, LockstepResponse, RecorderRequest, RecorderResponse, SensorHeader, SensorInfo,
    SensorRequest, SensorResponseHeader, ServiceNames, TickRequest, TickResponse,
};

/// The payload types a description stands for (it holds none).
type Types<Req, ReqHeader, Resp, RespHeader> =
    PhantomData<fn(&Req, &Resp) -> (ReqHeader, RespHeader)>;

/// A request-response service: one server, `clients` clients.
pub struct RequestSpec<Req: ?Sized, ReqHeader, Resp: ?Sized, RespHeader> {
    /// The service's name.
    pub name: ServiceName,
    /// Client ports admitted.
    pub clients: Limit,
    /// Requests one client may have in flight.
    pub active_requests: usize,
    /// Responses buffered per request.
    pub response_buffer: usize,
    /// Whether a client may drop a request's answer unread.
    pub fire_and_forget: bool,
    /// Whether a new request displaces the oldest unread one (`false`: the
    /// sender waits).
    pub safe_overflow_for_requests: bool,
    /// Elements reserved in the first sample of a slice payload (it grows
    /// as needed).
    pub initial_slice_len: usize,
    /// The event id a client rings on the wake-up event after a request.
    pub doorbell: Doorbell,
    types: Types<Req, ReqHeader, Resp, RespHeader>,
}

impl<Req: ?Sized, ReqHeader, Resp: ?Sized, RespHeader> Debug
    for RequestSpec<Req, ReqHeader, Resp, RespHeader>
{
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("RequestSpec")
            .field("name", &self.name.as_str())
            .field("clients", &self.clients)
            .field("active_requests", &self.active_requests)
            .field("response_buffer", &self.response_buffer)
            .field("fire_and_forget", &self.fire_and_forget)
            .field(
                "safe_overflow_for_requests",
                &self.safe_overflow_for_requests,
            )
            .field("doorbell", &self.doorbell)
            .finish()
    }
}

impl<Req, ReqHeader, Resp, RespHeader> RequestSpec<Req, ReqHeader, Resp, RespHeader>
where
    Req: Debug + IceoryxSend + ?Sized + 'static,
    ReqHeader: Debug + ZeroCopySend + 'static,
    Resp: Debug + IceoryxSend + ?Sized + 'static,
    RespHeader: Debug + ZeroCopySend + 'static,
{
    fn new(
        name: &str,
        doorbell: Doorbell,
        clients: Limit,
        active_requests: usize,
        response_buffer: usize,
    ) -> Result<Self, ServiceNameError> {
        Ok(Self {
            name: ServiceName::new(name)?,
            clients,
            active_requests,
            response_buffer,
            fire_and_forget: true,
            safe_overflow_for_requests: true,
            initial_slice_len: 1,
            doorbell,
            types: PhantomData,
        })
    }

    /// The builder with the service's types (what opening checks).
    fn typed(&self, node: &Node<Bus>) -> RequestBuilder<Req, ReqHeader, Resp, RespHeader, Bus> {
        node.service_builder(&self.name)
            .request_response::<Req, Resp>()
            .request_user_header::<ReqHeader>()
            .response_user_header::<RespHeader>()
    }

    /// The builder with every setting, limits resolved under `limits`.
    fn configured(
        &self,
        node: &Node<Bus>,
        limits: &WorldLimits,
    ) -> RequestBuilder<Req, ReqHeader, Resp, RespHeader, Bus> {
        self.typed(node)
            .max_servers(1)
            .max_clients(self.clients.of(limits))
            .max_nodes(Limit::Nodes.of(limits))
            .max_active_requests_per_client(self.active_requests)
            .max_response_buffer_size(self.response_buffer)
            .enable_safe_overflow_for_requests(self.safe_overflow_for_requests)
            .enable_fire_and_forget_requests(self.fire_and_forget)
    }
}

/// The port factory of a request service.
pub type RequestFactory<Req, ReqHeader, Resp, RespHeader> =
    request_response::PortFactory<Bus, Req, ReqHeader, Resp, RespHeader>;

macro_rules! request_shape {
    ([$($p:tt)*], $req:ty, $resp:ty) => {
        impl<$($p)*, ReqHeader, RespHeader> RequestSpec<$req, ReqHeader, $resp, RespHeader>
        where
            ReqHeader: Debug + ZeroCopySend + 'static,
            RespHeader: Debug + ZeroCopySend + 'static,
        {
            /// Creates the service (fails if it exists), configured under `limits`.
            ///
            /// # Errors
            ///
            /// Returns [`RequestResponseCreateError::AlreadyExists`] if the
            /// service exists (a server of this world is already running, or a
            /// crashed one left it behind), and iceoryx2's other variants if it
            /// cannot be created (`InsufficientPermissions`,
            /// `IsBeingCreatedByAnotherInstance`, `HangsInCreation`,
            /// `InternalFailure`, ...).
            pub fn create(
                &self,
                node: &Node<Bus>,
                limits: &WorldLimits,
            ) -> Result<RequestFactory<$req, ReqHeader, $resp, RespHeader>, RequestResponseCreateError> {
                self.configured(node, limits).create()
            }

            /// Opens the service, or creates it configured under `limits`.
            ///
            /// # Errors
            ///
            /// Returns
            /// [`RequestResponseOpenOrCreateError::RequestResponseOpenError`]
            /// if the service exists but cannot be opened as described (other
            /// payload types or limits), and
            /// [`RequestResponseOpenOrCreateError::RequestResponseCreateError`]
            /// if it does not exist and cannot be created.
            pub fn open_or_create(
                &self,
                node: &Node<Bus>,
                limits: &WorldLimits,
            ) -> Result<RequestFactory<$req, ReqHeader, $resp, RespHeader>, RequestResponseOpenOrCreateError> {
                self.configured(node, limits).open_or_create()
            }

            /// Opens the existing service (a client's side).
            ///
            /// # Errors
            ///
            /// Returns [`RequestResponseOpenError::DoesNotExist`] if no server
            /// has created the service (no server owns the world),
            /// [`RequestResponseOpenError::IncompatibleRequestOrResponseType`]
            /// if it was created with other payload or header types (a server
            /// of another version),
            /// [`RequestResponseOpenError::ExceedsMaxNumberOfNodes`] if the
            /// world admits no more processes, and iceoryx2's other variants
            /// otherwise.
            pub fn open(
                &self,
                node: &Node<Bus>,
            ) -> Result<RequestFactory<$req, ReqHeader, $resp, RespHeader>, RequestResponseOpenError> {
                self.typed(node).open()
            }
        }
    };
}
request_shape!([Req: Debug + ZeroCopySend + 'static, Resp: Debug + ZeroCopySend + 'static], Req, Resp);
request_shape!([Req: Debug + ZeroCopySend + 'static, Resp: Debug + ZeroCopySend + 'static], Req, [Resp]);
request_shape!([Req: Debug + ZeroCopySend + 'static, Resp: Debug + ZeroCopySend + 'static], [Req], [Resp]);

impl<Req, ReqHeader, Resp, RespHeader> RequestSpec<Req, ReqHeader, [Resp], RespHeader>
where
    Req: Debug + IceoryxSend + ?Sized + 'static,
    ReqHeader: Debug + ZeroCopySend + 'static,
    Resp: Debug + ZeroCopySend + 'static,
    RespHeader: Debug + ZeroCopySend + 'static,
{
    /// The server port of a slice answer, its memory growing as needed.
    ///
    /// # Errors
    ///
    /// Returns `ServerCreateError::ExceedsMaxSupportedServers` if the service
    /// already has its one server, and iceoryx2's other variants if the port or
    /// its data segment cannot be created.
    pub fn server(
        &self,
        factory: &RequestFactory<Req, ReqHeader, [Resp], RespHeader>,
    ) -> Result<
        iceoryx2::port::server::Server<Bus, Req, ReqHeader, [Resp], RespHeader>,
        iceoryx2::service::port_factory::server::ServerCreateError,
    > {
        factory
            .server_builder()
            .initial_max_slice_len(self.initial_slice_len)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
    }
}

impl<Req, ReqHeader, Resp, RespHeader> RequestSpec<[Req], ReqHeader, Resp, RespHeader>
where
    Req: Debug + ZeroCopySend + 'static,
    ReqHeader: Debug + ZeroCopySend + 'static,
    Resp: Debug + IceoryxSend + ?Sized + 'static,
    RespHeader: Debug + ZeroCopySend + 'static,
{
    /// The client port of a slice request, its memory growing as needed.
    ///
    /// # Errors
    ///
    /// Returns `ClientCreateError::ExceedsMaxSupportedClients` if the service
    /// already has as many clients as it admits (`--max-clients`), and
    /// iceoryx2's other variants if the port or its data segment cannot be
    /// created.
    pub fn client(
        &self,
        factory: &RequestFactory<[Req], ReqHeader, Resp, RespHeader>,
    ) -> Result<
        iceoryx2::port::client::Client<Bus, [Req], ReqHeader, Resp, RespHeader>,
        iceoryx2::service::port_factory::client::ClientCreateError,
    > {
        factory
            .client_builder()
            .initial_max_slice_len(self.initial_slice_len)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
    }
}

/// A publish-subscribe service of a slice of `T` with a `Header`: one
/// publisher.
pub struct PubSubSpec<T, Header> {
    /// The service's name.
    pub name: ServiceName,
    /// Subscriber ports admitted.
    pub subscribers: Limit,
    /// Nodes that may open the service.
    pub nodes: Limit,
    /// Samples a subscriber may have queued.
    pub subscriber_buffer: usize,
    /// Samples a subscriber may hold at once.
    pub subscriber_borrowed: usize,
    /// Samples a new subscriber gets at once (the latest ones).
    pub history: usize,
    /// Whether a full subscriber queue drops its oldest sample (the
    /// publisher never waits).
    pub safe_overflow: bool,
    /// The payload's alignment, if above its type's.
    pub alignment: Option<usize>,
    /// Samples the publisher may loan at once.
    pub loaned_samples: usize,
    /// Whether the publisher's samples grow (doubling) past their initial
    /// length: frames do (actors are spawned); a sensor's captures have
    /// one size for its life, and a fixed segment outlives the publisher
    /// long enough for its readers to take its last sample (the end of
    /// stream, sent just before the sensor's port goes).
    pub growable: bool,
    types: PhantomData<fn(&T) -> Header>,
}

impl<T, Header> Debug for PubSubSpec<T, Header> {
    fn fmt(&self, f: &mut core::fmt::Formatter<'_>) -> core::fmt::Result {
        f.debug_struct("PubSubSpec")
            .field("name", &self.name.as_str())
            .field("subscribers", &self.subscribers)
            .field("history", &self.history)
            .field("safe_overflow", &self.safe_overflow)
            .finish()
    }
}

/// The port factory of a publish-subscribe service of a slice.
pub type PubSubFactory<T, Header> = publish_subscribe::PortFactory<Bus, [T], Header>;

impl<T, Header> PubSubSpec<T, Header>
where
    T: Debug + ZeroCopySend + 'static,
    Header: Debug + ZeroCopySend + 'static,
{
    fn typed(&self, node: &Node<Bus>) -> PubSubBuilder<[T], Header, Bus> {
        let builder = node
            .service_builder(&self.name)
            .publish_subscribe::<[T]>()
            .user_header::<Header>();
        match self.alignment.and_then(Alignment::new) {
            Some(alignment) => builder.payload_alignment(alignment),
            None => builder,
        }
    }

    fn configured(
        &self,
        node: &Node<Bus>,
        limits: &WorldLimits,
    ) -> PubSubBuilder<[T], Header, Bus> {
        self.typed(node)
            .max_publishers(1)
            .max_subscribers(self.subscribers.of(limits))
            .subscriber_max_buffer_size(self.subscriber_buffer)
            .subscriber_max_borrowed_samples(self.subscriber_borrowed)
            .history_size(self.history)
            .enable_safe_overflow(self.safe_overflow)
            .max_nodes(self.nodes.of(limits))
    }

    /// Creates the service (fails if it exists), configured under `limits`.
    ///
    /// # Errors
    ///
    /// Returns [`PublishSubscribeCreateError::AlreadyExists`] if the service
    /// exists (a server of this world is already running, or a crashed one left
    /// it behind), and iceoryx2's other variants if it cannot be created
    /// (`InsufficientPermissions`, `IsBeingCreatedByAnotherInstance`,
    /// `InternalFailure`, ...).
    pub fn create(
        &self,
        node: &Node<Bus>,
        limits: &WorldLimits,
    ) -> Result<PubSubFactory<T, Header>, PublishSubscribeCreateError> {
        self.configured(node, limits).create()
    }

    /// Opens the service, or creates it configured under `limits`.
    ///
    /// # Errors
    ///
    /// Returns [`PublishSubscribeOpenOrCreateError::PublishSubscribeOpenError`]
    /// if the service exists but cannot be opened as described (other payload
    /// types or limits), and
    /// [`PublishSubscribeOpenOrCreateError::PublishSubscribeCreateError`] if it
    /// does not exist and cannot be created.
    pub fn open_or_create(
        &self,
        node: &Node<Bus>,
        limits: &WorldLimits,
    ) -> Result<PubSubFactory<T, Header>, PublishSubscribeOpenOrCreateError> {
        self.configured(node, limits).open_or_create()
    }

    /// Opens the existing service (a reader's side).
    ///
    /// # Errors
    ///
    /// Returns [`PublishSubscribeOpenError::DoesNotExist`] if nobody has
    /// created the service (no server owns the world, or the sensor is gone),
    /// [`PublishSubscribeOpenError::IncompatibleTypes`] if it was created with
    /// another payload, header or alignment (a server of another version), and
    /// iceoryx2's other variants otherwise
    /// (`DoesNotSupportRequestedAmountOfNodes`, `InsufficientPermissions`,
    /// ...).
    pub fn open(
        &self,
        node: &Node<Bus>,
    ) -> Result<PubSubFactory<T, Header>, PublishSubscribeOpenError> {
        self.typed(node).open()
    }

    /// The publisher, with `initial_len` elements reserved in its first
    /// sample (it grows as needed).
    ///
    /// # Errors
    ///
    /// Returns `PublisherCreateError::ExceedsMaxSupportedPublishers` if the
    /// service already has its one publisher, and iceoryx2's other variants if
    /// the port or its data segment cannot be created.
    pub fn publisher(
        &self,
        factory: &PubSubFactory<T, Header>,
        initial_len: usize,
    ) -> Result<
        iceoryx2::port::publisher::Publisher<Bus, [T], Header>,
        iceoryx2::port::publisher::PublisherCreateError,
    > {
        let builder = factory
            .publisher_builder()
            .initial_max_slice_len(initial_len.max(1))
            .max_loaned_samples(self.loaned_samples);
        if self.growable {
            builder
                .allocation_strategy(AllocationStrategy::PowerOfTwo)
                .create()
        } else {
            builder.create()
        }
    }

    /// A subscriber that may queue the service's whole buffer.
    ///
    /// # Errors
    ///
    /// Returns `SubscriberCreateError::ExceedsMaxSupportedSubscribers` if the
    /// service already has as many subscribers as it admits (`--max-clients`
    /// for frames, `--max-sensor-readers` for a sensor), and iceoryx2's other
    /// variants if the port cannot be created.
    pub fn subscriber(
        &self,
        factory: &PubSubFactory<T, Header>,
    ) -> Result<
        iceoryx2::port::subscriber::Subscriber<Bus, [T], Header>,
        iceoryx2::port::subscriber::SubscriberCreateError,
    > {
        factory
            .subscriber_builder()
            .buffer_size(self.subscriber_buffer)
            .create()
    }
}

/// The frames: one sample per frame, the current one kept for every new
/// subscriber.
pub type FramesSpec = PubSubSpec<ActorState, FrameHeader>;
/// A sensor's captures.
pub type SensorSpec<T> = PubSubSpec<T, SensorHeader>;
/// The control service.
pub type ControlSpec = RequestSpec<ControlRequest, (), ControlResponse, ()>;
/// The tick service.
pub type TickSpec = RequestSpec<TickRequest, (), TickResponse, ()>;
/// The batch service.
pub type BatchSpec = RequestSpec<[Command], BatchHeader, [CommandResult], BatchResponseHeader>;
/// The lockstep service.
pub type LockstepSpec = RequestSpec<LockstepRequest, (), LockstepResponse, ()>;
/// The sensor service (spawn, destroy, list).
pub type SensorsSpec = RequestSpec<SensorRequest, (), [SensorInfo], SensorResponseHeader>;
/// The recorder service (recorder and replayer).
pub type RecorderSpec = RequestSpec<RecorderRequest, (), RecorderResponse, ()>;
/// The debug-drawing service (draw, list, clear).
pub type DebugSpec = RequestSpec<DebugRequest, (), [DebugShape], DebugResponseHeader>;

/// Every service of one world, described once.
#[derive(Debug)]
pub struct WorldServices {
    /// Frames ([`ServiceNames::frames`]).
    pub frames: FramesSpec,
    /// Notified after every frame ([`ServiceNames::frame_ready`]).
    pub frame_ready: EventSpec,
    /// Control requests ([`ServiceNames::control`]).
    pub control: ControlSpec,
    /// Notified by clients after a request ([`ServiceNames::control_wake`]).
    pub control_wake: EventSpec,
    /// Ticks ([`ServiceNames::tick`]).
    pub tick: TickSpec,
    /// Command batches ([`ServiceNames::batch`]).
    pub batch: BatchSpec,
    /// Lockstep participants ([`ServiceNames::lockstep`]).
    pub lockstep: LockstepSpec,
    /// Sensor requests ([`ServiceNames::sensors`]).
    pub sensors: SensorsSpec,
    /// Recorder requests ([`ServiceNames::recorder`]).
    pub recorder: RecorderSpec,
    /// Debug drawing ([`ServiceNames::debug`]).
    pub debug: DebugSpec,
    names: ServiceNames,
}

impl WorldServices {
    /// The services of the world named by `names`.
    ///
    /// # Errors
    ///
    /// Returns the [`ServiceNameError`] of the first name in `names` that is
    /// not a valid iceoryx2 service name (`InvalidContent`,
    /// `ExceedsMaximumLength`).
    pub fn new(names: &ServiceNames) -> Result<Self, ServiceNameError> {
        let frames = PubSubSpec {
            name: ServiceName::new(&names.frames)?,
            subscribers: Limit::Clients,
            nodes: Limit::Nodes,
            subscriber_buffer: FRAME_SUBSCRIBER_BUFFER,
            subscriber_borrowed: FRAME_SUBSCRIBER_BORROWED,
            history: 1,
            safe_overflow: true,
            alignment: None,
            loaned_samples: 2,
            growable: true,
            types: PhantomData,
        };
        let event = |name: &str, notifiers, max_event_id| -> Result<EventSpec, ServiceNameError> {
            Ok(EventSpec {
                name: ServiceName::new(name)?,
                listeners: Limit::EventListeners,
                notifiers,
                max_event_id,
            })
        };
        let mut batch = RequestSpec::new(
            &names.batch,
            Doorbell::Batch,
            Limit::Clients,
            MAX_BATCHES_IN_FLIGHT,
            1,
        )?;
        // A batch is never dropped: a sender that outruns the server waits.
        batch.safe_overflow_for_requests = false;
        batch.initial_slice_len = INITIAL_MAX_BATCH;
        let mut sensors =
            RequestSpec::new(&names.sensors, Doorbell::Sensors, Limit::Clients, 2, 1)?;
        sensors.initial_slice_len = 16;
        // A list answers every shape kept: the answer's memory grows with
        // them.
        let mut debug = RequestSpec::new(&names.debug, Doorbell::Debug, Limit::Clients, 4, 2)?;
        debug.initial_slice_len = 64;
        Ok(Self {
            frames,
            frame_ready: event(&names.frame_ready, Limit::Fixed(4), 0)?,
            control: RequestSpec::new(&names.control, Doorbell::Control, Limit::Clients, 2, 2)?,
            control_wake: event(&names.control_wake, Limit::Clients, Doorbell::MAX_ID)?,
            // Four tick clients: the ticker, a dead ticker's port waiting
            // for cleanup (a new ticker connects meanwhile) and two standby
            // tickers (ownership, not the port count, admits one ticker).
            tick: RequestSpec::new(&names.tick, Doorbell::Tick, Limit::Fixed(4), 4, 4)?,
            batch,
            lockstep: RequestSpec::new(&names.lockstep, Doorbell::Lockstep, Limit::Clients, 4, 2)?,
            sensors,
            recorder: RequestSpec::new(&names.recorder, Doorbell::Recorder, Limit::Clients, 2, 2)?,
            debug,
            names: names.clone(),
        })
    }

    /// The captures of sensor `id`, a slice of `T` (its kind's element).
    ///
    /// # Errors
    ///
    /// Returns a [`ServiceNameError`] if the sensor's service name is not a
    /// valid iceoryx2 service name (`InvalidContent`, `ExceedsMaximumLength`).
    pub fn sensor<T>(&self, id: u64) -> Result<SensorSpec<T>, ServiceNameError> {
        Ok(PubSubSpec {
            name: ServiceName::new(&self.names.sensor(id))?,
            subscribers: Limit::SensorReaders,
            nodes: Limit::SensorNodes,
            subscriber_buffer: SENSOR_SUBSCRIBER_BUFFER,
            subscriber_borrowed: 2,
            history: 0,
            safe_overflow: true,
            alignment: Some(16),
            loaned_samples: 1,
            growable: false,
            types: PhantomData,
        })
    }
}
