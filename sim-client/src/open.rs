//! Opening a world's services from a client, waiting while the server is
//! still creating them.

use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use iceoryx2::service::builder::event::EventOpenError;
use iceoryx2::service::port_factory::event::PortFactory as EventService;

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

/// Opens the event service `name`, waiting until `deadline` for it to appear.
pub(crate) fn open_event(
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
