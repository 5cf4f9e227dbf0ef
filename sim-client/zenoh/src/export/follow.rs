//! The export's life across its server's restarts: it waits for the
//! world's server (Ctrl-C ends the wait), exports it, and goes on with a
//! server resumed from the same journal when one comes back in time.

use sim_client::Client;
use tracing::{info, warn};

use super::{export_once, Ended};
use crate::error::ExportError;
use crate::side::{Notice, Side};

/// Exports `world` on `session` until `stop`. When the server exits and
/// one resumed from its journal (`sim-server --resume DIR`: the same run)
/// comes back within the timeout, the export goes on with it: its
/// liveliness token goes and comes back (a mirror answers its local
/// clients `Unreachable` in between, as when the link drops), the remote
/// ticker that owned the world owns it again, and frames go on from the
/// frame the world resumed at. A server that does not come back, or a new
/// run, ends the export.
pub(crate) fn run(mut side: Side<'_>) -> Result<(), ExportError> {
    info!(world = %side.world, timeout = ?side.timeout, "waiting for the world's server");
    // Its own copy: `side` is lent mutably to each export below.
    let world = side.world.clone();
    let Some(mut client) = sim_client::connect_until_stopped(side.timeout, side.stop, |slice| {
        Client::connect(world.as_str(), slice)
    })?
    else {
        return Ok(());
    };
    let mut claim_for = None;
    let mut first = true;
    loop {
        let (error, server_pid, run_pid, owner) =
            match export_once(&mut side, client, claim_for.take(), first) {
                Ended::Done(result) => return result,
                Ended::ServerGone {
                    error,
                    server_pid,
                    run_pid,
                    owner,
                } => (error, server_pid, run_pid, owner),
            };
        first = false;
        info!(world = %side.world, server_pid, timeout = ?side.timeout, "the server exited; waiting for it to resume");
        let next = sim_client::connect_until_stopped(side.timeout, side.stop, |slice| {
            Client::connect_next(world.as_str(), server_pid, slice)
        });
        let next = match next {
            Ok(Some(next)) => next,
            Ok(None) => return Ok(()),
            Err(_) => return Err(error),
        };
        let resumed = next.status()?;
        if resumed.run_pid != run_pid {
            warn!(world = %side.world, server_pid = resumed.server_pid, "a new run began on the world (not resumed from the journal): the export ends");
            return Err(error);
        }
        (side.notice)(Notice::Resumed {
            world: side.world.clone(),
            server_pid: resumed.server_pid,
            previous_pid: server_pid,
            frame: resumed.frame,
        });
        client = next;
        claim_for = owner;
    }
}
