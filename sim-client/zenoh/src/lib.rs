//! The simbus Zenoh bridge (`sim-client bridge zenoh`): a world beyond one
//! machine, over Zenoh.
//!
//! One bridge per host, symmetric. On the server's host, `--listen`
//! **exports** the world: frames and sensor captures become Zenoh
//! publications under `simbus/<world>/…`, the world's request services
//! (control, tick, batch, lockstep, sensors, recorder) become queryables
//! whose requests the bridge sends to the server through ordinary simbus
//! ports (a mirror's ticks go as publications, their answers attached to
//! the frames they produced). On another host, `--connect` **mirrors** the world into that
//! host's shared memory: the bridge creates the world's services there, as
//! a server would, publishes every frame and capture it receives and
//! forwards every request, so unmodified local clients (`watch`, `tick`,
//! `sensor watch`, the CARLA gateway, the Rust API) work as if the server
//! were local. Frames cross the network once per host.
//!
//! The single-ticker rule holds across hosts: a remote ticker claims
//! through its mirror; the exporting bridge holds the world's tick
//! ownership on its behalf (the server reports the remote ticker's node and
//! pid) and refuses every other claimant; when the server exits and one
//! resumed from its journal comes back, the exporter goes on with it and
//! claims the world again for that ticker. Each bridge declares a Zenoh
//! liveliness token; when a mirror's token goes (its link dropped or it
//! died) the exporter releases the ownership it held for it, and when the
//! exporter's goes, the mirror answers every request with
//! [`shared_types::ResponseStatus::Unreachable`]. Both happen within the
//! Zenoh lease (`--lease-ms`).
//!
//! The crate owns what crosses the network ([`wire`]: the Zenoh keys, the
//! payload layouts, ROS 2's CDR clock). [`run`] runs one bridge until its
//! stop flag is set, telling the caller what a user would want to know
//! through [`Notice`]s; it prints nothing.

mod bridge;
mod error;
mod export;
mod link;
mod mirror;
mod ports;
mod side;
mod tagged;
pub mod wire;

pub use bridge::run;
pub use error::{
    BridgeError, ExportError, FramesError, LinkError, LocalError, MirrorError, QueryError,
    TransportError, ZenohError, ZenohFailure,
};
pub use link::check_endpoint;
pub use side::{JsonViews, Notice, Options, Role};
