//! [`Sensor`]: a subscription to one sensor's captures, read in place in
//! shared memory.

use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::{Arc, OnceLock};
use std::time::{Duration, Instant};

use iceoryx2::port::listener::Listener;
use iceoryx2::port::subscriber::Subscriber;
use iceoryx2::port::subscriber::SubscriberCreateError;
use iceoryx2::prelude::*;
use shared_types::limits::MAX_SENSOR_READERS_FLAG;
use shared_types::{
    Bgra, CollisionEvent, GnssMeasurement, ImuMeasurement, LidarPoint, ObstacleDetection,
    RadarDetection, ResponseStatus, SemanticLidarPoint, SensorEnd, SensorHeader, SensorInfo,
    SensorKind, SensorRefusal, SensorRequest, SensorResponseHeader, SensorSpec, SensorSpecError,
    ServiceNames, WorldName, PROTOCOL_VERSION,
};
use simbus_transport::spec::WorldServices;
use simbus_transport::Bus;

use crate::open::{frame_ready_listener, open_with_retry, OpenFailure};
use crate::rpc::RequestPort;
use crate::wait::{self, Stop, Wait};
use crate::{Capture, RequestError, WaitError, WaitMode};

type Sub<T> = Subscriber<Bus, [T], SensorHeader>;

/// The request port of the world's sensor service (spawn, list, destroy).
pub(crate) type SensorRequestClient =
    RequestPort<SensorRequest, [SensorInfo], (), SensorResponseHeader>;

enum Port {
    Depth(Sub<f32>),
    Image(Sub<Bgra>),
    Lidar(Sub<LidarPoint>),
    SemanticLidar(Sub<SemanticLidarPoint>),
    Radar(Sub<RadarDetection>),
    Imu(Sub<ImuMeasurement>),
    Gnss(Sub<GnssMeasurement>),
    Collision(Sub<CollisionEvent>),
    Obstacle(Sub<ObstacleDetection>),
}

/// Why a sensor request failed.
#[derive(Debug, thiserror::Error)]
pub enum SensorError {
    /// The spec breaks a rule (checked before anything is sent).
    #[error("invalid sensor: {0}")]
    InvalidSpec(#[from] SensorSpecError),
    /// The server refused: invalid spec, unknown actor, unknown sensor, no
    /// memory for its captures.
    #[error("sensor refused: {0}")]
    Refused(SensorRefusal),
    /// No sensor has this id in the world: never spawned, or it has ended
    /// (the server's [`SensorRefusal::UnknownSensor`], with the id asked for).
    #[error("unknown sensor {id} in world '{world}' (never spawned, or it has ended)")]
    UnknownSensor {
        /// The sensor id asked for.
        id: u64,
        /// The world.
        world: String,
    },
    /// The request failed.
    #[error(transparent)]
    Request(#[from] RequestError),
}

/// A subscription to one sensor. In synchronous mode, a reader that drains
/// its queue before the next tick gets every capture, in order, each once;
/// a reader that must never miss one joins the lockstep, so the server
/// waits for it. Slower readers lose the oldest captures (4 are kept),
/// counted by [`Sensor::missed`].
///
/// # Threads
///
/// Neither [`Send`] nor [`Sync`]: its iceoryx2 ports belong to the thread
/// that opened them. A thread that needs one subscribes there ([`Client::sensor`]), from a client of its own.
///
/// ```compile_fail
/// fn to_another_thread<T: Send>(_: T) {}
/// # fn f(handle: sim_client::Sensor) {
/// to_another_thread(handle); // its ports belong to this thread
/// # }
/// ```
pub struct Sensor {
    info: SensorInfo,
    reader: Reader,
    ready: Listener<Bus>,
    mode: WaitMode,
    world: String,
    server_pid: u32,
    _node: Node<Bus>,
}

/// The subscription and what reading it has counted.
struct Reader {
    id: u64,
    port: Port,
    last_sequence: Option<u64>,
    /// The frame of the last capture received.
    last_frame: Option<u64>,
    /// Set once the server said the stream ended.
    ended: Option<SensorEnd>,
    missed: u64,
}

impl Reader {
    /// The next queued capture, counting gaps and noticing the end.
    fn next(&mut self) -> Result<Option<Capture>, WaitError> {
        if let Some(reason) = self.ended {
            return Err(WaitError::SensorEnded {
                sensor: self.id,
                reason,
            });
        }
        let capture = match &self.port {
            Port::Depth(s) => s.receive().map(|c| c.map(Capture::Depth)),
            Port::Image(s) => s.receive().map(|c| c.map(Capture::Image)),
            Port::Lidar(s) => s.receive().map(|c| c.map(Capture::Lidar)),
            Port::SemanticLidar(s) => s.receive().map(|c| c.map(Capture::SemanticLidar)),
            Port::Radar(s) => s.receive().map(|c| c.map(Capture::Radar)),
            Port::Imu(s) => s.receive().map(|c| c.map(Capture::Imu)),
            Port::Gnss(s) => s.receive().map(|c| c.map(Capture::Gnss)),
            Port::Collision(s) => s.receive().map(|c| c.map(Capture::Collision)),
            Port::Obstacle(s) => s.receive().map(|c| c.map(Capture::Obstacle)),
        }
        .map_err(|e| WaitError::transport("sensor receive", e))?;
        if let Some(capture) = &capture {
            let header = capture.header();
            if header.protocol_version != PROTOCOL_VERSION {
                return Err(WaitError::ProtocolMismatch {
                    got: header.protocol_version,
                    client: PROTOCOL_VERSION,
                });
            }
            if let Some(reason) = header.end() {
                self.ended = Some(reason);
                return Err(WaitError::SensorEnded {
                    sensor: self.id,
                    reason,
                });
            }
            self.last_frame = Some(header.frame);
            if let Some(last) = self.last_sequence {
                self.missed += header.sequence.saturating_sub(last.saturating_add(1));
            }
            self.last_sequence = Some(header.sequence);
        }
        Ok(capture)
    }
}

impl Sensor {
    /// Subscribes to sensor `info` of `world` (whose server is `server_pid`),
    /// waiting up to `timeout` for its service.
    pub(crate) fn open(
        world: &WorldName,
        server_pid: u32,
        timeout: Duration,
        info: SensorInfo,
    ) -> Result<Self, RequestError> {
        let names = ServiceNames::new(world);
        let node = simbus_transport::node(&format!("sensor-{}-reader", info.id))
            .map_err(|e| RequestError::transport("node", e))?;
        let deadline = Instant::now() + timeout;
        let specs =
            WorldServices::new(&names).map_err(|e| RequestError::transport("service name", e))?;
        fn subscribe<T: std::fmt::Debug + ZeroCopySend + 'static>(
            node: &Node<Bus>,
            specs: &WorldServices,
            id: u64,
            deadline: Instant,
        ) -> Result<Sub<T>, RequestError> {
            use iceoryx2::service::builder::publish_subscribe::PublishSubscribeOpenError as E;
            let spec = specs
                .sensor::<T>(id)
                .map_err(|e| RequestError::transport("service name", e))?;
            let service = open_with_retry(
                deadline,
                || spec.open(node),
                |e| matches!(e, E::DoesNotExist | E::HangsInCreation),
            )
            .map_err(|e| RequestError::transport("sensor service", e))?
            .ok_or(RequestError::transport("sensor service", "does not exist"))?;
            spec.subscriber(&service).map_err(|e| match e {
                SubscriberCreateError::ExceedsMaxSupportedSubscribers => RequestError::Full {
                    what: "readers of this sensor",
                    max: service.static_config().max_subscribers(),
                    flag: MAX_SENSOR_READERS_FLAG,
                },
                e => RequestError::transport("sensor subscriber", e),
            })
        }
        let port = match info.spec.sensor_kind() {
            Some(SensorKind::Depth) => Port::Depth(subscribe(&node, &specs, info.id, deadline)?),
            Some(SensorKind::Rgb | SensorKind::Semantic | SensorKind::Instance) => {
                Port::Image(subscribe(&node, &specs, info.id, deadline)?)
            }
            Some(SensorKind::Lidar) => Port::Lidar(subscribe(&node, &specs, info.id, deadline)?),
            Some(SensorKind::SemanticLidar) => {
                Port::SemanticLidar(subscribe(&node, &specs, info.id, deadline)?)
            }
            Some(SensorKind::Radar) => Port::Radar(subscribe(&node, &specs, info.id, deadline)?),
            Some(SensorKind::Imu) => Port::Imu(subscribe(&node, &specs, info.id, deadline)?),
            Some(SensorKind::Gnss) => Port::Gnss(subscribe(&node, &specs, info.id, deadline)?),
            Some(SensorKind::Collision) => {
                Port::Collision(subscribe(&node, &specs, info.id, deadline)?)
            }
            Some(SensorKind::Obstacle) => {
                Port::Obstacle(subscribe(&node, &specs, info.id, deadline)?)
            }
            None => {
                return Err(RequestError::UnknownAnswer {
                    status: ResponseStatus::Ok as u32,
                })
            }
        };
        let ready = frame_ready_listener(&node, &names, deadline)
            .map_err(OpenFailure::into_request)?
            .ok_or(RequestError::transport(
                "frame-ready service",
                "does not exist",
            ))?;
        Ok(Self {
            info,
            reader: Reader {
                id: info.id,
                port,
                last_sequence: None,
                last_frame: None,
                ended: None,
                missed: 0,
            },
            ready,
            mode: WaitMode::Block,
            world: world.to_string(),
            server_pid,
            _node: node,
        })
    }

    /// The sensor's id.
    pub fn id(&self) -> u64 {
        self.info.id
    }

    /// How it was built.
    pub fn spec(&self) -> &SensorSpec {
        &self.info.spec
    }

    /// Captures lost since this subscription began (the reader fell more
    /// than 4 captures behind).
    pub fn missed(&self) -> u64 {
        self.reader.missed
    }

    /// How [`Sensor::recv`] waits for a capture: blocking on the
    /// frame-ready event (default), spinning, or both (as for frames).
    pub fn set_wait_mode(&mut self, mode: WaitMode) {
        self.mode = mode;
    }

    /// The next queued capture, without waiting.
    ///
    /// # Errors
    ///
    /// Returns [`WaitError::SensorEnded`] (with the reason) once the sensor is
    /// gone, and on every call after; [`WaitError::ProtocolMismatch`] for a
    /// capture of another protocol version; [`WaitError::Transport`] if
    /// iceoryx2 fails to receive.
    pub fn try_recv(&mut self) -> Result<Option<Capture>, WaitError> {
        self.reader.next()
    }

    /// Waits up to `timeout` for the next capture.
    ///
    /// Ends with [`WaitError::NoCapture`] when none came, and with
    /// [`WaitError::SensorEnded`] once the sensor is gone (destroyed, its
    /// parent destroyed, the world reloaded, the server stopped).
    ///
    /// # Errors
    ///
    /// Returns [`WaitError::NoCapture`] if no capture comes within `timeout`,
    /// [`WaitError::SensorEnded`] once the sensor is gone (destroyed, its
    /// parent destroyed, the world reloaded, the server stopped),
    /// [`WaitError::ServerGone`] if the server process exits,
    /// [`WaitError::Interrupted`] if the interrupt check ends the wait,
    /// [`WaitError::ProtocolMismatch`] for a capture of another protocol
    /// version, and [`WaitError::Transport`] if iceoryx2 fails to receive or
    /// wait.
    pub fn recv(&mut self, timeout: Duration) -> Result<Capture, WaitError> {
        let wait = Wait::for_mode(self.mode, &self.ready);
        let reader = &mut self.reader;
        let pid = self.server_pid;
        wait::until(Instant::now() + timeout, pid, wait, || reader.next()).map_err(
            |stop| match stop {
                Stop::Failed(e) => e,
                Stop::TimedOut => WaitError::NoCapture {
                    sensor: self.info.id,
                    world: self.world.clone(),
                    timeout,
                    last_frame: self.reader.last_frame,
                },
                Stop::ServerGone => WaitError::ServerGone {
                    world: self.world.clone(),
                    pid,
                },
                Stop::Interrupted => WaitError::Interrupted {
                    world: self.world.clone(),
                },
                Stop::Event(e) => WaitError::transport("frame-ready wait", e),
            },
        )
    }

    /// Every capture queued now, oldest first (drain before the next
    /// tick). An error (the sensor ended, another protocol version) is the
    /// last item, never a silent end.
    pub fn queue(&mut self) -> impl Iterator<Item = Result<Capture, WaitError>> + '_ {
        let mut failed = false;
        std::iter::from_fn(move || {
            if failed {
                return None;
            }
            match self.try_recv() {
                Ok(capture) => capture.map(Ok),
                Err(e) => {
                    failed = true;
                    Some(Err(e))
                }
            }
        })
    }

    /// Calls `callback` with every capture, on a background thread with its
    /// own subscription (CARLA's `sensor.listen`), until the returned
    /// handle is stopped or dropped.
    ///
    /// # Errors
    ///
    /// Returns [`SensorError::Request`] if the background thread cannot be
    /// started or cannot subscribe to the sensor ([`RequestError::Full`] if the
    /// sensor admits no more readers, `--max-sensor-readers`;
    /// [`RequestError::Transport`] if its service is gone or iceoryx2 refuses).
    pub fn listen(
        &self,
        mut callback: impl FnMut(&Capture) + Send + 'static,
    ) -> Result<Listening, SensorError> {
        let info = self.info;
        let world = WorldName::new(&self.world).map_err(|e| RequestError::transport("world", e))?;
        let server_pid = self.server_pid;
        let stop = Arc::new(AtomicBool::new(false));
        let ended = Arc::new(OnceLock::new());
        let (ready_tx, ready_rx) = std::sync::mpsc::channel();
        let (flag, end) = (stop.clone(), ended.clone());
        let thread = std::thread::Builder::new()
            .name(format!("simbus-sensor-{}", info.id))
            .spawn(move || {
                // Its own subscription, and nothing else.
                let opened = Sensor::open(&world, server_pid, crate::DEFAULT_REQUEST_TIMEOUT, info);
                let mut sensor = match opened {
                    Ok(sensor) => {
                        let _ = ready_tx.send(Ok(()));
                        sensor
                    }
                    Err(e) => {
                        let _ = ready_tx.send(Err(e));
                        return;
                    }
                };
                while !flag.load(Ordering::Relaxed) {
                    match sensor.recv(Duration::from_millis(100)) {
                        Ok(capture) => callback(&capture),
                        Err(WaitError::NoCapture { .. }) => {}
                        Err(e) => {
                            tracing::info!("sensor {} listener stopped: {e}", info.id);
                            let _ = end.set(e);
                            return;
                        }
                    }
                }
            })
            .map_err(|e| RequestError::transport("listen thread", e))?;
        ready_rx
            .recv()
            .map_err(|e| RequestError::transport("listen thread", e))??;
        Ok(Listening {
            stop,
            ended,
            thread: Some(thread),
        })
    }
}

/// A running [`Sensor::listen`]; [`Listening::stop`] or dropping it ends
/// the callbacks.
pub struct Listening {
    stop: Arc<AtomicBool>,
    /// Why the callbacks ended by themselves (the sensor ended, the server
    /// stopped), if they did.
    ended: Arc<OnceLock<WaitError>>,
    thread: Option<std::thread::JoinHandle<()>>,
}

impl Listening {
    /// Stops the callbacks (CARLA's `sensor.stop()`); the sensor stays in the world.
    pub fn stop(self) {}

    /// Why the callbacks ended by themselves, if they did: the sensor ended
    /// ([`WaitError::SensorEnded`]), or the server is gone.
    pub fn ended(&self) -> Option<&WaitError> {
        self.ended.get()
    }
}

impl Drop for Listening {
    fn drop(&mut self) {
        self.stop.store(true, Ordering::Relaxed);
        if let Some(thread) = self.thread.take() {
            let _ = thread.join();
        }
    }
}

impl std::fmt::Debug for Capture {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Capture")
            .field("header", self.header())
            .field("bytes", &self.bytes().len())
            .finish()
    }
}

impl std::fmt::Debug for Sensor {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Sensor")
            .field("info", &self.info)
            .field("world", &self.world)
            .field("missed", &self.reader.missed)
            .field("ended", &self.reader.ended)
            .finish_non_exhaustive()
    }
}

impl std::fmt::Debug for Listening {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("Listening")
            .field("running", &self.thread.is_some())
            .finish()
    }
}
