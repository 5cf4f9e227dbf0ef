//! [`StandbyTicker`]: a ticker in waiting. It opens its node and ports and
//! queues its claim while another process owns the world; the server
//! answers the claim at the moment ownership becomes free (the owner
//! released, died or was revoked), so a failover costs the server's notice
//! of the death and one answer, not a new client's whole setup.

use std::time::{Duration, Instant};

use shared_types::{ResponseStatus, TickRequest, TickResponse, TickerInfo, WorldName};

use crate::rpc::Pending;
use crate::{RequestError, TickError, Ticker};

/// A ticker waiting for the world to be free. Made by
/// [`crate::Client::standby_ticker`]; [`StandbyTicker::wait`] returns the
/// [`Ticker`] once the world is this process's. Standbys are served first
/// come, first served. Dropping one withdraws its claim.
///
/// A server runs on a thread here, so the example runs as a test:
///
/// ```
/// use std::time::Duration;
/// use sim_client::Client;
///
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// # use std::sync::{atomic::{AtomicBool, Ordering}, Arc};
/// # let name = format!("doc-{}-{}", "standby", std::process::id());
/// # let stop = Arc::new(AtomicBool::new(false));
/// # let server = {
/// #     let (stop, world) = (stop.clone(), shared_types::WorldName::new(&name)?);
/// #     std::thread::spawn(move || {
/// #         let mut config = sim_server::ServerConfig::new(world);
/// #         config.settings.fixed_delta_seconds = Some(0.01);
/// #         config.realtime = true;
/// #         sim_server::Server::start(config).and_then(|mut s| s.run(&stop))
/// #     })
/// # };
/// let client = Client::connect(&name, Duration::from_secs(5))?;
/// let owner = client.claim_ticker()?;
/// let standby = client.standby_ticker()?; // queued behind the owner
/// assert!(standby.owner().is_some());
/// owner.release()?; // or the owner's process dies
/// let mut ticker = standby.wait(Duration::from_secs(5))?;
/// ticker.tick(Duration::from_secs(1))?;
/// # drop(ticker);
/// # stop.store(true, Ordering::Relaxed);
/// # server.join().expect("server thread")?;
/// # Ok(())
/// # }
/// ```
pub struct StandbyTicker {
    /// Declared first: the claim's answer drops before the ticker, whose
    /// drop withdraws the claim (or releases a world granted meanwhile).
    pending: Pending<TickRequest, TickResponse>,
    ticker: Ticker,
    /// The owner the server named when it queued the claim.
    owner: Option<TickerInfo>,
    /// An answer taken but not yet acted on.
    answer: Option<TickResponse>,
}

/// What [`StandbyTicker::wait_for`] ended with.
// Both variants hold a ticker's ports; the value is returned, not stored.
#[allow(clippy::large_enum_variant)]
#[derive(Debug)]
pub enum TakeOver {
    /// The world is this process's.
    Ticker(Ticker),
    /// The world still has a ticker; the standby still waits.
    Waiting(StandbyTicker),
}

impl StandbyTicker {
    /// Opens a ticker's ports on `world` and queues its standby claim;
    /// returns once the server answered it (granted, or queued).
    pub(crate) fn open(
        world: &WorldName,
        server_pid: u32,
        node_name: &str,
        request_timeout: Duration,
    ) -> Result<Self, TickError> {
        let full = |max| TickError::StandbyFull {
            world: world.to_string(),
            max,
        };
        let ticker = Ticker::open(world, server_pid, node_name, request_timeout, full)?;
        let pending = ticker.send_standby()?;
        let first = ticker.standby_answer(&pending, request_timeout)?;
        let mut standby = Self {
            pending,
            ticker,
            owner: None,
            answer: None,
        };
        standby.take(first);
        Ok(standby)
    }

    /// Notes an answer: an interim one names the owner it waits behind;
    /// any other is kept for [`StandbyTicker::wait_for`].
    fn take(&mut self, answer: TickResponse) {
        if answer.status == ResponseStatus::NotTicker as u32 {
            self.owner = answer.ticker.active();
        } else {
            self.answer = Some(answer);
        }
    }

    /// The world waited for.
    pub fn world(&self) -> &WorldName {
        self.ticker.world()
    }

    /// The ticker this standby waits behind, as the server named it when it
    /// queued the claim; `None` when the world was free.
    pub fn owner(&self) -> Option<TickerInfo> {
        self.owner
    }

    /// Waits up to `timeout` for the world to be free, then returns the
    /// [`Ticker`]: [`TickError::StandbyTimedOut`] (naming the owner) if it
    /// is not, [`RequestError::ServerGone`] if the server died meanwhile.
    ///
    /// # Errors
    ///
    /// Returns [`TickError::StandbyTimedOut`] (naming the owner) if the world
    /// still has a ticker after `timeout`, [`TickError::Request`] with
    /// [`RequestError::ServerGone`] if the server died meanwhile (or another
    /// [`RequestError`] if the answer cannot be read), and the errors of the
    /// grant ([`TickError::Revoked`], [`TickError::NotTicker`]).
    pub fn wait(self, timeout: Duration) -> Result<Ticker, TickError> {
        match self.wait_for(timeout)? {
            TakeOver::Ticker(ticker) => Ok(ticker),
            TakeOver::Waiting(standby) => Err(TickError::StandbyTimedOut {
                world: standby.world().to_string(),
                waited: timeout,
                owner: standby.owner.map(Box::new),
            }),
        }
    }

    /// Waits up to `within` for the world to be free (woken by the server's
    /// answer, not by a timer): the [`Ticker`], or this standby, still
    /// queued, to wait again (a loop that also watches for Ctrl-C).
    ///
    /// # Errors
    ///
    /// Running out of time is not an error: it returns [`TakeOver::Waiting`].
    /// Returns [`TickError::Request`] with [`RequestError::ServerGone`] if the
    /// server died meanwhile (or another [`RequestError`] if the answer cannot
    /// be read), and [`TickError::Revoked`] or [`TickError::NotTicker`] if the
    /// server's answer is not a grant.
    pub fn wait_for(mut self, within: Duration) -> Result<TakeOver, TickError> {
        let deadline = Instant::now() + within;
        loop {
            let answer = match self.answer.take() {
                Some(answer) => answer,
                None => {
                    let remaining = deadline.saturating_duration_since(Instant::now());
                    match self.ticker.standby_answer(&self.pending, remaining) {
                        Err(RequestError::Timeout { .. }) => return Ok(TakeOver::Waiting(self)),
                        other => other?,
                    }
                }
            };
            if answer.status == ResponseStatus::NotTicker as u32 {
                self.take(answer);
                continue;
            }
            let Self {
                pending,
                mut ticker,
                ..
            } = self;
            drop(pending);
            ticker.granted(answer)?;
            return Ok(TakeOver::Ticker(ticker));
        }
    }
}

impl std::fmt::Debug for StandbyTicker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("StandbyTicker")
            .field("ticker", &self.ticker)
            .field("owner", &self.owner)
            .finish_non_exhaustive()
    }
}
