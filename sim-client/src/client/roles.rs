//! The roles a client takes in its world: the ticker, a standby ticker,
//! a lockstep participant.

use std::time::{Duration, Instant};

use shared_types::{ControlRequest, RequestKind};

use super::{default_ticker_name, Client};
use crate::standby::StandbyTicker;
use crate::{Participant, RequestError, TickError, Ticker};

impl Client {
    /// Claims tick ownership of the world. Fails with
    /// [`TickError::NotTicker`], naming the owner, while another client ticks.
    ///
    /// # Errors
    ///
    /// Returns [`TickError::NotTicker`] (naming the owner when the server can)
    /// if another client ticks the world; [`TickError::Request`] with
    /// [`RequestError::Timeout`] if the tick service does not appear or the
    /// claim is not answered within the request timeout, with
    /// [`RequestError::ServerGone`] if the server exits meanwhile, or with
    /// [`RequestError::Full`] / [`RequestError::Transport`] if the ticker's
    /// node or ports cannot be opened; and [`TickError::Revoked`] if the claim
    /// is answered as revoked.
    pub fn claim_ticker(&self) -> Result<Ticker, TickError> {
        self.claim_ticker_as(&default_ticker_name())
    }

    /// [`Client::claim_ticker`] with the node name others see as the owner.
    ///
    /// # Errors
    ///
    /// Returns the errors of [`Client::claim_ticker`]: [`TickError::NotTicker`]
    /// if another client ticks the world, [`TickError::Request`] if the tick
    /// service cannot be opened or does not answer (including
    /// [`RequestError::Transport`] if iceoryx2 refuses `node_name` as a node
    /// name).
    pub fn claim_ticker_as(&self, node_name: &str) -> Result<Ticker, TickError> {
        Ticker::claim(
            &self.world,
            self.server_pid,
            node_name,
            self.request_timeout,
            || {
                // The owner may be registering right now: ask a few times,
                // within one request timeout in all.
                let deadline = Instant::now() + self.request_timeout;
                (0..20).find_map(|_| {
                    let remaining = deadline.saturating_duration_since(Instant::now());
                    let owner = self
                        .request_within(ControlRequest::new(RequestKind::Status), remaining)
                        .ok()
                        .and_then(|r| r.report.ticker.active());
                    if owner.is_none() {
                        std::thread::sleep(Duration::from_millis(10));
                    }
                    owner
                })
            },
        )
    }

    /// A standby ticker: a claim the server grants once the world has no ticker.
    ///
    /// It opens a ticker's node and ports now and queues a claim that the
    /// server grants the moment the world has no ticker (the owner released,
    /// died or was revoked); first come, first served. Returns once the server
    /// answered (granted or queued); [`StandbyTicker::wait`] then returns the
    /// [`Ticker`]. Fails with [`TickError::StandbyFull`] when the tick service
    /// admits no more ports.
    ///
    /// # Errors
    ///
    /// Returns [`TickError::StandbyFull`] if the tick service admits no more
    /// ports (too many standbys wait), and [`TickError::Request`] if the
    /// ticker's ports cannot be opened or the server does not answer the claim
    /// within the request timeout ([`RequestError::Timeout`],
    /// [`RequestError::ServerGone`], [`RequestError::Transport`], ...).
    pub fn standby_ticker(&self) -> Result<StandbyTicker, TickError> {
        self.standby_ticker_as(&default_ticker_name())
    }

    /// [`Client::standby_ticker`] with the node name others see once it
    /// owns the world.
    ///
    /// # Errors
    ///
    /// Returns the errors of [`Client::standby_ticker`]:
    /// [`TickError::StandbyFull`] if the tick service admits no more ports,
    /// [`TickError::Request`] if the ports cannot be opened (including a
    /// `node_name` iceoryx2 refuses) or the claim is not answered in time.
    pub fn standby_ticker_as(&self, node_name: &str) -> Result<StandbyTicker, TickError> {
        StandbyTicker::open(
            &self.world,
            self.server_pid,
            node_name,
            self.request_timeout,
        )
    }

    /// Joins the world's lockstep as `name`: in synchronous mode the server
    /// then waits for this participant's [`Participant::done`] every frame.
    ///
    /// # Errors
    ///
    /// Returns [`RequestError::Timeout`] if the lockstep service does not
    /// appear or the join is not answered within the request timeout,
    /// [`RequestError::ServerGone`] if the server exits meanwhile,
    /// [`RequestError::Full`] if the world admits no more lockstep participants
    /// (`--max-clients`), [`RequestError::ProtocolMismatch`] for a server of
    /// another version, and [`RequestError::Transport`] if iceoryx2 refuses to
    /// open the participant's node or ports.
    pub fn join_lockstep(&self, name: &str) -> Result<Participant, RequestError> {
        self.join_lockstep_with_window(name, 0)
    }

    /// Joins the world's lockstep as `name` with a window of `window` frames.
    ///
    /// CARLA's per-participant synchronous windows: in synchronous mode the
    /// server steps past frame N only when this participant is done with frame
    /// N − `window`, so it may fall up to `window` frames behind without
    /// holding the ticker. 0 is [`Client::join_lockstep`]; at most
    /// [`shared_types::MAX_LOCKSTEP_WINDOW`].
    ///
    /// # Errors
    ///
    /// Returns [`RequestError::WindowTooLarge`] if `window` is above
    /// [`shared_types::MAX_LOCKSTEP_WINDOW`] (checked before anything is
    /// opened) or the server refuses it, and otherwise the errors of
    /// [`Client::join_lockstep`] ([`RequestError::Timeout`],
    /// [`RequestError::Full`], [`RequestError::ServerGone`], ...).
    pub fn join_lockstep_with_window(
        &self,
        name: &str,
        window: u32,
    ) -> Result<Participant, RequestError> {
        Participant::join_with_window(
            &self.world,
            self.server_pid,
            (name, window),
            self.request_timeout,
        )
    }
}
