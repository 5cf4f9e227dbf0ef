//! What both sides of a bridge need from iceoryx2: a node of this process,
//! the world's service descriptions ([`WorldServices`], the one place every
//! builder setting is written) and a notifier of the world's wake-up event.
//! It imports neither side.

use iceoryx2::node::Node;
use iceoryx2::port::notifier::Notifier;
use shared_types::ServiceNames;
use simbus_transport::spec::WorldServices;
use simbus_transport::Bus;

use crate::error::LocalError;

/// A node of this process, named `name`.
pub(crate) fn node(name: &str) -> Result<Node<Bus>, LocalError> {
    simbus_transport::node(name).map_err(|e| LocalError::transport("iceoryx2 node", e))
}

/// The descriptions of the services of the world named by `names`.
pub(crate) fn specs(names: &ServiceNames) -> Result<WorldServices, LocalError> {
    WorldServices::new(names).map_err(|e| LocalError::transport("the world's service names", e))
}

/// A notifier of the world's wake-up event (what clients notify after a
/// request) on `node`.
pub(crate) fn wake_notifier_on(
    node: &Node<Bus>,
    specs: &WorldServices,
) -> Result<Notifier<Bus>, LocalError> {
    specs
        .control_wake
        .open(node)
        .map_err(|e| LocalError::transport("wake-up event", e))?
        .notifier_builder()
        .create()
        .map_err(|e| LocalError::transport("wake-up notifier", e))
}

/// An event of the world that any thread may ring ([`ring`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub(crate) enum Bell {
    /// The world's wake-up (what clients notify after a request): wakes
    /// the mirror, the server of its host.
    Wake,
    /// The world's frame-ready event: wakes the exporter's frame thread
    /// (and every other listener of the host, who find nothing new).
    FrameReady,
}

/// Rings `bell` of the world named by `names` from any thread (a Zenoh
/// callback's, say). iceoryx2 ports stay on the thread that made them, so
/// each calling thread opens its own notifier once and keeps it; a
/// thread that cannot (the event admits no more notifiers) says so once
/// and returns `false` ever after.
pub(crate) fn ring(names: &ServiceNames, bell: Bell) -> bool {
    type Rung = Option<(Node<Bus>, Notifier<Bus>)>;
    thread_local! {
        static NOTIFIERS: std::cell::RefCell<Vec<(Bell, Rung)>> =
            const { std::cell::RefCell::new(Vec::new()) };
    }
    NOTIFIERS.with(|cell| {
        let mut notifiers = cell.borrow_mut();
        let index = match notifiers.iter().position(|(b, _)| *b == bell) {
            Some(index) => index,
            None => {
                let opened = bell_notifier(names, bell)
                    .map_err(|e| {
                        tracing::warn!(
                            ?bell,
                            "cannot ring the world's event from this thread: {}",
                            crate::error::Chain(&e)
                        );
                    })
                    .ok();
                notifiers.push((bell, opened));
                notifiers.len() - 1
            }
        };
        let Some((_, notifier)) = &notifiers[index].1 else {
            return false;
        };
        if let Err(e) = notifier.notify() {
            tracing::debug!(?bell, "not delivered: {e:?}");
        }
        true
    })
}

fn bell_notifier(
    names: &ServiceNames,
    bell: Bell,
) -> Result<(Node<Bus>, Notifier<Bus>), LocalError> {
    let node = node(match bell {
        Bell::Wake => "zenoh-mirror-wake",
        Bell::FrameReady => "zenoh-export-wake",
    })?;
    let specs = specs(names)?;
    let notifier = match bell {
        Bell::Wake => wake_notifier_on(&node, &specs)?,
        Bell::FrameReady => specs
            .frame_ready
            .open(&node)
            .map_err(|e| LocalError::transport("frame-ready event", e))?
            .notifier_builder()
            .create()
            .map_err(|e| LocalError::transport("frame-ready notifier", e))?,
    };
    Ok((node, notifier))
}
