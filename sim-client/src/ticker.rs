//! [`Ticker`]: tick ownership of a world, and the ticks themselves.

use std::time::{Duration, Instant};

use iceoryx2::port::listener::Listener;
use iceoryx2::prelude::*;
use shared_types::{
    FrameHeader, ResponseStatus, ServiceNames, TickRequest, TickRequestKind, TickResponse,
    TickerInfo, WorldName, WorldSettings,
};
use simbus_transport::spec::WorldServices;
use simbus_transport::stamps::{self, Stage};
use simbus_transport::Bus;
use tracing::{debug, info, warn};

use crate::open::{frame_ready_listener, wake_notifier};
use crate::rpc::{open_service, Pending, RequestPort, Wait};
use crate::{RequestError, TickError, WaitError, WaitMode};

/// How much longer than the server's lockstep timeout a held-up tick
/// waits, for the server to drop the participant and step.
const PARTICIPANT_DROP_MARGIN: Duration = Duration::from_secs(2);

/// Tick ownership of one world. Only one `Ticker` exists per world at a time
/// (the tick service admits a single client); dropping it releases ownership.
///
/// A server runs on a thread here, so the example runs as a test:
///
/// ```
/// use std::time::Duration;
/// use sim_client::Client;
/// use shared_types::WorldSettings;
///
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// # use std::sync::{atomic::{AtomicBool, Ordering}, Arc};
/// # let name = format!("doc-{}-{}", "ticker", std::process::id());
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
/// let mut ticker = client.claim_ticker()?; // fails, naming the owner, if someone ticks
/// let sync = WorldSettings {
///     synchronous_mode: true,
///     fixed_delta_seconds: Some(0.05),
///     ..client.get_settings()?
/// };
/// let first = ticker.apply_settings(sync)?;
/// for n in 0..100 {
///     let frame = ticker.tick(Duration::from_secs(1))?; // published when this returns
///     assert_eq!(frame, first + n);
/// }
/// ticker.release()?;
/// # stop.store(true, Ordering::Relaxed);
/// # server.join().expect("server thread")?;
/// # Ok(())
/// # }
/// ```
///
/// # Threads
///
/// Neither [`Send`] nor [`Sync`]: its iceoryx2 ports belong to the thread
/// that opened them. A thread that needs one claims it there, from a client of its own.
///
/// ```compile_fail
/// fn to_another_thread<T: Send>(_: T) {}
/// # fn f(handle: sim_client::Ticker) {
/// to_another_thread(handle); // its ports belong to this thread
/// # }
/// ```
pub struct Ticker {
    pub(crate) world: WorldName,
    port: RequestPort<TickRequest, TickResponse>,
    ready: Listener<Bus>,
    pub(crate) server_pid: u32,
    pub(crate) node_name: String,
    /// The tick request, built once: a tick in a tight loop copies 100
    /// bytes into shared memory and builds nothing.
    tick_request: TickRequest,
    pub(crate) mode: WaitMode,
    request_timeout: Duration,
    pub(crate) last: Option<(u64, u64)>,
    pub(crate) released: bool,
    /// How long to wait for a server coming back ([`Ticker::set_follow_restarts`]).
    pub(crate) follow_restarts: Option<Duration>,
    // Declared last: ports drop before their node.
    _node: Node<Bus>,
}

/// How long dropping a ticker waits for the server to confirm the release.
const RELEASE_TIMEOUT: Duration = Duration::from_secs(1);

mod handover;
mod in_flight;

pub use in_flight::TickInFlight;

impl Ticker {
    /// Claims tick ownership of `world`. `owner` names the current ticker
    /// when the transport refuses a second one.
    pub(crate) fn claim(
        world: &WorldName,
        server_pid: u32,
        node_name: &str,
        request_timeout: Duration,
        owner: impl Fn() -> Option<TickerInfo>,
    ) -> Result<Self, TickError> {
        let full = |_| TickError::NotTicker {
            world: world.to_string(),
            owner: owner(),
        };
        let mut ticker = Self::open(world, server_pid, node_name, request_timeout, full)?;
        let response = ticker.send(TickRequestKind::Claim, None, request_timeout)?;
        ticker.granted(response)?;
        Ok(ticker)
    }

    /// Opens the ports of a ticker of `world` (its node, tick port, wake-up
    /// notifier and frame-ready listener) without claiming: `full` is the
    /// error when the tick service admits no more ports (given how many it
    /// admits). Dropped, it
    /// releases (harmless when it never owned the world).
    pub(crate) fn open(
        world: &WorldName,
        server_pid: u32,
        node_name: &str,
        request_timeout: Duration,
        full: impl FnOnce(usize) -> TickError,
    ) -> Result<Self, TickError> {
        use iceoryx2::service::port_factory::client::ClientCreateError;

        let names = ServiceNames::new(world);
        let node =
            simbus_transport::node(node_name).map_err(|e| TickError::transport("node", e))?;
        let specs =
            WorldServices::new(&names).map_err(|e| TickError::transport("service name", e))?;
        let deadline = Instant::now() + request_timeout;
        let timeout = || {
            TickError::Request(RequestError::Timeout {
                world: world.to_string(),
                timeout: request_timeout,
            })
        };
        let service = open_service(deadline, || specs.tick.open(&node))
            .map_err(|e| TickError::transport("tick service", e))?
            .ok_or_else(timeout)?;
        let max = service.static_config().max_clients();
        let port = service.client_builder().create().map_err(|e| match e {
            ClientCreateError::ExceedsMaxSupportedClients => full(max),
            e => TickError::transport("tick client", e),
        })?;
        let wake = wake_notifier(&node, &names, deadline)
            .map_err(|e| TickError::Request(e.into_request()))?
            .ok_or_else(timeout)?;
        let ready = frame_ready_listener(&node, &names, deadline)
            .map_err(|e| TickError::Request(e.into_request()))?
            .ok_or_else(timeout)?;
        Ok(Self {
            world: world.clone(),
            port: RequestPort::new(
                port,
                Some(wake),
                specs.tick.doorbell,
                "request send",
                world.as_str(),
                server_pid,
            ),
            ready,
            server_pid,
            node_name: node_name.to_owned(),
            tick_request: TickRequest::new(TickRequestKind::Tick, node_name),
            mode: WaitMode::Block,
            request_timeout,
            last: None,
            released: false,
            follow_restarts: None,
            _node: node,
        })
    }

    /// Takes the answer to a claim: this ticker owns the world if it says so.
    pub(crate) fn granted(&mut self, response: TickResponse) -> Result<(), TickError> {
        let response = self.expect_ok(response)?;
        self.last = Some((response.frame, response.elapsed_ns));
        info!(world = %self.world, frame = response.frame, "claimed tick ownership");
        Ok(())
    }

    /// Sends a standby claim (granted when the world is free); the answers
    /// come on the returned pending response.
    pub(crate) fn send_standby(&self) -> Result<Pending<TickRequest, TickResponse>, RequestError> {
        self.port
            .send(TickRequest::new(TickRequestKind::Standby, &self.node_name))
    }

    /// The next answer to a standby claim, waiting up to `timeout` on the
    /// frame-ready event (which the server rings after answering).
    pub(crate) fn standby_answer(
        &self,
        pending: &Pending<TickRequest, TickResponse>,
        timeout: Duration,
    ) -> Result<TickResponse, RequestError> {
        self.port.answer(pending, timeout, Wait::Event(&self.ready))
    }

    /// How [`Ticker::tick`] waits for its frame: blocking (default) or spinning.
    pub fn set_wait_mode(&mut self, mode: WaitMode) {
        self.mode = mode;
    }

    /// The process id of the server this ticker ticks.
    pub fn server_pid(&self) -> u32 {
        self.server_pid
    }

    /// The world ticked.
    pub fn world(&self) -> &WorldName {
        &self.world
    }

    /// The last frame this ticker produced (or saw when claiming) and its
    /// simulation time in nanoseconds.
    pub fn last_frame(&self) -> Option<(u64, u64)> {
        self.last
    }

    /// Asks for the next frame and returns its id once its snapshot is published.
    ///
    /// A subscriber that then reads sees it. In synchronous mode nothing moves
    /// without a tick; in asynchronous mode a tick just waits for the next
    /// frame.
    ///
    /// A tick held up by a lockstep participant is told so by the server
    /// (which drops a participant after its `--lockstep-timeout`); it then
    /// waits that long too, whatever `timeout` says, so the two never race.
    ///
    /// With [`Ticker::set_follow_restarts`], a server that exits while the
    /// tick waits ends it with [`TickError::Restarted`] once another came
    /// back and this ticker claimed it.
    ///
    /// # Errors
    ///
    /// Returns [`TickError::Request`] with [`RequestError::Timeout`] if the
    /// frame is not published within `timeout`, or with
    /// [`RequestError::ServerGone`] if the server exits (without
    /// [`Ticker::set_follow_restarts`]); [`TickError::HeldUp`] if a lockstep
    /// participant held the tick past the server's lockstep timeout and no
    /// answer came; [`TickError::NotTicker`] or [`TickError::Revoked`] if this
    /// client is no longer the ticker; and [`TickError::Restarted`] when
    /// following restarts, once another server came back and this ticker
    /// claimed it.
    pub fn tick(&mut self, timeout: Duration) -> Result<u64, TickError> {
        self.tick_once(timeout).map_err(|e| self.ride_through(e))
    }

    fn tick_once(&mut self, timeout: Duration) -> Result<u64, TickError> {
        let started = Instant::now();
        let sent = stamps::began();
        let pending = self.port.send(self.tick_request)?;
        let mut deadline = started + timeout;
        let mut waiting_for = None;
        loop {
            let remaining = deadline.saturating_duration_since(Instant::now());
            let response =
                match self
                    .port
                    .answer(&pending, remaining, Wait::for_mode(self.mode, &self.ready))
                {
                    Err(RequestError::Timeout { .. }) if waiting_for.is_some() => {
                        let participant = waiting_for.unwrap_or_else(TickerInfo::none);
                        return Err(self.held_up(participant, started));
                    }
                    Err(RequestError::Timeout { world, .. }) => {
                        return Err(RequestError::Timeout { world, timeout }.into())
                    }
                    other => other?,
                };
            if response.status == ResponseStatus::WaitingForParticipants as u32 {
                deadline = deadline.max(self.told_held_up(&response));
                waiting_for = Some(response.waiting_for);
                continue;
            }
            let response = self.expect_ok(response)?;
            stamps::stamp_at(Stage::ClientSend, response.frame, sent);
            stamps::stamp_wake(Stage::ClientWake, response.frame);
            self.last = Some((response.frame, response.elapsed_ns));
            return Ok(response.frame);
        }
    }

    /// Asks for the next frame and returns it, read in place from `client`'s subscription.
    ///
    /// In synchronous mode, one wait, on the frame itself. The server sends
    /// this tick no answer once its frame is published
    /// ([`TickRequest::BY_FRAME`]), so a round trip is one message each way
    /// where [`Ticker::tick`] and a read take two.
    ///
    /// A refusal, a revocation and a lockstep participant holding the tick are
    /// answered and end or stretch the wait as for [`Ticker::tick`]; a frame
    /// another client's load or reload publishes meanwhile is not the tick's
    /// ([`FrameHeader::STEPPED`]) and is passed over. In asynchronous mode,
    /// whose frames come whatever ticks, it waits for the answer and returns
    /// the newest frame then.
    ///
    /// Frames `client` had queued before the tick are skipped (its next frame
    /// after this one counts none missed). Waits as `client`'s wait mode says.
    ///
    /// With [`Ticker::set_follow_restarts`], a server that exits ends the
    /// tick with [`TickError::Restarted`] once another came back, this
    /// ticker claimed it and `client` reconnected to it.
    ///
    /// # Errors
    ///
    /// Returns the errors of [`Ticker::tick`] ([`TickError::Request`] with
    /// [`RequestError::Timeout`] or [`RequestError::ServerGone`],
    /// [`TickError::HeldUp`], [`TickError::NotTicker`], [`TickError::Revoked`],
    /// [`TickError::Restarted`]), and [`TickError::Frame`] if reading the frame
    /// fails ([`WaitError::ProtocolMismatch`], [`WaitError::Transport`]) or,
    /// when following restarts, `client` cannot reconnect
    /// ([`WaitError::Reconnect`]).
    ///
    /// # Examples
    ///
    /// A server runs on a thread here, so the example runs as a test:
    ///
    /// ```
    /// use std::time::Duration;
    /// use sim_client::Client;
    /// use shared_types::WorldSettings;
    ///
    /// # fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// # use std::sync::{atomic::{AtomicBool, Ordering}, Arc};
    /// # let name = format!("doc-{}-{}", "tick-and-read", std::process::id());
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
    /// let mut client = Client::connect(&name, Duration::from_secs(5))?;
    /// let mut ticker = client.claim_ticker()?;
    /// let sync = WorldSettings {
    ///     synchronous_mode: true,
    ///     fixed_delta_seconds: Some(0.05),
    ///     ..client.get_settings()?
    /// };
    /// let first = ticker.apply_settings(sync)?;
    /// let frame = ticker.tick_and_read(&mut client, Duration::from_secs(1))?;
    /// assert_eq!(frame.frame(), first);
    /// assert_eq!(frame.timestamp().delta_ns, 50_000_000);
    /// # drop(frame);
    /// # drop(ticker);
    /// # stop.store(true, Ordering::Relaxed);
    /// # server.join().expect("server thread")?;
    /// # Ok(())
    /// # }
    /// ```
    pub fn tick_and_read(
        &mut self,
        client: &mut crate::Client,
        timeout: Duration,
    ) -> Result<crate::FrameView, TickError> {
        match self.tick_and_read_once(client, timeout) {
            Ok(view) => Ok(view),
            Err(e) => match self.ride_through(e) {
                TickError::Restarted(reconnected) => {
                    let wait = self.follow_restarts.unwrap_or(timeout);
                    if client.server_pid() != reconnected.server_pid {
                        client
                            .reconnect(wait)
                            .map_err(|e| TickError::Frame(WaitError::Reconnect(Box::new(e))))?;
                    }
                    Err(TickError::Restarted(reconnected))
                }
                e => Err(e),
            },
        }
    }

    fn tick_and_read_once(
        &mut self,
        client: &mut crate::Client,
        timeout: Duration,
    ) -> Result<crate::FrameView, TickError> {
        use crate::frame_stream::FrameOr;
        use crate::wait::Stop;
        let started = Instant::now();
        client.frames.skip_queued()?;
        let sent = stamps::began();
        let request = TickRequest {
            flags: self.tick_request.flags | TickRequest::BY_FRAME,
            ..self.tick_request
        };
        let pending = self.port.send(request)?;
        let mut deadline = started + timeout;
        let mut waiting_for = None;
        // An asynchronous world's newest frame, returned once answered.
        let mut newest = None;
        let mut answered = false;
        loop {
            if answered {
                if let Some(frame) = client.frames.try_next()?.or(newest.take()) {
                    return Ok(self.took(frame, sent));
                }
            }
            let outcome = client.frames.next_or(deadline, self.server_pid, || {
                self.port.try_answer(&pending).map_err(TickError::from)
            });
            let response = match outcome {
                Ok(FrameOr::Frame(frame)) if !frame.settings().synchronous_mode => {
                    newest = Some(frame);
                    continue;
                }
                Ok(FrameOr::Frame(frame)) if frame.header().flags & FrameHeader::STEPPED != 0 => {
                    return Ok(self.took(frame, sent));
                }
                // Published by another client's load or reload while the
                // tick was on its way: not the tick's.
                Ok(FrameOr::Frame(_)) => continue,
                Ok(FrameOr::Other(response)) => response,
                Err(Stop::Failed(e)) => return Err(e),
                Err(Stop::TimedOut) => {
                    return Err(match waiting_for {
                        Some(participant) => self.held_up(participant, started),
                        None => RequestError::Timeout {
                            world: self.world.to_string(),
                            timeout,
                        }
                        .into(),
                    })
                }
                Err(Stop::ServerGone) => {
                    return Err(RequestError::ServerGone {
                        world: self.world.to_string(),
                        pid: self.server_pid,
                    }
                    .into())
                }
                Err(Stop::Interrupted) => {
                    return Err(RequestError::Interrupted {
                        world: self.world.to_string(),
                    }
                    .into())
                }
                Err(Stop::Event(e)) => return Err(TickError::transport("frame-ready wait", e)),
            };
            if response.status == ResponseStatus::WaitingForParticipants as u32 {
                deadline = deadline.max(self.told_held_up(&response));
                waiting_for = Some(response.waiting_for);
                continue;
            }
            // Refused or revoked; an `Ok` (an asynchronous world's) comes
            // after the tick's frame was published.
            self.expect_ok(response)?;
            answered = true;
        }
    }

    /// `frame`, the one a tick sent at `sent` produced, as this ticker's
    /// last.
    fn took(&mut self, frame: crate::FrameView, sent: u64) -> crate::FrameView {
        let t = frame.timestamp();
        stamps::stamp_at(Stage::ClientSend, t.frame, sent);
        stamps::stamp_wake(Stage::ClientWake, t.frame);
        self.last = Some((t.frame, t.elapsed_ns));
        frame
    }

    /// The deadline a tick told it waits for a participant (`response`)
    /// waits until: the server's lockstep timeout and a margin from now.
    fn told_held_up(&self, response: &TickResponse) -> Instant {
        let participant = response.waiting_for;
        let patience = Duration::from_nanos(response.lockstep_timeout_ns)
            .saturating_add(PARTICIPANT_DROP_MARGIN);
        warn!(
            world = %self.world,
            frame = participant.since_frame,
            "the tick waits for lockstep participant {} (pid {}); the server drops it after {:?}",
            participant.node_name.to_string_lossy(),
            participant.pid,
            Duration::from_nanos(response.lockstep_timeout_ns),
        );
        Instant::now() + patience
    }

    /// The error of a tick that waited since `started` for `participant`
    /// and got no answer.
    fn held_up(&self, participant: TickerInfo, started: Instant) -> TickError {
        TickError::HeldUp {
            world: self.world.to_string(),
            participant: participant.node_name.to_string_lossy(),
            pid: participant.pid,
            waited: started.elapsed(),
        }
    }

    /// `response` if the server did what was asked.
    fn expect_ok(&self, response: TickResponse) -> Result<TickResponse, TickError> {
        match ResponseStatus::from_u32(response.status) {
            Some(ResponseStatus::Ok) => Ok(response),
            Some(ResponseStatus::Revoked) => Err(TickError::Revoked {
                world: self.world.to_string(),
                by: response.revoked_by,
            }),
            Some(ResponseStatus::NotTicker) => Err(TickError::NotTicker {
                world: self.world.to_string(),
                owner: response.ticker.active(),
            }),
            _ => Err(unexpected(response.status).into()),
        }
    }

    /// Sends one request (not a tick) and waits for its answer, whatever
    /// its status.
    fn send(
        &self,
        kind: TickRequestKind,
        settings: Option<WorldSettings>,
        timeout: Duration,
    ) -> Result<TickResponse, RequestError> {
        let mut request = TickRequest::new(kind, &self.node_name);
        if let Some(settings) = settings {
            request.settings = settings.into();
        }
        self.port.request(request, timeout, Wait::Backoff)
    }
}

/// An answer whose status this request does not expect.
fn unexpected(status: u32) -> RequestError {
    if status == ResponseStatus::UnknownRequest as u32 {
        RequestError::UnknownRequest
    } else {
        RequestError::UnknownAnswer { status }
    }
}

impl Drop for Ticker {
    fn drop(&mut self) {
        if !self.released {
            if let Err(e) = self.send(TickRequestKind::Release, None, RELEASE_TIMEOUT) {
                debug!("releasing tick ownership on drop: {e}");
            }
        }
    }
}

impl std::fmt::Debug for Ticker {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Ticker")
            .field("world", &self.world)
            .field("node_name", &self.node_name)
            .field("server_pid", &self.server_pid)
            .field("mode", &self.mode)
            .field("last", &self.last)
            .finish_non_exhaustive()
    }
}
