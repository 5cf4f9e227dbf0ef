//! # sim-server
//!
//! The simbus server layer: one process owns a rapier3d world, steps it on
//! the simulation [`clock`], and writes every frame's snapshot straight into
//! iceoryx2 shared memory for any number of clients.
//!
//! One domain, one module — each owns its iceoryx2 port(s), its state and
//! its request handling; the `server` loop only orders them:
//!
//! - `config`: how the server was started (immutable); `state`: what
//!   changes while it runs (settings, scene, episode, pacing).
//! - [`clock`]: integer-nanosecond time, fixed / variable step, substep
//!   plan, and the pacing of asynchronous frames.
//! - [`scene`]: the initial contents of a world (`default`, `empty`, `boxes:N`).
//! - [`world`]: rapier bodies and the actors that name them;
//!   `commands`: what each wire command does to them; `vehicles`: the
//!   ray-cast vehicles.
//! - `frames`: publishing each frame's snapshot.
//! - `control`: status, settings, load and reload — and the wake-up event
//!   the loop sleeps on.
//! - `ticker`: the tick service, tick ownership, its loss and revocation.
//! - `batches`: command batches.
//! - `lockstep`: participants the server waits for in synchronous mode.
//! - `sensors`: depth camera, lidar and IMU, written straight into shared memory.
//! - `ports`, `liveness`: the node the domains open their ports on, and
//!   which client processes still live.
//! - [`timing`]: per-frame timings a benchmark may ask for (off by default).
//!
//! The `sim-server` command line is the binary's (`src/cli.rs`), not the
//! library's.
//!
//! A server runs in-process too (this example computes 100 frames as fast
//! as it can and returns):
//!
//! ```
//! use std::sync::atomic::AtomicBool;
//! use sim_server::{Scene, Server, ServerConfig};
//! use shared_types::{WorldName, WorldSettings};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let config = ServerConfig {
//!     scene: Scene::Default,
//!     settings: WorldSettings { fixed_delta_seconds: Some(0.05), ..Default::default() },
//!     max_fps: 0.0,
//!     max_frames: Some(100),
//!     ..ServerConfig::new(WorldName::new(&format!("doc-lab-{}", std::process::id()))?)
//! };
//! let summary = Server::start(config)?.run(&AtomicBool::new(false))?;
//! assert_eq!(summary.frames, 100);
//! assert!((summary.elapsed_seconds - 5.0).abs() < 1e-9);
//! # Ok(())
//! # }
//! ```

#![deny(unsafe_op_in_unsafe_fn)]
#![warn(missing_docs)]

pub(crate) mod batches;
pub mod clock;
pub(crate) mod commands;
pub(crate) mod config;
pub(crate) mod control;
pub(crate) mod frames;
pub mod journal;
pub(crate) mod liveness;
pub(crate) mod lockstep;
pub(crate) mod ports;
pub mod recorder;
pub(crate) mod replayer;
pub mod scene;
pub(crate) mod sensors;
pub(crate) mod server;
pub(crate) mod snapshots;
pub(crate) mod state;
pub(crate) mod ticker;
pub mod timing;
pub(crate) mod vehicles;
pub mod world;

pub use config::ServerConfig;
pub use journal::resume::{ResumeError, ResumeOptions};
pub use journal::{JournalError, JournalOptions, JournalSync};
pub use scene::{Scene, SceneError};
pub use sensors::RenderThreadsError;
pub use server::{RunSummary, Server};
pub use ticker::OnTickerLoss;
pub use timing::{FrameTime, FrameTimings};

use shared_types::SettingsError;

/// Why the server could not start or stopped with an error.
#[derive(Debug, thiserror::Error)]
pub enum ServerError {
    /// Another live server already owns the world.
    #[error("world '{world}' already has a running server; stop it or pick another --world")]
    AlreadyRunning {
        /// The world name.
        world: String,
    },
    /// iceoryx2 cannot be used as configured (its configuration file, or a
    /// shared directory another user owns).
    #[error(transparent)]
    SharedDirectory(simbus_transport::environment::EnvironmentError),
    /// The start settings were refused.
    #[error("invalid settings: {0}")]
    Settings(SettingsError),
    /// The time between keyframes is not a number of seconds in range.
    #[error("keyframe interval {seconds} s is out of range: it must be in {min}..={max} s (--keyframe-seconds)")]
    KeyframeSeconds {
        /// The refused interval.
        seconds: f64,
        /// The shortest accepted.
        min: f64,
        /// The longest accepted.
        max: f64,
    },
    /// The render threads (`--render-threads`) could not be started.
    #[error(transparent)]
    RenderThreads(RenderThreadsError),
    /// The journal could not be started.
    #[error(transparent)]
    Journal(#[from] journal::JournalError),
    /// The journal could not be resumed.
    #[error(transparent)]
    Resume(#[from] journal::resume::ResumeError),
    /// A fork was asked to journal into the journal it forks.
    #[error("a fork leaves its journal untouched: journal it into another directory than {dir}")]
    ForkIntoOriginal {
        /// The original journal.
        dir: std::path::PathBuf,
    },
    /// A resume named another world than its journal's.
    #[error("the journal in {dir} is world '{journal}', not '{asked}': resume it under its own name, or fork it under a new one with --at FRAME --world NEW")]
    OtherWorld {
        /// The journal.
        dir: std::path::PathBuf,
        /// Its world.
        journal: String,
        /// The world asked for.
        asked: String,
    },
    /// iceoryx2 refused an operation.
    #[error("shared-memory transport failed at {what}")]
    Transport {
        /// What was being done.
        what: &'static str,
        /// iceoryx2's error, kept with its type.
        #[source]
        source: Box<dyn std::error::Error + Send + Sync + 'static>,
    },
}

impl ServerError {
    pub(crate) fn transport(
        what: &'static str,
        error: impl Into<Box<dyn std::error::Error + Send + Sync + 'static>>,
    ) -> Self {
        Self::Transport {
            what,
            source: error.into(),
        }
    }
}

/// An error and its sources in one line (`what failed: why: ...`), as a
/// client reads it in an answer's message.
pub(crate) fn message(error: &(dyn std::error::Error + 'static)) -> String {
    let mut text = error.to_string();
    let mut source = error.source();
    while let Some(cause) = source {
        text.push_str(": ");
        text.push_str(&cause.to_string());
        source = cause.source();
    }
    text
}

impl From<SettingsError> for ServerError {
    fn from(error: SettingsError) -> Self {
        Self::Settings(error)
    }
}
