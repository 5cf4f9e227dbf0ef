//! Running one side of a bridge: the Zenoh session opened, then the
//! exporter or the mirror until told to stop.

use std::sync::atomic::AtomicBool;
use std::time::Duration;

use shared_types::WorldName;

use crate::error::BridgeError;
use crate::side::{Notice, Options, Role, Side};
use crate::{export, link, mirror};

/// Runs a bridge of `world` as `role` says until `stop` is set.
///
/// When exporting, it also ends once the server is gone and no server
/// resumed from its journal came back within `timeout`. `notice` is called
/// with what the user should know. `timeout` bounds connecting to the world
/// (exporting) or waiting for the exporter (mirroring).
///
/// # Errors
///
/// Returns [`BridgeError::Link`] if the Zenoh session cannot be opened (a bad
/// endpoint or configuration: nothing started; or the endpoint cannot be
/// listened on or connected to); [`BridgeError::Export`] if the exporter cannot
/// reach the world's server, open its ports or start forwarding, or stops
/// forwarding because the server is gone and none came back within `timeout`;
/// and [`BridgeError::Mirror`] if nothing exports the world at the endpoint,
/// the exporter is of another simbus version, or this host's shared memory
/// cannot hold the world's services (a server or another mirror of it runs
/// here).
pub fn run(
    world: &WorldName,
    timeout: Duration,
    role: Role<'_>,
    options: &Options,
    stop: &AtomicBool,
    notice: &mut dyn FnMut(Notice),
) -> Result<(), BridgeError> {
    let session = link::open(options, role)?;
    let (Role::Export(endpoint) | Role::Mirror(endpoint)) = role;
    let side = Side {
        world,
        timeout,
        endpoint,
        options,
        session,
        stop,
        notice,
    };
    match role {
        Role::Export(_) => export::run(side)?,
        Role::Mirror(_) => mirror::run(side)?,
    }
    Ok(())
}
