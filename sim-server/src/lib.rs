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
//! - `error`: why a port could not be opened or used, and an error in one
//!   line; what starting or running a server can fail with is
//!   [`ServerError`].
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
pub(crate) mod debug_shapes;
pub mod error;
pub mod journal;
pub(crate) mod keyframe;
pub(crate) mod liveness;
pub(crate) mod lockstep;
pub(crate) mod ports;
pub(crate) mod publication;
pub mod recorder;
pub(crate) mod replayer;
pub mod scene;
pub(crate) mod sensors;
pub(crate) mod server;
pub(crate) mod snapshots;
pub(crate) mod state;
pub(crate) mod ticker;
pub mod timing;
pub(crate) mod traffic_lights;
pub(crate) mod vehicles;
pub(crate) mod walkers;
pub mod world;

pub use config::{JournalOptions, JournalSync, OnTickerLoss, ServerConfig};
pub use error::PortError;
pub use journal::resume::{ResumeError, ResumeOptions};
pub use journal::JournalError;
pub use scene::{Scene, SceneError};
pub use sensors::RenderThreadsError;
pub use server::{RunSummary, Server, ServerError};
pub use timing::{FrameTime, FrameTimings};
