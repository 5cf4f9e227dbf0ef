//! What every domain needs to open its iceoryx2 ports: the server's node
//! (created once, after removing what dead processes left behind) and the
//! world's service descriptions. Each domain opens its own ports.

use iceoryx2::prelude::*;
use shared_types::{ServiceNames, WorldName};
use simbus_transport::spec::WorldServices;
use simbus_transport::Bus;
use tracing::{info, warn};

use crate::error::PortError;

/// The server's node and the descriptions of its world's services.
#[derive(Debug)]
pub(crate) struct Transport {
    /// The server's iceoryx2 node (named `sim-server`).
    pub node: Node<Bus>,
    /// The world's services, each described once.
    pub services: WorldServices,
}

impl Transport {
    /// Creates the server's node for `world`, removing what dead processes
    /// left behind (a crashed predecessor's services included).
    pub(crate) fn open(world: &WorldName) -> Result<Self, PortError> {
        simbus_transport::environment::prepare().map_err(PortError::SharedDirectory)?;
        // Count the dead first so the log says it happened.
        let mut dead = 0u32;
        let _ = Node::<Bus>::list(Config::global_config(), |state| {
            if let NodeState::Dead(_) = state {
                dead += 1;
            }
            CallbackProgression::Continue
        });
        if dead > 0 {
            info!("removing resources left by {dead} dead process(es)");
        }
        let node =
            simbus_transport::node("sim-server").map_err(|e| PortError::transport("node", e))?;
        let cleanup = node.try_cleanup_dead_nodes();
        if cleanup.failed_cleanups > 0 {
            warn!(
                failed = cleanup.failed_cleanups,
                "could not remove the resources of some dead processes (permissions?)"
            );
        }
        let names = ServiceNames::new(world);
        let services =
            WorldServices::new(&names).map_err(|e| PortError::transport("service name", e))?;
        Ok(Self { node, services })
    }
}

pub(crate) use simbus_transport::sender_pid;
