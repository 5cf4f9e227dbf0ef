//! [`Client`]: a connection to one simbus world.

use std::cell::OnceCell;
use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use shared_types::{
    ControlRequest, ControlResponse, FixedText, RequestKind, ResponseStatus, ServiceNames,
    WorldName, PROTOCOL_VERSION,
};
use simbus_transport::spec::WorldServices;
use simbus_transport::Bus;
use tracing::debug;

use crate::batch::{open_batch_client, BatchClient};
use crate::frame_stream::FrameStream;
use crate::on_tick::{CallbackId, TickDispatcher};
use crate::open::{wake_notifier, OpenFailure};
use crate::rpc::{client_error, open_service, RequestPort, Wait};
use crate::FrameView;
use crate::WaitMode;
use crate::{ConnectError, RequestError, Status, WaitError, WorldSnapshot};

/// The control port, with the notifier that wakes the server after a request.
pub(crate) type ControlPort = RequestPort<ControlRequest, ControlResponse>;

/// How long one attempt of the first empty batch of a new batch port waits.
const BATCH_HANDSHAKE_ATTEMPT: Duration = Duration::from_millis(100);

/// How long a control request waits for its answer unless told otherwise.
pub const DEFAULT_REQUEST_TIMEOUT: Duration = Duration::from_secs(5);

/// A connection to one simbus world: its settings, its status and its frames.
///
/// A server runs on a thread here, so the example runs as a test:
///
/// ```
/// use std::time::Duration;
/// use sim_client::Client;
///
/// # fn main() -> Result<(), Box<dyn std::error::Error>> {
/// # use std::sync::{atomic::{AtomicBool, Ordering}, Arc};
/// # let name = format!("doc-{}-{}", "client", std::process::id());
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
/// let snapshot = client.wait_for_tick(Duration::from_secs(1))?;
/// println!("frame {} at {:.3} s", snapshot.frame(), snapshot.timestamp().elapsed_seconds());
/// assert_eq!(client.status()?.server_pid, std::process::id());
/// # stop.store(true, Ordering::Relaxed);
/// # server.join().expect("server thread")?;
/// # Ok(())
/// # }
/// ```
///
/// [`Client::builder`] sets the options before connecting.
///
/// # Threads
///
/// A `Client` is neither [`Send`] nor [`Sync`]: its iceoryx2 ports belong to
/// the thread that opened them, and its request ports open on first use
/// behind [`std::cell::OnceCell`]s. Connect one client in each thread that
/// needs one (connecting is cheap), as the CARLA gateway does, one per
/// connection. [`Client::on_tick`] callbacks run on a thread of their own
/// with their own subscription.
///
/// ```compile_fail
/// fn to_another_thread<T: Send>(_: T) {}
/// # fn f(client: sim_client::Client) {
/// to_another_thread(client); // its ports belong to this thread
/// # }
/// ```
///
/// ```compile_fail
/// fn shared<T: Sync>(_: &T) {}
/// # fn f(client: sim_client::Client) {
/// shared(&client); // `OnceCell` is not `Sync`
/// # }
/// ```
pub struct Client {
    pub(crate) world: WorldName,
    pub(crate) node: Node<Bus>,
    /// Opened on the first request: a client that only watches frames
    /// holds a frame subscription and a listener, nothing else.
    control: OnceCell<ControlPort>,
    /// Opened on the first batch: a client that never sends a command
    /// holds no batch port.
    batch: OnceCell<BatchClient>,
    /// Opened on the first sensor request.
    pub(crate) sensor_port: OnceCell<crate::sensor::SensorRequestClient>,
    /// The recorder port, opened on first use.
    pub(crate) recorder_port: OnceCell<crate::recorder::RecorderClient>,
    debug_port: OnceCell<debug::DebugClient>,
    pub(crate) names: ServiceNames,
    pub(crate) frames: FrameStream,
    pub(crate) server_pid: u32,
    pub(crate) request_timeout: Duration,
    pub(crate) dispatcher: Option<TickDispatcher>,
}

/// This executable's name, as the server's logs and a revoked ticker see it.
fn process_name() -> &'static str {
    static NAME: std::sync::OnceLock<String> = std::sync::OnceLock::new();
    NAME.get_or_init(default_ticker_name)
}

/// This executable's name, as a node name (letters, digits, `-`, `_`).
fn default_ticker_name() -> String {
    let name: String = std::env::current_exe()
        .ok()
        .and_then(|p| p.file_stem().map(|s| s.to_string_lossy().into_owned()))
        .unwrap_or_else(|| "ticker".to_owned())
        .chars()
        .filter(|c| c.is_ascii_alphanumeric() || matches!(c, '-' | '_'))
        .take(48)
        .collect();
    if name.is_empty() {
        "ticker".to_owned()
    } else {
        name
    }
}

mod debug;
pub use debug::DrawError;
mod roles;
mod sensors;
mod settings;

impl Client {
    /// Connects to the server of `world`, waiting up to `timeout` for it to
    /// appear and publish its current frame, which carries the protocol
    /// version (checked) and the server's pid (watched in every wait).
    ///
    /// Only the frame subscription and its listener are opened here; the
    /// control, batch and sensor ports open on first use and stay open.
    ///
    /// # Errors
    ///
    /// Returns [`ConnectError::InvalidWorld`] if `world` is not a valid world
    /// name; [`ConnectError::SharedDirectory`] if iceoryx2 cannot be used as
    /// configured (its configuration file does not load, or another user owns
    /// its shared directory); [`ConnectError::NoServer`] if no server owns the
    /// world within `timeout`; [`ConnectError::NotAnswering`] if the world's
    /// services exist but no frame is published within `timeout` (a stopped or
    /// overloaded server); [`ConnectError::ProtocolMismatch`] if the server
    /// speaks another protocol version; [`ConnectError::Full`] if the world
    /// admits no more frame subscribers or listeners (`--max-clients`); and
    /// [`ConnectError::Transport`] if iceoryx2 refuses anything else.
    ///
    /// # Examples
    ///
    /// A server runs on a thread here, so the example runs as a test:
    ///
    /// ```
    /// use std::time::Duration;
    /// use sim_client::{Client, ConnectError};
    ///
    /// # fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// # use std::sync::{atomic::{AtomicBool, Ordering}, Arc};
    /// # let name = format!("doc-{}-{}", "connect", std::process::id());
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
    /// assert_eq!(client.world().as_str(), name);
    /// assert_eq!(client.server_pid(), std::process::id()); // the server runs on a thread here
    ///
    /// // No server owns this world: refused once the timeout has passed.
    /// let nobody = format!("{name}-nobody");
    /// let missing = Client::connect(&nobody, Duration::from_millis(50));
    /// assert!(matches!(missing, Err(ConnectError::NoServer { .. })));
    /// # drop(client);
    /// # stop.store(true, Ordering::Relaxed);
    /// # server.join().expect("server thread")?;
    /// # Ok(())
    /// # }
    /// ```
    pub fn connect(world: &str, timeout: Duration) -> Result<Self, ConnectError> {
        let world = WorldName::new(world)?;
        let deadline = Instant::now() + timeout;
        let names = ServiceNames::new(&world);
        let node = crate::open::client_node()?;
        let mut frames =
            FrameStream::open(&node, &names, world.as_str(), deadline)?.ok_or_else(|| {
                ConnectError::NoServer {
                    world: world.to_string(),
                    timeout,
                }
            })?;
        let header = frames
            .first_header(deadline)
            .map_err(|e| ConnectError::transport("first frame", e))?
            .ok_or_else(|| ConnectError::NotAnswering {
                world: world.to_string(),
                timeout,
            })?;
        if header.protocol_version != PROTOCOL_VERSION {
            return Err(ConnectError::ProtocolMismatch {
                world: world.to_string(),
                detail: format!("its frames are version {}", header.protocol_version),
                client: PROTOCOL_VERSION,
            });
        }
        debug!(%world, server_pid = header.server_pid, "connected");
        Ok(Self {
            world,
            node,
            control: OnceCell::new(),
            batch: OnceCell::new(),
            sensor_port: OnceCell::new(),
            recorder_port: OnceCell::new(),
            debug_port: OnceCell::new(),
            names,
            frames,
            server_pid: header.server_pid,
            request_timeout: DEFAULT_REQUEST_TIMEOUT,
            dispatcher: None,
        })
    }

    /// The control port, opened on first use.
    pub(crate) fn control(&self) -> Result<&ControlPort, RequestError> {
        use iceoryx2::service::builder::request_response::RequestResponseOpenError;
        if let Some(port) = self.control.get() {
            return Ok(port);
        }
        let deadline = Instant::now() + self.request_timeout;
        let specs = WorldServices::new(&self.names)
            .map_err(|e| RequestError::transport("service name", e))?;
        let service = open_service(deadline, || specs.control.open(&self.node))
            .map_err(|e| match e {
                RequestResponseOpenError::IncompatibleRequestOrResponseType => {
                    RequestError::ProtocolMismatch {
                        client: PROTOCOL_VERSION,
                        server: None,
                    }
                }
                e => RequestError::transport("control service", e),
            })?
            .ok_or_else(|| RequestError::ServerGone {
                world: self.world.to_string(),
                pid: self.server_pid,
            })?;
        let client = service.client_builder().create().map_err(|e| {
            let max = service.static_config().max_clients();
            client_error(e, max, "clients sending requests", "control client")
        })?;
        let wake = wake_notifier(&self.node, &self.names, deadline)
            .map_err(OpenFailure::into_request)?
            .ok_or_else(|| RequestError::ServerGone {
                world: self.world.to_string(),
                pid: self.server_pid,
            })?;
        let (world, pid) = (self.world.as_str(), self.server_pid);
        let doorbell = specs.control.doorbell;
        Ok(self.control.get_or_init(|| {
            RequestPort::new(client, Some(wake), doorbell, "request send", world, pid)
        }))
    }

    /// Rings `doorbell` on the server's wake-up event after a request was
    /// sent on any port.
    pub(crate) fn wake_server(&self, doorbell: shared_types::Doorbell) -> Result<(), RequestError> {
        self.control()?.wake(doorbell);
        Ok(())
    }

    /// The world this client is connected to.
    pub fn world(&self) -> &WorldName {
        &self.world
    }

    /// The server's process id.
    pub fn server_pid(&self) -> u32 {
        self.server_pid
    }

    /// How [`Client::wait_for_tick`] waits: blocking (default) or spinning.
    pub fn set_wait_mode(&mut self, mode: WaitMode) {
        self.frames.mode = mode;
    }

    /// In asynchronous mode, hand out every queued frame in order instead of
    /// skipping to the newest (a reader more than 16 frames behind still
    /// loses the oldest, counted in [`WorldSnapshot::missed`]). Synchronous
    /// mode is always in order.
    pub fn set_every_frame(&mut self, every_frame: bool) {
        self.frames.every_frame = every_frame;
    }

    /// How long control requests wait for an answer (default 5 s).
    pub fn set_request_timeout(&mut self, timeout: Duration) {
        self.request_timeout = timeout;
    }

    /// The world's status: current frame, settings, scene, actors, ticker
    /// and lockstep participants.
    ///
    /// # Errors
    ///
    /// Returns [`RequestError::Timeout`] if the server does not answer within
    /// the request timeout ([`Client::set_request_timeout`]),
    /// [`RequestError::ServerGone`] if its process has exited,
    /// [`RequestError::Interrupted`] if the interrupt check
    /// ([`set_interrupt_check`](crate::set_interrupt_check)) ends the wait,
    /// [`RequestError::ProtocolMismatch`] if the server speaks another protocol
    /// version, and [`RequestError::Unreachable`] if the world is mirrored from
    /// a host the bridge cannot reach now. The first request opens the control
    /// port: [`RequestError::Full`] if the world admits no more clients sending
    /// requests, [`RequestError::Transport`] if iceoryx2 refuses.
    pub fn status(&self) -> Result<Status, RequestError> {
        let response = self.request(ControlRequest::new(RequestKind::Status))?;
        Ok(Status::from(&response.report))
    }

    /// Waits up to `timeout` for a frame newer than the last one this client
    /// received and returns it.
    ///
    /// In synchronous mode frames come in order, each once. In asynchronous
    /// mode a client that fell behind gets the newest frame, and
    /// [`WorldSnapshot::missed`] says how many it skipped.
    ///
    /// # Errors
    ///
    /// Returns [`WaitError::Timeout`] (with the last frame this client saw) if
    /// no new frame comes within `timeout`, [`WaitError::ServerGone`] if the
    /// server process exits meanwhile (see [`Client::next_event`] to ride
    /// through a restart), [`WaitError::Interrupted`] if the interrupt check
    /// ([`set_interrupt_check`](crate::set_interrupt_check)) ends the wait,
    /// [`WaitError::ProtocolMismatch`] for a frame of another protocol version,
    /// and [`WaitError::Transport`] if iceoryx2 fails to receive or wait.
    pub fn wait_for_tick(&mut self, timeout: Duration) -> Result<WorldSnapshot, WaitError> {
        self.wait_for_frame(timeout).map(|view| view.to_snapshot())
    }

    /// [`Client::wait_for_tick`] without the copy: the frame is read in
    /// place in shared memory until the view is dropped (hold at most a few).
    ///
    /// # Errors
    ///
    /// Returns the [`WaitError`]s of [`Client::wait_for_tick`]:
    /// [`WaitError::Timeout`] if no new frame comes within `timeout`,
    /// [`WaitError::ServerGone`] if the server process exits meanwhile,
    /// [`WaitError::Interrupted`], [`WaitError::ProtocolMismatch`] or
    /// [`WaitError::Transport`].
    ///
    /// # Examples
    ///
    /// A server runs on a thread here, so the example runs as a test:
    ///
    /// ```
    /// use std::time::Duration;
    /// use sim_client::Client;
    ///
    /// # fn main() -> Result<(), Box<dyn std::error::Error>> {
    /// # use std::sync::{atomic::{AtomicBool, Ordering}, Arc};
    /// # let name = format!("doc-{}-{}", "frame", std::process::id());
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
    /// let view = client.wait_for_frame(Duration::from_secs(1))?; // read in place
    /// assert_eq!(view.actors().len(), view.header().actor_count as usize);
    /// let seen = view.frame();
    /// drop(view); // the sample goes back to the server's pool
    /// let next = client.wait_for_frame(Duration::from_secs(1))?;
    /// assert!(next.frame() > seen);
    /// # drop(next);
    /// # drop(client);
    /// # stop.store(true, Ordering::Relaxed);
    /// # server.join().expect("server thread")?;
    /// # Ok(())
    /// # }
    /// ```
    pub fn wait_for_frame(&mut self, timeout: Duration) -> Result<FrameView, WaitError> {
        self.frames
            .next(timeout, self.world.as_str(), Some(self.server_pid))
    }

    pub(crate) fn request(&self, request: ControlRequest) -> Result<ControlResponse, RequestError> {
        self.request_within(request, self.request_timeout)
    }

    fn request_within(
        &self,
        mut request: ControlRequest,
        timeout: Duration,
    ) -> Result<ControlResponse, RequestError> {
        request.client_name = FixedText::new(process_name());
        let response = self.control()?.request(request, timeout, Wait::Backoff)?;
        if response.status == ResponseStatus::UnknownRequest as u32 {
            return Err(RequestError::UnknownRequest);
        }
        Ok(response)
    }

    /// The batch port, opened on first use.
    pub(crate) fn batch(&self) -> Result<&BatchClient, RequestError> {
        if let Some(batch) = self.batch.get() {
            return Ok(batch);
        }
        let (world, pid) = (self.world.as_str(), self.server_pid);
        let batch = open_batch_client(&self.node, &self.names, world, pid)?;
        let batch = self.batch.get_or_init(|| batch);
        // A request sent before the server has connected to a new port may
        // go unanswered: an empty batch, retried until answered, makes sure
        // both directions are connected before the first real one.
        let deadline = Instant::now() + self.request_timeout;
        loop {
            match self.round_trip_empty_batch(batch, BATCH_HANDSHAKE_ATTEMPT) {
                Ok(()) => return Ok(batch),
                Err(RequestError::Timeout { .. }) if Instant::now() < deadline => continue,
                // The whole wait, not the last attempt's, is what timed out.
                Err(RequestError::Timeout { world, .. }) => {
                    return Err(RequestError::Timeout {
                        world,
                        timeout: self.request_timeout,
                    })
                }
                Err(e) => return Err(e),
            }
        }
    }
}

impl Drop for Client {
    fn drop(&mut self) {
        if let Some(dispatcher) = self.dispatcher.take() {
            dispatcher.stop();
        }
    }
}

impl std::fmt::Debug for Client {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Client")
            .field("world", &self.world)
            .field("server_pid", &self.server_pid)
            .field("request_timeout", &self.request_timeout)
            .field("control_open", &self.control.get().is_some())
            .field("batch_open", &self.batch.get().is_some())
            .field("sensor_port_open", &self.sensor_port.get().is_some())
            .field("last_frame", &self.frames.last_frame())
            .finish_non_exhaustive()
    }
}

impl Client {
    /// Calls `callback` with every new frame, on a background thread with its
    /// own subscription, until [`Client::remove_on_tick`] or the client drops.
    ///
    /// # Errors
    ///
    /// The first callback starts the background thread and its subscription:
    /// [`ConnectError::NoServer`] if the world's frames do not appear within
    /// [`DEFAULT_REQUEST_TIMEOUT`], [`ConnectError::Full`] if the world admits
    /// no more frame subscribers, [`ConnectError::Transport`] if the thread
    /// cannot be started or has stopped, and the other errors of
    /// [`Client::connect`].
    pub fn on_tick(
        &mut self,
        callback: impl FnMut(&WorldSnapshot) + Send + 'static,
    ) -> Result<CallbackId, ConnectError> {
        let dispatcher = match &mut self.dispatcher {
            Some(dispatcher) => dispatcher,
            slot => slot.insert(TickDispatcher::start(&self.world, DEFAULT_REQUEST_TIMEOUT)?),
        };
        dispatcher.add(Box::new(callback))
    }

    /// Removes a callback; `false` if `id` was not registered.
    pub fn remove_on_tick(&mut self, id: CallbackId) -> bool {
        self.dispatcher
            .as_mut()
            .is_some_and(|dispatcher| dispatcher.remove(id))
    }
}
