//! How a server is started: the settings it was given, immutable for its
//! life. What changes while it runs (settings, scene, episode) is
//! [`crate::state::Runtime`].

use std::num::{NonZeroU64, NonZeroUsize};
use std::path::PathBuf;
use std::time::Duration;

use shared_types::limits::WorldLimits;
use shared_types::{WaitMode, WorldName, WorldSettings};

use crate::scene::Scene;

/// How a server is started.
#[derive(Debug, Clone)]
pub struct ServerConfig {
    /// The world the server owns.
    pub world: WorldName,
    /// The scene loaded at start.
    pub scene: Scene,
    /// The settings at start (validated by `Server::start`).
    pub settings: WorldSettings,
    /// Fixed step, async: pace frames so simulation time follows wall time.
    pub realtime: bool,
    /// Variable step, async: at most this many frames per second (0 = no limit).
    pub max_fps: f64,
    /// Stop after computing this many frames.
    pub max_frames: Option<u64>,
    /// What to do when the ticker dies in synchronous mode.
    pub on_ticker_loss: OnTickerLoss,
    /// Synchronous mode: how the server waits for the next tick — block on
    /// the wake-up event, spin (lowest latency, one core busy), or hybrid
    /// (poll for `hybrid_window` after each frame, then block).
    pub wait_mode: WaitMode,
    /// Hybrid waiting: how long to poll for the next tick after a frame (a
    /// ticker in a tight loop then costs no kernel wake-up).
    pub hybrid_window: Duration,
    /// Seed of the scene's placement (0: none); kept across reloads.
    pub seed: u64,
    /// A lockstep participant that keeps a tick waiting this long is
    /// dropped (a hung reader must not stop the world).
    pub lockstep_timeout: Duration,
    /// How many clients (and readers per sensor) the world admits.
    pub limits: WorldLimits,
    /// Simulation seconds between a recording's keyframes (`None`: 10 s).
    pub keyframe_seconds: Option<f64>,
    /// Threads cameras and lidars render on (`None`: rayon's global pool,
    /// one per CPU). Fewer than the CPUs leave one to a reader spinning on
    /// a capture.
    pub render_threads: Option<NonZeroUsize>,
    /// Journal the run into a directory (`None`: no journal).
    pub journal: Option<JournalOptions>,
}

impl ServerConfig {
    /// The defaults `sim-server` starts `world` with: the default scene,
    /// asynchronous mode with a variable step (at most 100 FPS), hybrid
    /// waiting, a 10 s lockstep timeout, the default limits.
    pub fn new(world: WorldName) -> Self {
        Self {
            world,
            scene: Scene::Default,
            settings: WorldSettings::default(),
            realtime: false,
            max_fps: 100.0,
            max_frames: None,
            on_ticker_loss: OnTickerLoss::Wait,
            wait_mode: WaitMode::Hybrid,
            hybrid_window: Duration::from_micros(100),
            seed: 0,
            lockstep_timeout: Duration::from_secs(10),
            limits: WorldLimits::default(),
            keyframe_seconds: None,
            render_threads: None,
            journal: None,
        }
    }
}

/// The policy when the ticker dies while the world is in synchronous mode.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum OnTickerLoss {
    /// Stay in synchronous mode and wait for a new ticker.
    #[default]
    Wait,
    /// Fall back to asynchronous mode.
    Async,
}

/// How often the journal is made durable.
#[derive(Debug, Clone, Copy, PartialEq, Eq, Default)]
pub enum JournalSync {
    /// Every frame in synchronous mode, every 50 frames in asynchronous mode.
    #[default]
    Default,
    /// At least every N frames.
    Frames(NonZeroU64),
}

impl JournalSync {
    /// Frames between two syncs under `settings`.
    pub(crate) fn every(self, settings: &WorldSettings) -> u64 {
        match self {
            Self::Frames(n) => n.get(),
            Self::Default if settings.synchronous_mode => 1,
            Self::Default => 50,
        }
    }
}

impl std::fmt::Display for JournalSync {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Default => f.write_str("frames:1 (synchronous) / frames:50 (asynchronous)"),
            Self::Frames(n) => write!(f, "frames:{n}"),
        }
    }
}

impl std::str::FromStr for JournalSync {
    type Err = String;

    fn from_str(text: &str) -> Result<Self, Self::Err> {
        let n = text
            .strip_prefix("frames:")
            .ok_or_else(|| format!("'{text}' is not a sync policy: write frames:N (N >= 1)"))?;
        n.parse::<NonZeroU64>()
            .map(Self::Frames)
            .map_err(|_| format!("'{n}' in '{text}' is not a whole number of frames >= 1"))
    }
}

/// Where and how a server journals.
#[derive(Debug, Clone, PartialEq, Eq)]
pub struct JournalOptions {
    /// The directory of segments.
    pub dir: PathBuf,
    /// How often it is made durable.
    pub sync: JournalSync,
}
