//! Opening a world's services from a client, waiting while the server is
//! still creating them.

use std::time::{Duration, Instant};

use iceoryx2::port::listener::Listener;
use iceoryx2::port::notifier::Notifier;
use iceoryx2::prelude::*;
use iceoryx2::service::builder::event::EventOpenError;
use iceoryx2::service::port_factory::event::PortFactory as EventService;
use shared_types::ServiceNames;

/// Opens a service, retrying while `is_missing` says it does not exist yet,
/// until `deadline`. `Ok(None)` when it never appeared.
pub(crate) fn open_with_retry<T, E: std::fmt::Debug>(
    deadline: Instant,
    mut open: impl FnMut() -> Result<T, E>,
    is_missing: impl Fn(&E) -> bool,
) -> Result<Option<T>, E> {
    loop {
        match open() {
            Ok(port) => return Ok(Some(port)),
            Err(e) if is_missing(&e) => {
                if Instant::now() >= deadline {
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
    pub detail: String,
}

/// The notifier that wakes an idle server after a request was sent.
/// `Ok(None)` when the world's service did not appear before `deadline`.
pub(crate) fn wake_notifier(
    node: &Node<ipc::Service>,
    names: &ServiceNames,
    deadline: Instant,
) -> Result<Option<Notifier<ipc::Service>>, OpenFailure> {
    open_event(node, &names.control_wake, deadline)?
        .map(|service| service.notifier_builder().create())
        .transpose()
        .map_err(|e| OpenFailure {
            what: "wake-up notifier",
            detail: format!("{e:?}"),
        })
}

/// A listener woken after every published frame (and its captures).
/// `Ok(None)` when the world's service did not appear before `deadline`.
pub(crate) fn frame_ready_listener(
    node: &Node<ipc::Service>,
    names: &ServiceNames,
    deadline: Instant,
) -> Result<Option<Listener<ipc::Service>>, OpenFailure> {
    open_event(node, &names.frame_ready, deadline)?
        .map(|service| service.listener_builder().create())
        .transpose()
        .map_err(|e| OpenFailure {
            what: "frame-ready listener",
            detail: format!("{e:?}"),
        })
}

/// Opens the event service `name`, waiting until `deadline` for it to appear.
fn open_event(
    node: &Node<ipc::Service>,
    name: &str,
    deadline: Instant,
) -> Result<Option<EventService<ipc::Service>>, OpenFailure> {
    let service_name = ServiceName::new(name).map_err(|e| OpenFailure {
        what: "service name",
        detail: format!("{e:?}"),
    })?;
    open_with_retry(
        deadline,
        || node.service_builder(&service_name).event().open(),
        |e| {
            matches!(
                e,
                EventOpenError::DoesNotExist | EventOpenError::HangsInCreation
            )
        },
    )
    .map_err(|e| OpenFailure {
        what: "event service",
        detail: format!("{e:?}"),
    })
}
