//! # sim-client
//!
//! The simbus client layer: connect to a world by name, read and change its
//! settings, and receive every frame's snapshot from shared memory.
//!
//! ```no_run
//! use std::time::Duration;
//! use sim_client::{Client, WaitMode};
//! use shared_types::WorldSettings;
//!
//! # fn main() -> Result<(), Box<dyn std::error::Error>> {
//! let mut client = Client::connect("default", Duration::from_secs(2))?;
//!
//! // Switch to a fixed 50 ms step; the answer is the first frame that uses it.
//! let settings = WorldSettings { fixed_delta_seconds: Some(0.05), ..client.get_settings()? };
//! let from_frame = client.apply_settings(settings)?;
//!
//! client.set_wait_mode(WaitMode::Block); // sleep on the frame-ready event (default)
//! loop {
//!     let snapshot = client.wait_for_tick(Duration::from_secs(1))?;
//!     if snapshot.frame() >= from_frame {
//!         assert_eq!(snapshot.timestamp().delta_ns, 50_000_000);
//!         break;
//!     }
//! }
//! # Ok(())
//! # }
//! ```

#![deny(unsafe_op_in_unsafe_fn)]
#![warn(missing_docs)]

mod batch;
mod builder;
mod capture;
mod client;
mod error;
mod frame_stream;
mod lockstep;
mod on_tick;
mod open;
mod recorder;
mod restart;
mod rpc;
mod saves;
mod sensor;
mod snapshot;
mod standby;
mod status;
mod ticker;
mod wait;

pub use batch::{BatchError, BatchResponse, CommandError};
pub use builder::{ClientBuilder, DEFAULT_CONNECT_TIMEOUT};
pub use capture::Capture;
pub use client::DrawError;
pub use client::{Client, DEFAULT_REQUEST_TIMEOUT};
pub use error::{
    ApplySettingsError, ConnectError, LoadWorldError, RequestError, TickError, TransportError,
    WaitError,
};
pub use lockstep::Participant;
pub use on_tick::CallbackId;
pub use open::connect_until_stopped;
pub use recorder::{
    Mismatch, RecorderError, RecorderStatus, ReplayOptions, ReplayStatus, REPLAY_READ_TIMEOUT,
};
pub use restart::{Event, Reconnected};
pub use saves::{SnapshotError, SnapshotId};
pub use sensor::{Listening, Sensor, SensorError};
pub use shared_types::SnapshotInfo;
pub use shared_types::WaitMode;
pub use snapshot::{FrameView, WorldSnapshot};
pub use standby::{StandbyTicker, TakeOver};
pub use status::{JournalStatus, ParticipantStatus, Status, TickerStatus};
pub use ticker::{TickInFlight, Ticker};
pub use wait::{process_alive, set_interrupt_check};

/// What most programs use: `use sim_client::prelude::*;`.
pub mod prelude {
    pub use crate::{
        ApplySettingsError, BatchError, Capture, Client, ClientBuilder, ConnectError, FrameView,
        LoadWorldError, Participant, RecorderError, RequestError, Sensor, SensorError, Status,
        TickError, Ticker, WaitError, WaitMode, WorldSnapshot,
    };
    pub use shared_types::{
        Camera, Imu, Lidar, SensorKind, SensorParams, SensorSpec, WorldName, WorldSettings,
    };
}

/// The README's Rust examples, compiled as doctests so they stay true.
#[cfg(doctest)]
#[doc = include_str!("../../README.md")]
struct ReadmeExamples;

/// The Rust examples of the book's guide (`docs/src/guide.md`), compiled
/// as doctests the same way; every chapter with Rust code is one such item.
#[cfg(doctest)]
#[doc = include_str!("../../docs/src/guide.md")]
struct GuideExamples;

/// The Rust examples of the book's durability chapter (`docs/src/durability.md`).
#[cfg(doctest)]
#[doc = include_str!("../../docs/src/durability.md")]
struct DurabilityExamples;

/// The Rust examples of the book's sensors chapter (`docs/src/sensors.md`).
#[cfg(doctest)]
#[doc = include_str!("../../docs/src/sensors.md")]
struct SensorsExamples;
