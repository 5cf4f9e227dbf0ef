//! Riding through a server restart: a server resumed from its journal
//! (`sim-server --resume DIR`) comes back on the same world with a new
//! pid. A [`Client`] reconnects to it ([`Client::reconnect`],
//! [`Client::next_event`]), a [`Ticker`] claims it again
//! ([`Ticker::set_follow_restarts`]), and both say where the world
//! resumed, so a program knows which frames to do again.

use std::time::{Duration, Instant};

use crate::{Client, ConnectError, TickError, Ticker, WaitError, WorldSnapshot};

/// A server came back on the world after the one this client knew exited.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Reconnected {
    /// The frame the world resumed at: the first frame the new server
    /// published (the last one its journal made durable). The next tick
    /// computes the frame after it.
    pub resumed_at: u64,
    /// Its episode.
    pub episode: u64,
    /// The new server's process id.
    pub server_pid: u32,
    /// The process id of the server that exited.
    pub previous_pid: u32,
}

impl std::fmt::Display for Reconnected {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(
            f,
            "the server restarted (pid {} -> {}): the world resumed at frame {} of episode {}",
            self.previous_pid, self.server_pid, self.resumed_at, self.episode
        )
    }
}

/// What [`Client::next_event`] hands out: the next frame, or the news that
/// the server restarted.
#[derive(Debug, Clone, PartialEq)]
#[allow(clippy::large_enum_variant)]
pub enum Event {
    /// The next frame, as [`Client::wait_for_tick`] returns it.
    Frame(WorldSnapshot),
    /// The server exited and another came back on the world; this client
    /// now talks to it. Frames after `resumed_at` follow.
    Reconnected(Reconnected),
}

/// How often a client looks for a server coming back.
const RETRY: Duration = Duration::from_millis(20);

impl Client {
    /// Connects to the next server of `world` after the one with pid `previous_pid`.
    ///
    /// It waits up to `timeout` for a live server whose pid is not that one to
    /// come (a resume: `sim-server --resume DIR`). Fails with
    /// [`ConnectError::NoServer`] when none came in time.
    /// [`Client::reconnect`] does this for a client that is already connected.
    ///
    /// # Errors
    ///
    /// Returns [`ConnectError::NoServer`] if no server other than
    /// `previous_pid` came within `timeout`, and any other error of
    /// [`Client::connect`] at once ([`ConnectError::InvalidWorld`],
    /// [`ConnectError::ProtocolMismatch`], [`ConnectError::Full`], ...).
    pub fn connect_next(
        world: &str,
        previous_pid: u32,
        timeout: Duration,
    ) -> Result<Client, ConnectError> {
        let started = Instant::now();
        let deadline = started + timeout;
        loop {
            let remaining = deadline.saturating_duration_since(Instant::now());
            match Client::connect(world, remaining.max(RETRY)) {
                Ok(client)
                    if client.server_pid != previous_pid
                        && crate::process_alive(client.server_pid) =>
                {
                    return Ok(client)
                }
                Ok(_) | Err(ConnectError::NoServer { .. } | ConnectError::NotAnswering { .. }) => {}
                Err(e) => return Err(e),
            }
            if Instant::now() >= deadline {
                return Err(ConnectError::NoServer {
                    world: world.to_owned(),
                    timeout: started.elapsed(),
                });
            }
            std::thread::sleep(RETRY);
        }
    }

    /// Waits up to `timeout` for a server to come back, and talks to it from now on.
    ///
    /// The server comes back on this client's world after the one it knew
    /// exited (a resume: `sim-server --resume DIR`); this client then reads its
    /// frames, and its ports open on first use as at connect. The wait mode,
    /// frame order and request timeout stay as set. Fails with
    /// [`ConnectError::NoServer`] when none came back in time.
    ///
    /// # Errors
    ///
    /// Returns [`ConnectError::NoServer`] if no new server came back within
    /// `timeout` (this client is unchanged), and any other error of
    /// [`Client::connect`] met meanwhile ([`ConnectError::ProtocolMismatch`],
    /// [`ConnectError::Full`], ...).
    pub fn reconnect(&mut self, timeout: Duration) -> Result<Reconnected, ConnectError> {
        let previous_pid = self.server_pid;
        let mut next = Client::connect_next(self.world.as_str(), previous_pid, timeout)?;
        next.frames.mode = self.frames.mode;
        next.frames.every_frame = self.frames.every_frame;
        next.request_timeout = self.request_timeout;
        let header = next.frames.stashed_header();
        next.dispatcher = self.dispatcher.take();
        *self = next;
        let (resumed_at, episode) = header.map_or((0, 0), |h| (h.timestamp.frame, h.episode));
        let reconnected = Reconnected {
            resumed_at,
            episode,
            server_pid: self.server_pid,
            previous_pid,
        };
        tracing::info!(world = %self.world, "{reconnected}");
        Ok(reconnected)
    }

    /// [`Client::wait_for_tick`] that rides through a server restart.
    ///
    /// The next frame, or — when the server exited and another came back on
    /// the world within `timeout` — [`Event::Reconnected`], after which this
    /// client reads the new server's frames (the frame it resumed at comes
    /// next). Fails with [`WaitError::NotBack`] when no server came back in
    /// time.
    ///
    /// # Errors
    ///
    /// Returns [`WaitError::NotBack`] if the server exited and none came back
    /// within `timeout`, [`WaitError::Reconnect`] if one came back but
    /// connecting to it failed, and the other [`WaitError`]s of
    /// [`Client::wait_for_tick`] ([`WaitError::Timeout`] if no frame came and
    /// the server still runs, [`WaitError::Interrupted`], ...).
    pub fn next_event(&mut self, timeout: Duration) -> Result<Event, WaitError> {
        let deadline = Instant::now() + timeout;
        match self.wait_for_tick(timeout) {
            Ok(snapshot) => Ok(Event::Frame(snapshot)),
            Err(WaitError::ServerGone { world, pid }) => {
                let remaining = deadline.saturating_duration_since(Instant::now());
                match self.reconnect(remaining) {
                    Ok(reconnected) => Ok(Event::Reconnected(reconnected)),
                    Err(ConnectError::NoServer { .. }) => Err(WaitError::NotBack {
                        world,
                        pid,
                        timeout,
                    }),
                    Err(e) => Err(WaitError::Reconnect(Box::new(e))),
                }
            }
            Err(e) => Err(e),
        }
    }
}

impl Ticker {
    /// When the server exits, wait up to `timeout` for one to come back on
    /// the world (a resume), claim it again and say so: the tick that
    /// noticed fails with [`TickError::Restarted`], and the next tick
    /// computes the frame after the one the world resumed at. `None` (the
    /// default): a server that exits ends the ticker.
    pub fn set_follow_restarts(&mut self, timeout: Option<Duration>) {
        self.follow_restarts = timeout;
    }

    /// After `error`, when following restarts and the server is gone:
    /// claims the world from the server that came back.
    pub(crate) fn ride_through(&mut self, error: TickError) -> TickError {
        let Some(timeout) = self.follow_restarts else {
            return error;
        };
        // A server that came back may answer first (refusing a port it
        // does not know): what counts is that this ticker's server is gone.
        if !error.is_server_gone() && crate::process_alive(self.server_pid) {
            return error;
        }
        match self.reclaim(timeout) {
            Ok(reconnected) => TickError::Restarted(reconnected),
            Err(e) => e,
        }
    }

    /// Waits up to `timeout` for the next server of the world and claims it.
    ///
    /// The next server is one whose pid is not this ticker's server's; it is
    /// claimed under the same node name, keeping this ticker's wait mode: what
    /// [`Ticker::set_follow_restarts`] does when a tick notices, for a program
    /// that noticed first (a request failed with the server gone).
    ///
    /// # Errors
    ///
    /// Returns [`TickError::Frame`] with [`WaitError::NotBack`] if no new
    /// server came within `timeout`, with [`WaitError::Reconnect`] if one came
    /// but connecting to it failed, and the errors of [`Client::claim_ticker`]
    /// if claiming it fails ([`TickError::NotTicker`] if another client got
    /// there first, [`TickError::Request`]).
    pub fn reclaim(&mut self, timeout: Duration) -> Result<Reconnected, TickError> {
        let previous_pid = self.server_pid;
        // Nothing to release on a server that is gone.
        self.released = true;
        let client = Client::connect_next(self.world.as_str(), previous_pid, timeout).map_err(
            |e| match e {
                ConnectError::NoServer { .. } => TickError::Frame(WaitError::NotBack {
                    world: self.world.to_string(),
                    pid: previous_pid,
                    timeout,
                }),
                e => TickError::Frame(WaitError::Reconnect(Box::new(e))),
            },
        )?;
        let mut fresh = client.claim_ticker_as(&self.node_name)?;
        fresh.mode = self.mode;
        fresh.follow_restarts = self.follow_restarts;
        let (resumed_at, _) = fresh.last.unwrap_or_default();
        let episode = client.frames.stashed_header().map_or(0, |h| h.episode);
        *self = fresh;
        let reconnected = Reconnected {
            resumed_at,
            episode,
            server_pid: self.server_pid,
            previous_pid,
        };
        tracing::info!(world = %self.world, "ticker claimed the world again: {reconnected}");
        Ok(reconnected)
    }
}

impl TickError {
    /// Whether the server process is gone.
    pub fn is_server_gone(&self) -> bool {
        matches!(
            self,
            TickError::Request(crate::RequestError::ServerGone { .. })
                | TickError::Frame(WaitError::ServerGone { .. })
        )
    }
}
