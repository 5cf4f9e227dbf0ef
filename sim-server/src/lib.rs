//! # sim-server
//!
//! The simbus server layer: one process owns a rapier3d world, steps it on
//! the simulation [`clock`], and writes every frame's snapshot straight into
//! iceoryx2 shared memory for any number of clients.
//!
//! - [`clock`]: integer-nanosecond time, fixed / variable step, substep plan.
//! - [`scene`]: the initial contents of a world (`default`, `empty`, `boxes:N`).
//! - [`world`]: rapier bodies and the actors that name them.
//! - [`services`]: the world's iceoryx2 ports.
//! - [`ticker`]: tick ownership and its loss.
//! - [`lockstep`]: participants the server waits for in synchronous mode.
//! - [`sensors`]: depth camera, lidar and IMU, written straight into shared memory.
//! - [`server`]: the loop that paces, steps and publishes, and its answers to requests.
//! - [`cli`]: the `sim-server` command line.
//!
//! ```no_run
//! use std::sync::atomic::AtomicBool;
//! use sim_server::{Scene, Server, ServerConfig};
//! use shared_types::{WorldName, WorldSettings};
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let config = ServerConfig {
//!     world: WorldName::new("lab")?,
//!     scene: Scene::Default,
//!     settings: WorldSettings { fixed_delta_seconds: Some(0.05), ..Default::default() },
//!     realtime: true,
//!     max_fps: 0.0,
//!     max_frames: Some(100),
//!     on_ticker_loss: Default::default(),
//!     spin: false,
//!     spin_window: std::time::Duration::from_micros(100),
//!     seed: 0,
//!     lockstep_timeout: std::time::Duration::from_secs(10),
//!     limits: Default::default(),
//! };
//! let summary = Server::start(config)?.run(&AtomicBool::new(false))?;
//! println!("{} frames at {:.0} FPS", summary.frames, summary.frames_per_second());
//! # Ok(())
//! # }
//! ```

#![deny(unsafe_op_in_unsafe_fn)]
#![warn(missing_docs)]

pub mod cli;
pub mod clock;
pub mod lockstep;
pub mod scene;
pub mod sensors;
pub mod server;
pub mod services;
pub mod ticker;
pub mod world;

pub use scene::{Scene, SceneError};
pub use server::{RunSummary, Server, ServerConfig};
pub use ticker::OnTickerLoss;

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
    /// iceoryx2's shared directory cannot be used by this user.
    #[error("{0}")]
    SharedDirectory(String),
    /// The start settings were refused.
    #[error("invalid settings: {0}")]
    Settings(SettingsError),
    /// Synchronous mode was asked for at start without a ticker.
    #[error(
        "synchronous mode is entered by the tick owner (sim-client tick), not at server start"
    )]
    SyncNeedsTicker,
    /// iceoryx2 refused an operation.
    #[error("shared-memory transport failed at {what}: {detail}")]
    Transport {
        /// What was being done.
        what: &'static str,
        /// iceoryx2's error.
        detail: String,
    },
}

impl ServerError {
    pub(crate) fn transport(what: &'static str, error: impl std::fmt::Debug) -> Self {
        Self::Transport {
            what,
            detail: format!("{error:?}"),
        }
    }
}

impl From<SettingsError> for ServerError {
    fn from(error: SettingsError) -> Self {
        Self::Settings(error)
    }
}
