//! The service type every simbus port is built on ([`Bus`]), a process's
//! node on it, and who sent a request.

use core::fmt::Debug;

use iceoryx2_bb_elementary_traits::testing::abandonable::Abandonable;
use iceoryx2_bb_elementary_traits::zero_copy_send::ZeroCopySend;
use iceoryx2_cal::shm_allocator::bump_allocator::BumpAllocator;
use iceoryx2_cal::shm_allocator::pool_allocator::PoolAllocator;
use iceoryx2_cal::{
    arc_sync_policy, bag, dynamic_storage, hash, monitoring, reactor, resizable_shared_memory,
    serialize, shared_memory, static_storage, zero_copy_connection,
};

/// iceoryx2's inter-process service with a futex-backed event (see the
/// module documentation). Use it where iceoryx2's examples write
/// `ipc::Service`.
#[derive(Debug, Clone)]
pub struct Bus {}

impl iceoryx2::service::Service for Bus {
    type StaticStorage = static_storage::recommended::Ipc;
    type ConfigSerializer = serialize::recommended::Recommended;
    type PersistentDynamicStorage<T: Debug + Send + Sync + ZeroCopySend + 'static> =
        dynamic_storage::recommended::PersistentIpc<T>;
    type Bag = bag::recommended::Recommended;
    type DynamicStorage<T: Debug + Send + Sync + ZeroCopySend + 'static> =
        dynamic_storage::recommended::Ipc<T>;
    type ServiceNameHasher = hash::recommended::Recommended;
    type SharedMemory = shared_memory::recommended::Ipc<PoolAllocator>;
    type ResizableSharedMemory = resizable_shared_memory::recommended::Ipc<PoolAllocator>;
    type Connection = zero_copy_connection::recommended::Ipc;
    /// The one difference from `ipc::Service`: a futex in shared memory
    /// instead of a Unix datagram socket.
    type Event = crate::futex::FutexShmCountingBitSet;
    type Monitoring = monitoring::recommended::Ipc;
    type Reactor = reactor::recommended::Ipc;
    type ArcThreadSafetyPolicy<T: Send + Debug + Abandonable> =
        arc_sync_policy::single_threaded::SingleThreaded<T>;
    type BlackboardMgmt<KeyType: Send + Sync + Debug + ZeroCopySend + 'static> =
        dynamic_storage::recommended::Ipc<KeyType>;
    type BlackboardPayload = shared_memory::recommended::Ipc<BumpAllocator>;
    type UniqueId = iceoryx2::unique_id_generator::unique_system_id::UniqueSystemId;
}

impl iceoryx2::service::internal::ServiceInternal<Bus> for Bus {}

/// Why [`node`] could not make a node.
#[derive(Debug, thiserror::Error)]
pub enum NodeError {
    /// The name is not a valid iceoryx2 node name.
    #[error("{name:?} is not a valid node name: {source:?}")]
    Name {
        /// The name given.
        name: String,
        /// Why iceoryx2 refused it.
        source: iceoryx2::prelude::SemanticStringError,
    },
    /// iceoryx2 could not create the node.
    #[error("cannot create an iceoryx2 node: {0:?}")]
    Create(#[source] iceoryx2::node::NodeCreationFailure),
}

/// A node of this process for simbus's ports, named `name`.
///
/// The name is what `iox2 node list` and `sim-client top` show. iceoryx2's
/// signal handling is off: simbus processes handle their own signals. Every
/// simbus process makes its nodes here.
///
/// # Errors
///
/// Returns [`NodeError::Name`] if `name` is not a valid iceoryx2 node name, and
/// [`NodeError::Create`] if iceoryx2 cannot create the node (for instance
/// `InternalError` when another user owns iceoryx2's root directory: call
/// [`environment::prepare`] first for a message that says so).
pub fn node(name: &str) -> Result<iceoryx2::node::Node<Bus>, NodeError> {
    use iceoryx2::prelude::*;
    let node_name = NodeName::new(name).map_err(|source| NodeError::Name {
        name: name.to_owned(),
        source,
    })?;
    NodeBuilder::new()
        .name(&node_name)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<Bus>()
        .map_err(NodeError::Create)
}

/// The process that sent a request, as iceoryx2's port recorded it in the
/// request's header (the sending node's id carries its creator's pid), not
/// as the request's payload claims: a client cannot name another process.
/// 0 when the transport cannot say.
pub fn sender_pid(header: &iceoryx2::service::header::request_response::RequestHeader) -> u32 {
    use iceoryx2::prelude::*;
    header
        .node_id()
        .pid::<Bus>()
        .map_or(0, |pid| u32::try_from(pid.value()).unwrap_or(0))
}

/// The client ports a request-response service already had when a server
/// opened it: a service outlives its server while clients hold it open,
/// so after a crash and a resume these are the previous server's clients.
/// Their requests were meant for a server that is gone (a batch of
/// commands for its frame, a tick it was to step), so the new server
/// drops them unanswered, and their senders learn that their server is
/// gone as they would had it died before reading them: a client that
/// follows the restart reconnects with new ports.
#[derive(Debug, Default)]
pub struct EarlierClients(Vec<iceoryx2::identifiers::UniqueClientId>);

impl EarlierClients {
    /// The clients `service` has now.
    pub fn of<B: iceoryx2_cal::bag::BagFamily>(
        service: &iceoryx2::service::dynamic_config::request_response::DynamicConfig<B>,
    ) -> Self {
        let mut ids = Vec::new();
        service.list_clients(|client| {
            ids.push(client.client_id);
            iceoryx2::prelude::CallbackProgression::Continue
        });
        Self(ids)
    }

    /// Whether the request with `header` comes from one of them.
    pub fn sent(
        &self,
        header: &iceoryx2::service::header::request_response::RequestHeader,
    ) -> bool {
        !self.0.is_empty() && self.0.contains(&header.client_id())
    }
}
