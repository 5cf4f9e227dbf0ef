//! [`Client`]: a connection to one simbus world.

use shared_types::Bus;
use std::cell::OnceCell;
use std::collections::{BTreeMap, BTreeSet};
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{mpsc, Arc};
use std::thread::JoinHandle;
use std::time::{Duration, Instant};

use iceoryx2::prelude::*;
use shared_types::limits::MAX_CLIENTS_FLAG;
use shared_types::{
    ControlRequest, ControlResponse, FixedText, RequestKind, ResponseStatus, ServiceNames,
    StatusReport, WorldName, WorldSettings, PROTOCOL_VERSION,
};
use tracing::{debug, warn};

use crate::batch::{open_batch_client, BatchClient};
use crate::frames::FrameStream;
use crate::open::{open_with_retry, wake_notifier, OpenFailure};
use crate::rpc::{RequestPort, Wait};
use crate::FrameView;
use crate::WaitMode;
use crate::{
    ApplySettingsError, ConnectError, LoadWorldError, Participant, RequestError, TickError, Ticker,
    WaitError, WorldSnapshot,
};

/// The control port, with the notifier that wakes the server after a request.
pub(crate) type ControlPort = RequestPort<ControlRequest, ControlResponse>;

/// How long one attempt of the first empty batch of a new batch port waits.
const BATCH_HANDSHAKE_ATTEMPT: Duration = Duration::from_millis(100);

/// How long a control request waits for its answer unless told otherwise.
pub const DEFAULT_REQUEST_TIMEOUT: Duration = Duration::from_secs(5);

/// The id of a callback registered with [`Client::on_tick`].
#[derive(Debug, Clone, Copy, PartialEq, Eq, PartialOrd, Ord, Hash)]
pub struct CallbackId(u64);

type TickCallback = Box<dyn FnMut(&WorldSnapshot) + Send>;

/// The thread that calls `on_tick` callbacks, with its own subscription.
struct TickDispatcher {
    /// Registrations travel to the thread, which owns the callbacks: no
    /// lock is held while a user callback runs.
    changes: mpsc::Sender<Registration>,
    registered: BTreeSet<CallbackId>,
    stop: Arc<AtomicBool>,
    thread: Option<JoinHandle<()>>,
    next_id: u64,
}

/// A change to the dispatcher's callbacks.
enum Registration {
    Add(CallbackId, TickCallback),
    Remove(CallbackId),
}

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
pub struct Client {
    pub(crate) world: WorldName,
    node: Node<Bus>,
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
    pub(crate) names: ServiceNames,
    pub(crate) frames: FrameStream,
    pub(crate) server_pid: u32,
    pub(crate) request_timeout: Duration,
    dispatcher: Option<TickDispatcher>,
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

fn client_node() -> Result<Node<Bus>, ConnectError> {
    shared_types::environment::prepare().map_err(ConnectError::SharedDirectory)?;
    let name = NodeName::new("sim-client").map_err(|e| ConnectError::transport("node name", e))?;
    NodeBuilder::new()
        .name(&name)
        .signal_handling_mode(SignalHandlingMode::Disabled)
        .create::<Bus>()
        .map_err(|e| ConnectError::transport("node", e))
}

impl Client {
    /// Connects to the server of `world`, waiting up to `timeout` for it to
    /// appear and publish its current frame, which carries the protocol
    /// version (checked) and the server's pid (watched in every wait).
    ///
    /// Only the frame subscription and its listener are opened here; the
    /// control, batch and sensor ports open on first use and stay open.
    pub fn connect(world: &str, timeout: Duration) -> Result<Self, ConnectError> {
        let world = WorldName::new(world)?;
        let deadline = Instant::now() + timeout;
        let names = ServiceNames::new(&world);
        let node = client_node()?;
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
        use iceoryx2::service::port_factory::client::ClientCreateError;
        if let Some(port) = self.control.get() {
            return Ok(port);
        }
        let deadline = Instant::now() + self.request_timeout;
        let name = ServiceName::new(&self.names.control)
            .map_err(|e| RequestError::transport("service name", e))?;
        let service = open_with_retry(
            deadline,
            || {
                self.node
                    .service_builder(&name)
                    .request_response::<ControlRequest, ControlResponse>()
                    .open()
            },
            |e| {
                matches!(
                    e,
                    RequestResponseOpenError::DoesNotExist
                        | RequestResponseOpenError::HangsInCreation
                )
            },
        )
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
        let client = service.client_builder().create().map_err(|e| match e {
            ClientCreateError::ExceedsMaxSupportedClients => RequestError::Full {
                what: "clients sending requests",
                max: service.static_config().max_clients(),
                flag: MAX_CLIENTS_FLAG,
            },
            e => RequestError::transport("control client", e),
        })?;
        let wake = wake_notifier(&self.node, &self.names, deadline)
            .map_err(OpenFailure::into_request)?
            .ok_or_else(|| RequestError::ServerGone {
                world: self.world.to_string(),
                pid: self.server_pid,
            })?;
        Ok(self
            .control
            .get_or_init(|| RequestPort::new(client, wake, self.world.as_str(), self.server_pid)))
    }

    /// Wakes the server after a request was sent on any port.
    pub(crate) fn wake_server(&self) -> Result<(), RequestError> {
        self.control()?.wake();
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

    /// The world's status: current frame, settings, scene, actors.
    pub fn status(&self) -> Result<StatusReport, RequestError> {
        Ok(self
            .request(ControlRequest::new(RequestKind::Status))?
            .report)
    }

    /// The settings in force for the next frame.
    pub fn get_settings(&self) -> Result<WorldSettings, RequestError> {
        let response = self.request(ControlRequest::new(RequestKind::GetSettings))?;
        Ok(response.report.settings.into())
    }

    /// Applies `settings` and returns the first frame computed with them.
    /// Refused settings come back as [`ApplySettingsError::Invalid`] and
    /// leave the server's settings unchanged.
    pub fn apply_settings(&self, settings: WorldSettings) -> Result<u64, ApplySettingsError> {
        // Check here first: a clear error without a round trip. The server
        // checks again, since not every sender is this library.
        settings.validate()?;
        let response = self.request(ControlRequest::apply_settings(settings))?;
        match ResponseStatus::from_u32(response.status) {
            Some(ResponseStatus::Ok) => Ok(response.effective_frame),
            Some(ResponseStatus::SyncNeedsTicker) => Err(ApplySettingsError::SyncNeedsTicker),
            Some(ResponseStatus::NotTicker) => Err(ApplySettingsError::TickerHolds {
                owner: response.report.ticker,
            }),
            Some(ResponseStatus::InvalidSettings) => match response.settings_error() {
                Some(error) => Err(ApplySettingsError::Invalid(error)),
                None => Err(RequestError::UnknownAnswer {
                    status: response.status,
                }
                .into()),
            },
            _ => Err(RequestError::UnknownAnswer {
                status: response.status,
            }
            .into()),
        }
    }

    /// Loads `scene` (`default`, `empty`, `boxes:N`) as a new episode that
    /// starts at frame 0; settings are kept unless `reset_settings`.
    pub fn load_world(
        &self,
        scene: &str,
        reset_settings: bool,
    ) -> Result<StatusReport, LoadWorldError> {
        if let Err(reason) = scene.parse::<shared_types::scene::SceneName>() {
            return Err(LoadWorldError::UnknownScene {
                scene: scene.to_owned(),
                reason,
            });
        }
        self.load(
            ControlRequest::load_world(Some(scene), reset_settings),
            scene,
        )
    }

    /// Restores the current scene's initial state (actors and physics; the
    /// actors get new ids, never reused within the server's life) as
    /// a new episode that starts at frame 0; settings are kept unless
    /// `reset_settings`.
    pub fn reload_world(&self, reset_settings: bool) -> Result<StatusReport, LoadWorldError> {
        self.load(ControlRequest::load_world(None, reset_settings), "")
    }

    fn load(&self, request: ControlRequest, scene: &str) -> Result<StatusReport, LoadWorldError> {
        let response = self.request(request)?;
        match ResponseStatus::from_u32(response.status) {
            Some(ResponseStatus::Ok) => Ok(response.report),
            Some(ResponseStatus::UnknownScene) => Err(LoadWorldError::UnknownScene {
                scene: scene.to_owned(),
                reason: scene
                    .parse::<shared_types::scene::SceneName>()
                    .err()
                    .unwrap_or_else(|| {
                        shared_types::scene::SceneNameError::Unknown(scene.to_owned())
                    }),
            }),
            Some(ResponseStatus::LoadFailed) => Err(LoadWorldError::Failed {
                world: self.world.to_string(),
            }),
            Some(ResponseStatus::NotTicker) => Err(LoadWorldError::TickerHolds {
                owner: response.report.ticker,
            }),
            _ => Err(RequestError::UnknownAnswer {
                status: response.status,
            }
            .into()),
        }
    }

    /// Waits up to `timeout` for a frame newer than the last one this client
    /// received and returns it.
    ///
    /// In synchronous mode frames come in order, each once. In asynchronous
    /// mode a client that fell behind gets the newest frame, and
    /// [`WorldSnapshot::missed`] says how many it skipped.
    pub fn wait_for_tick(&mut self, timeout: Duration) -> Result<WorldSnapshot, WaitError> {
        self.wait_for_frame(timeout).map(|view| view.to_snapshot())
    }

    /// [`Client::wait_for_tick`] without the copy: the frame is read in
    /// place in shared memory until the view is dropped (hold at most a few).
    pub fn wait_for_frame(&mut self, timeout: Duration) -> Result<FrameView, WaitError> {
        self.frames
            .next(timeout, self.world.as_str(), Some(self.server_pid))
    }

    /// Calls `callback` with every new frame, on a background thread with its
    /// own subscription, until [`Client::remove_on_tick`] or the client drops.
    pub fn on_tick(
        &mut self,
        callback: impl FnMut(&WorldSnapshot) + Send + 'static,
    ) -> Result<CallbackId, ConnectError> {
        let dispatcher = match &mut self.dispatcher {
            Some(dispatcher) => dispatcher,
            slot => slot.insert(Self::start_dispatcher(&self.world)?),
        };
        dispatcher.next_id += 1;
        let id = CallbackId(dispatcher.next_id);
        dispatcher
            .changes
            .send(Registration::Add(id, Box::new(callback)))
            .map_err(|_| ConnectError::transport("on_tick thread", "the thread has stopped"))?;
        dispatcher.registered.insert(id);
        Ok(id)
    }

    /// Removes a callback; `false` if `id` was not registered.
    pub fn remove_on_tick(&mut self, id: CallbackId) -> bool {
        let Some(dispatcher) = &mut self.dispatcher else {
            return false;
        };
        if !dispatcher.registered.remove(&id) {
            return false;
        }
        // If the thread has stopped, nothing calls the callback any more.
        let _ = dispatcher.changes.send(Registration::Remove(id));
        true
    }

    fn start_dispatcher(world: &WorldName) -> Result<TickDispatcher, ConnectError> {
        let (changes, incoming) = mpsc::channel::<Registration>();
        let stop = Arc::new(AtomicBool::new(false));
        let world = world.clone();
        let (ready_tx, ready_rx) = mpsc::channel();
        let thread = {
            let stop = stop.clone();
            std::thread::Builder::new()
                .name("simbus-on-tick".into())
                .spawn(move || {
                    let opened = client_node().and_then(|node| {
                        let deadline = Instant::now() + DEFAULT_REQUEST_TIMEOUT;
                        let names = ServiceNames::new(&world);
                        let stream = FrameStream::open(&node, &names, world.as_str(), deadline)?;
                        Ok((node, stream))
                    });
                    let (_node, mut stream) = match opened {
                        Ok((node, Some(stream))) => {
                            let _ = ready_tx.send(Ok(()));
                            (node, stream)
                        }
                        Ok((_, None)) => {
                            let _ = ready_tx.send(Err(ConnectError::NoServer {
                                world: world.to_string(),
                                timeout: DEFAULT_REQUEST_TIMEOUT,
                            }));
                            return;
                        }
                        Err(e) => {
                            let _ = ready_tx.send(Err(e));
                            return;
                        }
                    };
                    let mut callbacks: BTreeMap<CallbackId, TickCallback> = BTreeMap::new();
                    while !stop.load(Ordering::Relaxed) {
                        match stream.next(Duration::from_millis(100), world.as_str(), None) {
                            Ok(view) => {
                                let snapshot = view.to_snapshot();
                                drop(view);
                                // Whatever was registered before this frame
                                // arrived sees it.
                                for change in incoming.try_iter() {
                                    match change {
                                        Registration::Add(id, callback) => {
                                            callbacks.insert(id, callback);
                                        }
                                        Registration::Remove(id) => {
                                            callbacks.remove(&id);
                                        }
                                    }
                                }
                                for callback in callbacks.values_mut() {
                                    callback(&snapshot);
                                }
                            }
                            Err(WaitError::Timeout { .. }) => {}
                            Err(e) => {
                                warn!("on_tick dispatcher stopped: {e}");
                                return;
                            }
                        }
                    }
                })
                .map_err(|e| ConnectError::transport("on_tick thread", e))?
        };
        ready_rx
            .recv()
            .map_err(|e| ConnectError::transport("on_tick thread start", e))??;
        Ok(TickDispatcher {
            changes,
            registered: BTreeSet::new(),
            stop,
            thread: Some(thread),
            next_id: 0,
        })
    }

    fn request(&self, request: ControlRequest) -> Result<ControlResponse, RequestError> {
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

    /// Claims tick ownership of the world. Fails with
    /// [`TickError::NotTicker`], naming the owner, while another client ticks.
    pub fn claim_ticker(&self) -> Result<Ticker, TickError> {
        self.claim_ticker_as(&default_ticker_name())
    }

    /// [`Client::claim_ticker`] with the node name others see as the owner.
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

    /// Joins the world's lockstep as `name`: in synchronous mode the server
    /// then waits for this participant's [`Participant::done`] every frame.
    pub fn join_lockstep(&self, name: &str) -> Result<Participant, RequestError> {
        Participant::join(&self.world, self.server_pid, name, self.request_timeout)
    }

    /// The batch port, opened on first use.
    pub(crate) fn batch(&self) -> Result<&BatchClient, RequestError> {
        if let Some(batch) = self.batch.get() {
            return Ok(batch);
        }
        let batch = open_batch_client(&self.node, &self.names.batch)?;
        let batch = self.batch.get_or_init(|| batch);
        // A request sent before the server has connected to a new port may
        // go unanswered: an empty batch, retried until answered, makes sure
        // both directions are connected before the first real one.
        let deadline = Instant::now() + self.request_timeout;
        loop {
            match self.round_trip_empty_batch(batch, BATCH_HANDSHAKE_ATTEMPT) {
                Ok(()) => return Ok(batch),
                Err(RequestError::Timeout { .. }) if Instant::now() < deadline => continue,
                Err(e) => return Err(e),
            }
        }
    }

    /// The iceoryx2 node of this client (for tools that open more ports).
    pub fn node(&self) -> &Node<Bus> {
        &self.node
    }
}

impl Drop for Client {
    fn drop(&mut self) {
        if let Some(mut dispatcher) = self.dispatcher.take() {
            dispatcher.stop.store(true, Ordering::Relaxed);
            if let Some(thread) = dispatcher.thread.take() {
                let _ = thread.join();
            }
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
