//! The export's life across its server's restarts: it waits for the
//! world's server (Ctrl-C ends the wait), exports it, and goes on with a
//! server resumed from the same journal when one comes back in time.

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use sim_client::Client;
use tracing::{info, warn};

use super::{export_once, Ended};
use crate::error::ExportError;
use crate::{Notice, Side};

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
    let Some(mut client) = until_stopped(side.timeout, side.stop, |slice| {
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
        let next = until_stopped(side.timeout, side.stop, |slice| {
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

/// How long one attempt to reach a server waits before the stop flag is
/// looked at again (Ctrl-C while the export waits for its server).
const STOP_CHECK: Duration = Duration::from_millis(200);

/// `connect`, given at most [`STOP_CHECK`] per attempt, until it reaches a
/// server, `timeout` has passed (then its last error, with the whole
/// `timeout` in it) or `stop` is set (`None`).
fn until_stopped(
    timeout: Duration,
    stop: &AtomicBool,
    mut connect: impl FnMut(Duration) -> Result<Client, sim_client::ConnectError>,
) -> Result<Option<Client>, sim_client::ConnectError> {
    use sim_client::ConnectError;
    let deadline = Instant::now() + timeout;
    loop {
        if stop.load(Ordering::Relaxed) {
            return Ok(None);
        }
        let slice = deadline
            .saturating_duration_since(Instant::now())
            .min(STOP_CHECK);
        match connect(slice) {
            Ok(client) => return Ok(Some(client)),
            Err(ConnectError::NoServer { .. } | ConnectError::NotAnswering { .. })
                if Instant::now() < deadline => {}
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
