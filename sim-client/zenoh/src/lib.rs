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

mod error;
mod export;
mod link;
mod mirror;
mod ports;
mod tagged;
pub mod wire;

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use shared_types::{WorldName, WorldSettings};
use sim_client::Status;

pub use error::{
    BridgeError, ExportError, FramesError, LinkError, LocalError, MirrorError, QueryError,
    TransportError, ZenohError, ZenohFailure,
};
pub use link::check_endpoint;

/// What one side of a bridge runs with: the world, how long a request
/// may wait, the Zenoh endpoint, the options, the open session, the stop
/// flag and where [`Notice`]s go.
pub(crate) struct Side<'a> {
    world: &'a WorldName,
    timeout: Duration,
    endpoint: &'a str,
    options: &'a Options,
    session: zenoh::Session,
    stop: &'a AtomicBool,
    notice: &'a mut dyn FnMut(Notice),
}

/// Which side of the link this bridge is.
#[derive(Debug, Clone, Copy, PartialEq, Eq)]
pub enum Role<'a> {
    /// Export the world from the server's host, listening on this Zenoh
    /// endpoint (`tcp/0.0.0.0:7447`).
    Export(&'a str),
    /// Mirror the world exported at this Zenoh endpoint into this host's
    /// shared memory.
    Mirror(&'a str),
}

/// The JSON the exporter answers Zenoh tools' `status` and `settings`
/// queries with (the caller's, so it is the JSON its own tools print).
#[derive(Debug, Clone, Copy)]
pub struct JsonViews {
    /// A world's status as JSON.
    pub status: fn(&WorldName, &Status) -> serde_json::Value,
    /// A world's settings as JSON.
    pub settings: fn(&WorldSettings) -> serde_json::Value,
}

/// How a bridge runs.
#[derive(Debug, Clone)]
pub struct Options {
    /// A Zenoh configuration file (JSON5: TLS, routers, scouting...); the
    /// endpoint is added to it. Without one: peer mode, no multicast
    /// scouting.
    pub zenoh_config: Option<PathBuf>,
    /// Exporting: also publish the simulation time as ROS 2
    /// `rosgraph_msgs/msg/Clock` in CDR on the Zenoh key
    /// [`wire::ROS2_CLOCK_KEY`].
    pub ros2_clock: bool,
    /// Zenoh's lease in milliseconds: a silent link is declared dead after
    /// this long.
    pub lease_ms: u64,
    /// Mirroring: how long a forwarded request may wait for its answer.
    pub request_timeout: Duration,
    /// How long the bridge looks for a tick's next event, yielding the
    /// CPU, before it sleeps: the exporter while the server has a remote
    /// tick (its answer is coming), the mirror after it answered one (the
    /// ticker's next tick is coming). Each event found within it saves a
    /// wake-up; zero sleeps at once (no CPU spent).
    pub poll: Duration,
    /// Exporting: the JSON of the `status` and `settings` queries.
    pub json: JsonViews,
}

/// What a running bridge has to say to its user.
#[derive(Debug, Clone, PartialEq, Eq)]
#[non_exhaustive]
pub enum Notice {
    /// The exporter is up: the current frame is out.
    Exporting {
        /// The world.
        world: WorldName,
        /// The endpoint it listens on.
        endpoint: String,
        /// The server's pid.
        server_pid: u32,
        /// The frame current when it started.
        frame: u64,
    },
    /// The mirror is up: local clients may connect.
    Mirroring {
        /// The world.
        world: WorldName,
        /// The exporter's endpoint.
        endpoint: String,
        /// The server's pid on the exporter's host.
        server_pid: u32,
        /// The frame current when it started.
        frame: u64,
    },
    /// The exporter goes on with a server resumed from its journal after
    /// the world's server exited (`sim-server --resume DIR`).
    Resumed {
        /// The world.
        world: WorldName,
        /// The resumed server's pid.
        server_pid: u32,
        /// The pid of the server that exited.
        previous_pid: u32,
        /// The frame the world resumed at.
        frame: u64,
    },
    /// The mirror reaches the exporting bridge again.
    LinkUp,
    /// The mirror lost the exporting bridge: requests are answered
    /// [`shared_types::ResponseStatus::Unreachable`] until it is back.
    LinkDown,
}

/// Runs a bridge of `world` as `role` says until `stop` is set.
///
/// When exporting, it also ends once the server is gone and no server
/// resumed from its journal came back within `timeout`. `notice` is called
/// with what the user should know. `timeout` bounds connecting to the world
/// (exporting) or waiting for the exporter (mirroring).
///
/// # Errors
///
/// Returns [`BridgeError::Link`] if the Zenoh session cannot be opened (a bad
/// endpoint or configuration: nothing started; or the endpoint cannot be
/// listened on or connected to); [`BridgeError::Export`] if the exporter cannot
/// reach the world's server, open its ports or start forwarding, or stops
/// forwarding because the server is gone and none came back within `timeout`;
/// and [`BridgeError::Mirror`] if nothing exports the world at the endpoint,
/// the exporter is of another simbus version, or this host's shared memory
/// cannot hold the world's services (a server or another mirror of it runs
/// here).
pub fn run(
    world: &WorldName,
    timeout: Duration,
    role: Role<'_>,
    options: &Options,
    stop: &AtomicBool,
    notice: &mut dyn FnMut(Notice),
) -> Result<(), BridgeError> {
    let session = link::open(options, role)?;
    let (Role::Export(endpoint) | Role::Mirror(endpoint)) = role;
    let side = Side {
        world,
        timeout,
        endpoint,
        options,
        session,
        stop,
        notice,
    };
    match role {
        Role::Export(_) => export::run(side)?,
        Role::Mirror(_) => mirror::run(side)?,
    }
    Ok(())
}
