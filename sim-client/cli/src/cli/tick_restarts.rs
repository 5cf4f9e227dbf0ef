//! `sim-client tick` on a journaling world: when its server exits, wait
//! for the server resumed from the journal, claim it again and check that
//! it goes on with the same run (a fresh server ends the ticks).

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use anyhow::anyhow;
use sim_client::{Client, ConnectError, TickError, Ticker, WaitError};

/// Following a journaling world's server through a crash and resume.
#[derive(Debug, Clone, Copy)]
pub(super) struct Restarts {
    /// The run ticked: the pid of the server that began it, which a server
    /// resumed from its journal keeps.
    pub(super) run_pid: u32,
    /// How long to wait for the server to come back.
    pub(super) patience: Duration,
    /// The lockstep participants to wait for again before ticking the
    /// resumed world (--participants), so none misses its first frame.
    pub(super) participants: u32,
}

/// Why the ticks ended early.
#[derive(Debug, thiserror::Error)]
pub(super) enum TickLoopError {
    /// A tick failed.
    #[error(transparent)]
    Tick(#[from] TickError),
    /// The server exited and another started on the world that did not
    /// resume this run.
    #[error(
        "the server of world '{world}' exited and a fresh server (pid {server_pid}) started \
         on it, not a resume of this run (begun by pid {run_pid}): ticking ended after frame \
         {last_frame}; the fresh world is left as it is"
    )]
    FreshServer {
        /// The world.
        world: String,
        /// The fresh server's pid.
        server_pid: u32,
        /// The pid that began the run ticked.
        run_pid: u32,
        /// The last frame ticked.
        last_frame: u64,
    },
    /// Talking to the server that came back failed (asking about its run,
    /// waiting for the participants).
    #[error("after the server came back: {0:#}")]
    Reconnect(#[from] anyhow::Error),
    /// Ctrl-C or SIGTERM while waiting for the server to be resumed.
    #[error(
        "while waiting for the server of world '{world}' to be resumed (ticked up to frame \
         {last_frame}); there was no server to give the world back to"
    )]
    InterruptedWaiting {
        /// The world.
        world: String,
        /// The last frame ticked.
        last_frame: u64,
    },
}

impl TickLoopError {
    /// Whether the world is not this run's to give back: ownership was
    /// revoked, the server is gone (none came back, or Ctrl-C while
    /// waiting), or a fresh server took the world.
    pub(super) fn nothing_to_give_back(&self) -> bool {
        match self {
            Self::Tick(e) => {
                matches!(
                    e,
                    TickError::Revoked { .. } | TickError::Frame(WaitError::NotBack { .. })
                ) || e.is_server_gone()
            }
            Self::FreshServer { .. } | Self::InterruptedWaiting { .. } => true,
            Self::Reconnect(_) => false,
        }
    }
}

/// After the server exited: waits (in slices, so Ctrl-C is noticed) for a
/// server to come back on the world, checks that it resumed this run, and
/// only then claims it; returns the frame it resumed at.
pub(super) fn ride_through(
    ticker: &mut Ticker,
    follow: Restarts,
    client: &mut Client,
    interrupted: &AtomicBool,
) -> Result<u64, TickLoopError> {
    let world = ticker.world().to_string();
    let last_frame = ticker.last_frame().map_or(0, |(frame, _)| frame);
    eprintln!(
        "tick: the server of world '{world}' (pid {}) exited after frame {last_frame}; \
         waiting up to {} s for it to be resumed from its journal",
        ticker.server_pid(),
        simbus_input::Readable(follow.patience.as_secs_f64())
    );
    let deadline = Instant::now() + follow.patience;
    // The client finds the server that came back first, so a fresh one is
    // told apart before this ticker claims it.
    loop {
        if interrupted.load(Ordering::Relaxed) {
            return Err(TickLoopError::InterruptedWaiting { world, last_frame });
        }
        let slice = deadline
            .saturating_duration_since(Instant::now())
            .min(Duration::from_millis(200));
        match client.reconnect(slice) {
            Ok(_) => break,
            Err(ConnectError::NoServer { .. }) if Instant::now() >= deadline => {
                return Err(TickError::Frame(WaitError::NotBack {
                    world,
                    pid: ticker.server_pid(),
                    timeout: follow.patience,
                })
                .into())
            }
            Err(ConnectError::NoServer { .. }) => {}
            Err(e) => return Err(TickLoopError::Reconnect(e.into())),
        }
    }
    let run_pid = client
        .status()
        .map_err(|e| TickLoopError::Reconnect(e.into()))?
        .run_pid;
    if run_pid != follow.run_pid {
        return Err(TickLoopError::FreshServer {
            world,
            server_pid: client.server_pid(),
            run_pid: follow.run_pid,
            last_frame,
        });
    }
    let reconnected = ticker.reclaim(follow.patience)?;
    wait_for_participants(client, follow.participants, follow.patience)
        .map_err(TickLoopError::Reconnect)?;
    eprintln!("tick: {reconnected}; ticking on");
    Ok(reconnected.resumed_at)
}

/// Waits until at least `count` lockstep participants have joined: before
/// the first tick, and again after each resume.
pub(super) fn wait_for_participants(
    client: &Client,
    count: u32,
    timeout: Duration,
) -> anyhow::Result<()> {
    if count == 0 {
        return Ok(());
    }
    let deadline = Instant::now() + timeout;
    loop {
        let joined = client.status()?.participants;
        if joined >= count {
            return Ok(());
        }
        if Instant::now() >= deadline {
            return Err(anyhow!(
                "only {joined} of {count} lockstep participants joined within {timeout:?}"
            ));
        }
        // Joins are rare and this runs once: a short poll of the status.
        std::thread::sleep(Duration::from_millis(20));
    }
}
