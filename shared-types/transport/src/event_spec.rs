//! An event service's description: created by the server and the mirror,
//! opened by clients.

use iceoryx2::node::Node;
use iceoryx2::prelude::ServiceName;
use iceoryx2::service::builder::event::{EventCreateError, EventOpenError, EventOpenOrCreateError};
use iceoryx2::service::port_factory::event;
use shared_types::limits::WorldLimits;

use crate::bus::Bus;
use crate::limit::Limit;

/// An event service.
#[derive(Debug, Clone)]
pub struct EventSpec {
    /// The service's name.
    pub name: ServiceName,
    /// Listener ports admitted.
    pub listeners: Limit,
    /// Notifier ports admitted.
    pub notifiers: Limit,
    /// The largest event id rung: 0 for an event that says only "now",
    /// [`Doorbell::MAX_ID`] for the wake-up event (which service holds a
    /// request).
    pub max_event_id: usize,
}

impl EventSpec {
    fn configured(
        &self,
        node: &Node<Bus>,
        limits: &WorldLimits,
    ) -> iceoryx2::service::builder::event::Builder<Bus> {
        node.service_builder(&self.name)
            .event()
            // As few event ids as are rung: a listener's wait or check
            // drains one counter per id, and iceoryx2's default of 256 cost
            // ~2 µs on every wait and every doorbell look.
            .event_id_max_value(self.max_event_id)
            .max_listeners(self.listeners.of(limits))
            .max_notifiers(self.notifiers.of(limits))
            .max_nodes(Limit::Nodes.of(limits))
    }

    /// Creates the service (fails if it exists), configured under `limits`.
    ///
    /// # Errors
    ///
    /// Returns [`EventCreateError::AlreadyExists`] if the service exists, and
    /// iceoryx2's other variants if it cannot be created
    /// (`InsufficientPermissions`, `IsBeingCreatedByAnotherInstance`,
    /// `InternalFailure`, ...).
    pub fn create(
        &self,
        node: &Node<Bus>,
        limits: &WorldLimits,
    ) -> Result<event::PortFactory<Bus>, EventCreateError> {
        self.configured(node, limits).create()
    }

    /// Opens the service, or creates it configured under `limits`.
    ///
    /// # Errors
    ///
    /// Returns [`EventOpenOrCreateError::EventOpenError`] if the service exists
    /// but cannot be opened, and [`EventOpenOrCreateError::EventCreateError`]
    /// if it does not exist and cannot be created.
    pub fn open_or_create(
        &self,
        node: &Node<Bus>,
        limits: &WorldLimits,
    ) -> Result<event::PortFactory<Bus>, EventOpenOrCreateError> {
        self.configured(node, limits).open_or_create()
    }

    /// Opens the existing service.
    ///
    /// # Errors
    ///
    /// Returns [`EventOpenError::DoesNotExist`] if nobody has created the
    /// service (no server owns the world), and iceoryx2's other variants if it
    /// cannot be opened (`InsufficientPermissions`, `HangsInCreation`,
    /// `InternalFailure`, ...).
    pub fn open(&self, node: &Node<Bus>) -> Result<event::PortFactory<Bus>, EventOpenError> {
        node.service_builder(&self.name).event().open()
    }
}
