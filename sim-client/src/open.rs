//! Opening a world's services from a client, waiting while the server is
//! still creating them.

use std::time::{Duration, Instant};

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use iceoryx2::service::builder::event::EventOpenError;
use iceoryx2::service::port_factory::event::PortFactory as EventService;
use shared_types::limits::MAX_CLIENTS_FLAG;
use shared_types::ServiceNames;
use simbus_transport::spec::{EventSpec, WorldServices};
use simbus_transport::Bus;

use crate::error::TransportError;
use crate::{ConnectError, RequestError};

/// Opens a service, retrying while `is_missing` says it does not exist yet,
/// until `deadline` or the interrupt check ([`crate::set_interrupt_check`])
/// says to stop. `Ok(None)` when it never appeared.
pub(crate) fn open_with_retry<T, E: std::fmt::Debug>(
    deadline: Instant,
    mut open: impl FnMut() -> Result<T, E>,
    is_missing: impl Fn(&E) -> bool,
) -> Result<Option<T>, E> {
    loop {
        match open() {
            Ok(port) => return Ok(Some(port)),
            Err(e) if is_missing(&e) => {
                if Instant::now() >= deadline || crate::wait::interrupted() {
                    return Ok(None);
                }
                std::thread::sleep(Duration::from_millis(10));
            }
            Err(e) => return Err(e),
        }
    }
}

/// Why opening a service failed, for the callers' own error types.
#[derive(Debug)]
pub(crate) struct OpenFailure {
    pub what: &'static str,
    pub source: TransportError,
    /// The port kind was full: its limit and the flag that raises it.
    pub full: Option<(usize, &'static str)>,
}

impl OpenFailure {
    fn new(what: &'static str, error: impl Into<TransportError>) -> Self {
        Self {
            what,
            source: error.into(),
            full: None,
        }
    }

    /// As a [`ConnectError`] of `world`.
    pub(crate) fn into_connect(self, world: &str) -> ConnectError {
        match self.full {
            Some((max, flag)) => ConnectError::Full {
                world: world.to_owned(),
                what: self.what,
                max,
                flag,
            },
            None => ConnectError::Transport {
                what: self.what,
                source: self.source,
            },
        }
    }

    /// As a [`RequestError`].
    pub(crate) fn into_request(self) -> RequestError {
        match self.full {
            Some((max, flag)) => RequestError::Full {
                what: self.what,
                max,
                flag,
            },
            None => RequestError::Transport {
                what: self.what,
                source: self.source,
            },
        }
    }
}

/// The notifier that wakes an idle server after a request was sent.
/// `Ok(None)` when the world's service did not appear before `deadline`.
pub(crate) fn wake_notifier(
    node: &Node<Bus>,
    names: &ServiceNames,
    deadline: Instant,
) -> Result<Option<Notifier<Bus>>, OpenFailure> {
    use iceoryx2::port::notifier::NotifierCreateError;
    let Some(service) = open_event(node, |s| &s.control_wake, names, deadline)? else {
        return Ok(None);
    };
    let max = service.static_config().max_notifiers();
    service
        .notifier_builder()
        .create()
        .map(Some)
        .map_err(|e| match e {
            NotifierCreateError::ExceedsMaxSupportedNotifiers => OpenFailure {
                full: Some((max, MAX_CLIENTS_FLAG)),
                ..OpenFailure::new("wake-up notifiers (clients that send requests)", e)
            },
            e => OpenFailure::new("wake-up notifier", e),
        })
}

/// A listener woken after every published frame (and its captures).
/// `Ok(None)` when the world's service did not appear before `deadline`.
pub(crate) fn frame_ready_listener(
    node: &Node<Bus>,
    names: &ServiceNames,
    deadline: Instant,
) -> Result<Option<Listener<Bus>>, OpenFailure> {
    use iceoryx2::port::listener::ListenerCreateError;
    let Some(service) = open_event(node, |s| &s.frame_ready, names, deadline)? else {
        return Ok(None);
    };
    let max = service.static_config().max_listeners();
    service
        .listener_builder()
        .create()
        .map(Some)
        .map_err(|e| match e {
            ListenerCreateError::ExceedsMaxSupportedListeners => OpenFailure {
                full: Some((max, MAX_CLIENTS_FLAG)),
                ..OpenFailure::new("frame-ready listeners (clients and sensor readers)", e)
            },
            e => OpenFailure::new("frame-ready listener", e),
        })
}

/// Opens the event service `spec` picks from the world's services (named
/// by `names`), waiting until `deadline` for it to appear.
fn open_event(
    node: &Node<Bus>,
    spec: impl Fn(&WorldServices) -> &EventSpec,
    names: &ServiceNames,
    deadline: Instant,
) -> Result<Option<EventService<Bus>>, OpenFailure> {
    let specs = WorldServices::new(names).map_err(|e| OpenFailure::new("service name", e))?;
    let spec = spec(&specs);
    open_with_retry(
        deadline,
        || spec.open(node),
        |e| {
            matches!(
                e,
                EventOpenError::DoesNotExist | EventOpenError::HangsInCreation
            )
        },
    )
    .map_err(|e| match e {
        EventOpenError::ExceedsMaxNumberOfNodes => OpenFailure::new(
            "event service: more processes than the world admits (raise sim-server --max-clients)",
            e,
        ),
        e => OpenFailure::new("event service", e),
    })
}

/// A node for this process's client ports, after the iceoryx2 environment
/// checks.
pub(crate) fn client_node() -> Result<Node<Bus>, ConnectError> {
    simbus_transport::environment::prepare().map_err(ConnectError::SharedDirectory)?;
    simbus_transport::node("sim-client").map_err(|e| ConnectError::transport("node", e))
}
