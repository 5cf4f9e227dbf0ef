//! The world live in Foxglove (`sim-client foxglove`), over the Foxglove
//! WebSocket protocol (subprotocol `foxglove.sdk.v1`, the `foxglove` SDK's
//! server). Open `ws://HOST:PORT` in Foxglove:
//!
//! - `/simbus/scene`: every actor as a `foxglove.SceneUpdate` entity (boxes,
//!   spheres, capsules as a cylinder and two spheres, vehicles, the ground),
//!   in frame `world` (simbus's: Y up, metres), one update per frame sent;
//! - the server's clock is the simulation's (the protocol's `time`
//!   capability), and every message is stamped with the frame's time;
//! - `/simbus/sensor/<id>/depth`: each depth camera as a `foxglove.RawImage`
//!   (`32FC1`, metres), `/simbus/sensor/<id>/points`: each lidar as a
//!   `foxglove.PointCloud` (x, y, z, intensity as float32) posed at the
//!   sensor in frame `world`.
//!
//! Frames are sent at the simulation's rate or at most [`Config::max_hz`]; the
//! captures sent are those of the frames sent. Sensors spawned later are
//! picked up within a second.

use std::collections::BTreeMap;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;
use std::time::{Duration, Instant};

use foxglove::messages::{SceneEntityDeletion, SceneUpdate};
use foxglove::websocket::Capability;
use foxglove::{Channel, Context, FoxgloveError, WebSocketServer, WebSocketServerHandle};
use shared_types::WorldName;
use sim_client::{Client, ConnectError, FrameView, SensorError, WaitError, WaitMode};
use tracing::debug;

mod scene;
mod sensors;

use sensors::Forward;

/// How often the view looks for sensors spawned since.
const LOOK_EVERY: Duration = Duration::from_secs(1);
/// The longest a wait for a frame runs before the stop flag is read again.
const SLICE: Duration = Duration::from_millis(200);

/// What to serve, where.
#[derive(Debug, Clone)]
pub struct Config {
    /// The address to listen on.
    pub host: String,
    /// The port to listen on (0: any free port; [`Listening::port`] says
    /// which).
    pub port: u16,
    /// The most frames sent per wall second (0: every frame).
    pub max_hz: f64,
    /// How long to wait for the world's server to answer.
    pub timeout: Duration,
}

/// Where the view listens, once it does.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct Listening {
    /// The port bound (the one asked for, or the free one taken for 0).
    pub port: u16,
}

/// What a view that ended sent.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub struct Served {
    /// The frames sent.
    pub frames: u64,
}

/// Why the view could not start or ended.
#[derive(Debug, thiserror::Error)]
#[non_exhaustive]
pub enum ServeError {
    /// [`Config::max_hz`] is negative or not a number: refused input.
    #[error("--max-hz must be 0 (every frame) or a positive rate, not {max_hz}")]
    MaxHz {
        /// The rate given.
        max_hz: f64,
    },
    /// The world's server did not answer.
    #[error(transparent)]
    Connect(#[from] ConnectError),
    /// The WebSocket server could not listen.
    #[error("listening on {host}:{port}")]
    Listen {
        /// The address asked for.
        host: String,
        /// The port asked for.
        port: u16,
        /// Why.
        #[source]
        source: FoxgloveError,
    },
    /// The world's sensors could not be listed.
    #[error(transparent)]
    Sensors(#[from] SensorError),
    /// The world's frames stopped (its server is gone).
    #[error(transparent)]
    Wait(#[from] WaitError),
}

impl ServeError {
    /// Whether the input was refused (nothing was started), as opposed to
    /// a failure talking to the world or the network.
    pub fn is_refused(&self) -> bool {
        matches!(self, Self::MaxHz { .. })
    }
}

/// Serves `world` to Foxglove until `stop` is set; `on_listening` is told
/// where, once the server listens. Returns what was sent.
///
/// # Errors
///
/// Returns [`ServeError::MaxHz`] if [`Config::max_hz`] is negative or not a
/// number (nothing is started); [`ServeError::Connect`] if the world's server
/// cannot be reached within the config's timeout; [`ServeError::Listen`] if the
/// WebSocket server cannot listen on the address asked for;
/// [`ServeError::Sensors`] if the world's sensors cannot be listed or
/// subscribed; and [`ServeError::Wait`] if the world's frames stop (its server
/// is gone). Setting `stop` ends it with `Ok`.
pub fn serve(
    world: &WorldName,
    config: &Config,
    stop: &AtomicBool,
    on_listening: impl FnOnce(&Listening),
) -> Result<Served, ServeError> {
    let mut view = View::start(world, config)?;
    on_listening(&Listening {
        port: view.server.port(),
    });
    let ended = view.run(stop);
    view.server.stop().wait_blocking();
    ended?;
    Ok(Served { frames: view.sent })
}

/// A running view: the world's client, the WebSocket server and what it
/// forwards.
struct View {
    client: Client,
    ctx: Arc<Context>,
    server: WebSocketServerHandle,
    scene: Channel<SceneUpdate>,
    forwards: BTreeMap<u64, Forward>,
    /// The least wall time between two frames sent.
    min_gap: Duration,
    last_sent: Option<Instant>,
    last_look: Option<Instant>,
    sent: u64,
    /// Whether the last scene sent had the debug shapes' entity.
    drew_debug: bool,
}

impl View {
    /// Connects to `world` and starts the WebSocket server.
    fn start(world: &WorldName, config: &Config) -> Result<Self, ServeError> {
        let max_hz = config.max_hz;
        if !(max_hz.is_finite() && max_hz >= 0.0) {
            return Err(ServeError::MaxHz { max_hz });
        }
        let mut client = Client::connect(world.as_str(), config.timeout)?;
        client.set_request_timeout(config.timeout);
        client.set_wait_mode(WaitMode::Block);
        let ctx = Context::new();
        // Every channel of what is there now exists before the server
        // listens, so a viewer connecting once this returns gets them all
        // advertised at once: a channel made while a viewer registers can
        // be advertised to it before its session knows the channel (its
        // subscription is then refused as "unknown channel").
        let scene = ctx.channel_builder("/simbus/scene").build();
        let mut forwards = BTreeMap::new();
        sensors::pick_up(&client, &ctx, &mut forwards)?;
        let server = WebSocketServer::new()
            .name(format!("simbus {world}"))
            .context(&ctx)
            .bind(config.host.clone(), config.port)
            .capabilities([Capability::Time])
            .start_blocking()
            .map_err(|source| ServeError::Listen {
                host: config.host.clone(),
                port: config.port,
                source,
            })?;
        Ok(Self {
            client,
            ctx,
            server,
            scene,
            forwards,
            min_gap: if max_hz > 0.0 {
                Duration::from_secs_f64(1.0 / max_hz)
            } else {
                Duration::ZERO
            },
            last_sent: None,
            last_look: Some(Instant::now()),
            sent: 0,
            drew_debug: false,
        })
    }

    /// Serves frames until `stop` is set or the world's server is gone.
    /// The one wait point: the next frame (in slices, to notice `stop`).
    fn run(&mut self, stop: &AtomicBool) -> Result<(), ServeError> {
        while !stop.load(Ordering::Relaxed) {
            if self.last_look.is_none_or(|at| at.elapsed() >= LOOK_EVERY) {
                sensors::pick_up(&self.client, &self.ctx, &mut self.forwards)?;
                self.last_look = Some(Instant::now());
            }
            match self.client.wait_for_frame(SLICE) {
                Ok(frame) => self.on_frame(&frame),
                // A paused world (synchronous, nobody ticking): keep serving.
                // A dead server ends the wait with its own error instead.
                Err(WaitError::Timeout { .. }) => {}
                Err(e) => return Err(e.into()),
            }
        }
        Ok(())
    }

    /// Sends `frame` (unless the last went out less than the least gap
    /// ago): the scene, the clock, and each sensor's newest capture.
    fn on_frame(&mut self, frame: &FrameView) {
        if self.last_sent.is_some_and(|at| at.elapsed() < self.min_gap) {
            return;
        }
        self.last_sent = Some(Instant::now());
        let elapsed_ns = frame.timestamp().elapsed_ns;
        let time = scene::stamp(elapsed_ns);
        let actors = frame.actors();
        // What clients drew, asked for each frame sent (a viewer's pace).
        let shapes = match self.client.debug_shapes() {
            Ok(shapes) => shapes,
            Err(e) => {
                debug!("no debug shapes: {e}");
                Vec::new()
            }
        };
        let debug = scene::debug_entity(&shapes, time);
        // The debug entity goes when the last shape does.
        let deletions = if debug.is_none() && self.drew_debug {
            vec![SceneEntityDeletion {
                timestamp: Some(time),
                r#type: 0,
                id: "debug".into(),
            }]
        } else {
            Vec::new()
        };
        self.drew_debug = debug.is_some();
        let update = SceneUpdate {
            deletions,
            entities: actors
                .iter()
                .map(|a| scene::entity(a, time))
                .chain(debug)
                .collect(),
        };
        self.server.broadcast_time(elapsed_ns);
        self.scene.log_with_time(&update, elapsed_ns);
        for forward in self.forwards.values_mut() {
            sensors::forward_capture(forward, actors);
        }
        self.sent += 1;
    }
}
