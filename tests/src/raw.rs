//! Raw iceoryx2 ports on a world's services, opened with the wire types
//! as any process of the same user can open them, for the tests that send
//! what no simbus client would (out-of-range codes, forged headers, other
//! protocol versions) or count who holds a port.

use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use iceoryx2::service::port_factory::request_response::PortFactory;
use shared_types::{
    BatchHeader, BatchResponseHeader, Command, CommandResult, ControlRequest, ControlResponse,
    ServiceNames, WorldName,
};
use simbus_transport::Bus;

/// How long a raw request waits for its answer.
const ANSWER: Duration = Duration::from_secs(10);

/// The control service of a world, as its clients open it.
pub type ControlService = PortFactory<Bus, ControlRequest, (), ControlResponse, ()>;

/// The batch service of a world, as its clients open it.
pub type BatchService =
    PortFactory<Bus, [Command], BatchHeader, [CommandResult], BatchResponseHeader>;

/// The service names of `world`.
pub fn service_names(world: &str) -> ServiceNames {
    ServiceNames::new(&WorldName::new(world).expect("world name"))
}

/// `name` as an iceoryx2 service name.
pub fn service_name(name: &str) -> ServiceName {
    ServiceName::new(name).expect("service name")
}

/// Opens the control service of the world named by `names`.
pub fn control_service(node: &Node<Bus>, names: &ServiceNames) -> ControlService {
    node.service_builder(&service_name(&names.control))
        .request_response::<ControlRequest, ControlResponse>()
        .open()
        .expect("the control service")
}

/// Opens the batch service of the world named by `names`.
pub fn batch_service(node: &Node<Bus>, names: &ServiceNames) -> BatchService {
    node.service_builder(&service_name(&names.batch))
        .request_response::<[Command], [CommandResult]>()
        .request_user_header::<BatchHeader>()
        .response_user_header::<BatchResponseHeader>()
        .open()
        .expect("the batch service")
}

/// Raw ports on one world's control and batch services, and the event that
/// wakes its server.
pub struct RawPorts {
    control: iceoryx2::port::client::Client<Bus, ControlRequest, (), ControlResponse, ()>,
    batch: iceoryx2::port::client::Client<
        Bus,
        [Command],
        BatchHeader,
        [CommandResult],
        BatchResponseHeader,
    >,
    wake: iceoryx2::port::notifier::Notifier<Bus>,
    _node: Node<Bus>,
}

impl std::fmt::Debug for RawPorts {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("RawPorts").finish_non_exhaustive()
    }
}

impl RawPorts {
    /// Opens the ports on `world`'s services.
    pub fn open(world: &str) -> Self {
        let names = service_names(world);
        let node = simbus_transport::node("raw-ports").expect("node");
        let control = control_service(&node, &names)
            .client_builder()
            .create()
            .expect("control client");
        let batch = batch_service(&node, &names)
            .client_builder()
            .initial_max_slice_len(64)
            .allocation_strategy(AllocationStrategy::PowerOfTwo)
            .create()
            .expect("batch client");
        let wake = node
            .service_builder(&service_name(&names.control_wake))
            .event()
            .open()
            .expect("the wake event")
            .notifier_builder()
            .create()
            .expect("wake notifier");
        Self {
            control,
            batch,
            wake,
            _node: node,
        }
    }

    /// Sends `request`, wakes the server and returns its answer.
    pub fn control(&self, request: ControlRequest) -> ControlResponse {
        let pending = self.control.send_copy(request).expect("send");
        self.wake.notify().expect("wake");
        let deadline = Instant::now() + ANSWER;
        loop {
            if let Some(response) = pending.receive().expect("receive") {
                return *response.payload();
            }
            assert!(
                Instant::now() < deadline,
                "no answer to {request:?} within {ANSWER:?}"
            );
            std::thread::yield_now();
        }
    }

    /// Sends a batch with `header`, wakes the server and returns the
    /// answer's header and results.
    pub fn batch(
        &self,
        header: BatchHeader,
        commands: &[Command],
    ) -> (BatchResponseHeader, Vec<CommandResult>) {
        let mut request = self
            .batch
            .loan_slice_uninit(commands.len())
            .expect("batch loan");
        *request.user_header_mut() = header;
        let pending = request
            .write_from_slice(commands)
            .send()
            .expect("batch send");
        self.wake.notify().expect("wake");
        let deadline = Instant::now() + ANSWER;
        loop {
            if let Some(response) = pending.receive().expect("receive") {
                return (*response.user_header(), response.payload().to_vec());
            }
            assert!(
                Instant::now() < deadline,
                "no answer to a batch within {ANSWER:?}"
            );
            std::thread::yield_now();
        }
    }
}
