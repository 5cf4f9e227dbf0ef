//! Opening a world's services from a client, waiting while the server is
//! still creating them.

use std::sync::atomic::{AtomicBool, Ordering};
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
use crate::{Client, ConnectError, RequestError};

/// How long one attempt of [`connect_until_stopped`] waits before the stop
/// flag is looked at again.
const STOP_CHECK: Duration = Duration::from_millis(200);

/// Calls `connect` until it reaches a server, `timeout` passes or `stop` is set.
///
/// `connect` (e.g. `|slice| Client::connect(world, slice)`) is given at
/// most 200 ms per attempt, until it reaches a server, `timeout` has passed
/// (then its last error, with the whole `timeout` in it) or `stop` is set
/// (`Ok(None)`): a wait for a world's server that Ctrl-C ends, for a
/// program whose signal handler sets `stop`.
///
/// # Errors
///
/// Returns `Ok(None)`, not an error, when `stop` is set. Returns
/// [`ConnectError::NoServer`] or [`ConnectError::NotAnswering`] (with the whole
/// `timeout` in it) if no attempt reached a server before `timeout` passed, and
/// any other error of `connect` at once ([`ConnectError::InvalidWorld`],
/// [`ConnectError::ProtocolMismatch`], ...): only a missing or silent server is
/// waited for.
pub fn connect_until_stopped(
    timeout: Duration,
    stop: &AtomicBool,
    mut connect: impl FnMut(Duration) -> Result<Client, ConnectError>,
) -> Result<Option<Client>, ConnectError> {
    let deadline = Instant::now() + timeout;
    let mut said = false;
    loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(None);
        }
        let slice = deadline
            .saturating_duration_since(Instant::now())
            .min(STOP_CHECK);
        match connect(slice) {
            Ok(client) => return Ok(Some(client)),
            Err(
                ConnectError::NoServer { world, .. } | ConnectError::NotAnswering { world, .. },
            ) if Instant::now() < deadline => {
                if !std::mem::replace(&mut said, true) {
                    tracing::debug!(world, ?timeout, "waiting for the world's server");
                }
            }
            Err(ConnectError::NoServer { world, .. }) => {
                return Err(ConnectError::NoServer { world, timeout })
            }
            Err(ConnectError::NotAnswering { world, .. }) => {
                return Err(ConnectError::NotAnswering { world, timeout })
            }
            Err(e) => return Err(e),
        }
    }
}

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

#[cfg(test)]
mod tests {
    use super::*;

    fn no_server(slice: Duration) -> Result<Client, ConnectError> {
        Err(ConnectError::NoServer {
            world: "w".into(),
            timeout: slice,
        })
    }

    #[test]
    fn a_stop_ends_the_wait_before_another_attempt() {
        let mut attempts = 0;
        let stopped =
            connect_until_stopped(Duration::from_secs(600), &AtomicBool::new(true), |s| {
                attempts += 1;
                no_server(s)
            });
        assert!(matches!(stopped, Ok(None)));
        assert_eq!(attempts, 0);
    }

    #[test]
    fn a_timeout_names_the_whole_wait_not_the_last_attempt() {
        let timeout = Duration::from_millis(450);
        let mut slices = Vec::new();
        let failed = connect_until_stopped(timeout, &AtomicBool::new(false), |s| {
            slices.push(s);
            std::thread::sleep(s);
            no_server(s)
        });
        match failed {
            Err(ConnectError::NoServer { timeout: t, .. }) => assert_eq!(t, timeout),
            other => panic!("{other:?}"),
        }
        // Each attempt gets at most STOP_CHECK, the first all of it.
        assert_eq!(slices.first(), Some(&STOP_CHECK), "{slices:?}");
        assert!(slices.iter().all(|s| *s <= STOP_CHECK), "{slices:?}");
    }
}
