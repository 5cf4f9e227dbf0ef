//! One side of a bridge: its role, its options, what it runs with, and
//! what it tells the user.

use std::path::PathBuf;
use std::sync::atomic::AtomicBool;
use std::time::Duration;

use shared_types::{WorldName, WorldSettings};
use sim_client::Status;

/// What one side of a bridge runs with: the world, how long a request
/// may wait, the Zenoh endpoint, the options, the open session, the stop
/// flag and where [`Notice`]s go.
pub(crate) struct Side<'a> {
    pub(crate) world: &'a WorldName,
    pub(crate) timeout: Duration,
    pub(crate) endpoint: &'a str,
    pub(crate) options: &'a Options,
    pub(crate) session: zenoh::Session,
    pub(crate) stop: &'a AtomicBool,
    pub(crate) notice: &'a mut dyn FnMut(Notice),
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
