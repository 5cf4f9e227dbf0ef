//! One error enum per client operation.

use std::time::Duration;

use shared_types::{SensorEnd, SettingsError, TickerInfo, WorldNameError};

/// Why [`crate::Client::connect`] failed.
#[derive(Debug, thiserror::Error)]
pub enum ConnectError {
    /// The world name is not valid.
    #[error(transparent)]
    InvalidWorld(#[from] WorldNameError),
    /// No server answered within the timeout.
    #[error("no simbus server answered on world '{world}' within {timeout:?}; start one with `sim-server --world {world}`")]
    NoServer {
        /// The world asked for.
        world: String,
        /// How long the client waited.
        timeout: Duration,
    },
    /// The world's server exists but did not answer in time (stopped with
    /// SIGSTOP, or overloaded).
    #[error("the server of world '{world}' exists but did not answer within {timeout:?} (is it stopped, or overloaded?)")]
    NotAnswering {
        /// The world asked for.
        world: String,
        /// How long the client waited.
        timeout: Duration,
    },
    /// iceoryx2 cannot be used as configured: its configuration file does
    /// not load, or its shared directory belongs to another user.
    #[error(transparent)]
    SharedDirectory(#[from] simbus_transport::environment::EnvironmentError),
    /// The server speaks another protocol version.
    #[error("world '{world}' runs a server with another protocol version ({detail}); this client speaks version {client}")]
    ProtocolMismatch {
        /// The world asked for.
        world: String,
        /// What differs.
        detail: String,
        /// This client's [`shared_types::PROTOCOL_VERSION`].
        client: u32,
    },
    /// The world admits no more clients of this kind right now.
    #[error("world '{world}' already has the most {what} it admits ({max}); close one, or start its server with a larger {flag}")]
    Full {
        /// The world.
        world: String,
        /// What is full.
        what: &'static str,
        /// The limit.
        max: usize,
        /// The `sim-server` flag that raises it.
        flag: &'static str,
    },
    /// iceoryx2 refused an operation.
    #[error("shared-memory transport failed at {what}: {source}")]
    Transport {
        /// What was being done.
        what: &'static str,
        /// iceoryx2's error, kept with its type.
        #[source]
        source: TransportError,
    },
}

/// Why a control request (status, settings) failed.
#[derive(Debug, thiserror::Error)]
pub enum RequestError {
    /// The server did not answer in time.
    #[error("the server of world '{world}' did not answer within {timeout:?}")]
    Timeout {
        /// The world.
        world: String,
        /// How long the client waited.
        timeout: Duration,
    },
    /// The wait was interrupted ([`crate::set_interrupt_check`]: Ctrl-C
    /// in the Python package).
    #[error("interrupted while waiting on world '{world}'")]
    Interrupted {
        /// The world.
        world: String,
    },
    /// The server process is gone.
    #[error("the server of world '{world}' (pid {pid}) has exited")]
    ServerGone {
        /// The world.
        world: String,
        /// The server's process id.
        pid: u32,
    },
    /// The server speaks another protocol version.
    #[error("protocol versions differ: the server speaks {}, this client speaks version {client}", server_version(*.server))]
    ProtocolMismatch {
        /// This client's version.
        client: u32,
        /// The server's, when it said (an older server may only have
        /// types that do not match).
        server: Option<u32>,
    },
    /// The world is mirrored from another host and its server cannot be
    /// reached now (the link is down or the exporting bridge is gone).
    #[error("the server of world '{world}' is on another host and the bridge cannot reach it now (link down or exporting bridge gone); nothing was done")]
    Unreachable {
        /// The world.
        world: String,
    },
    /// The server does not know the request.
    #[error("the server does not know this request (is it an older version?)")]
    UnknownRequest,
    /// The server answered with a status this client does not expect here.
    #[error("the server answered with status {status}, which this client does not expect here")]
    UnknownAnswer {
        /// The status, as a [`shared_types::ResponseStatus`] code.
        status: u32,
    },
    /// A lockstep window larger than a participant may ask for.
    #[error("a lockstep window of {window} frames is more than the {max} a participant may ask for; nothing was joined")]
    WindowTooLarge {
        /// The window asked for.
        window: u32,
        /// [`shared_types::MAX_LOCKSTEP_WINDOW`].
        max: u32,
    },
    /// This lockstep participant was dropped by the server.
    #[error("dropped from the lockstep of world '{world}': the server no longer waits for this participant (it kept a tick waiting past the server's --lockstep-timeout, or left); frames went on without it")]
    NotParticipant {
        /// The world.
        world: String,
    },
    /// No more clients of this kind fit right now.
    #[error("the most {what} admitted ({max}) are already there; close one, or start the server with a larger {flag}")]
    Full {
        /// What is full.
        what: &'static str,
        /// The limit.
        max: usize,
        /// The `sim-server` flag that raises it.
        flag: &'static str,
    },
    /// iceoryx2 refused an operation.
    #[error("shared-memory transport failed at {what}: {source}")]
    Transport {
        /// What was being done.
        what: &'static str,
        /// iceoryx2's error, kept with its type.
        #[source]
        source: TransportError,
    },
}

/// Why [`crate::Client::apply_settings`] failed. Nothing changed on the server.
#[derive(Debug, thiserror::Error)]
pub enum ApplySettingsError {
    /// The settings break a rule.
    #[error("invalid settings: {0}")]
    Invalid(SettingsError),
    /// Synchronous mode is entered by the tick owner, not through settings.
    #[error("synchronous mode cannot be entered through settings: it is entered by the tick owner (`sim-client tick`), so a world is never left waiting for ticks nobody sends")]
    SyncNeedsTicker,
    /// Only the ticker may apply settings through its tick service.
    #[error("this client is no longer the ticker")]
    NotTicker,
    /// Another client left synchronous mode, which ended this ticker's
    /// ownership.
    #[error("synchronous mode was turned off by {} (pid {}) at frame {}; this client is no longer the ticker", by.node_name.to_string_lossy(), by.pid, by.since_frame)]
    Revoked {
        /// Who left synchronous mode, and at which frame.
        by: TickerInfo,
    },
    /// A ticker holds the world: only it changes settings.
    #[error("world has a ticker: {owner}; while it ticks only it changes settings (anyone may leave synchronous mode with `sim-client config --no-sync`, which ends its ownership)")]
    TickerHolds {
        /// The ticker.
        owner: TickerInfo,
    },
    /// The request itself failed.
    #[error(transparent)]
    Request(#[from] RequestError),
}

/// Why [`crate::Client::wait_for_tick`] returned without a snapshot.
#[derive(Debug, thiserror::Error)]
pub enum WaitError {
    /// No new frame within the timeout.
    #[error("no new frame from world '{world}' within {timeout:?}{}", last_frame.map(|f| format!(" (last frame seen: {f})")).unwrap_or_default())]
    Timeout {
        /// The world.
        world: String,
        /// How long the client waited.
        timeout: Duration,
        /// The last frame this client saw.
        last_frame: Option<u64>,
    },
    /// The wait was interrupted ([`crate::set_interrupt_check`]: Ctrl-C
    /// in the Python package).
    #[error("interrupted while waiting on world '{world}'")]
    Interrupted {
        /// The world.
        world: String,
    },
    /// The server process is gone.
    #[error("the server of world '{world}' (pid {pid}) has exited")]
    ServerGone {
        /// The world.
        world: String,
        /// The server's process id.
        pid: u32,
    },
    /// The server exited and none came back on the world within the
    /// timeout ([`crate::Client::next_event`]).
    #[error(
        "the server of world '{world}' (pid {pid}) exited and none came back within {timeout:?}"
    )]
    NotBack {
        /// The world.
        world: String,
        /// The process id of the server that exited.
        pid: u32,
        /// How long the client waited in all.
        timeout: Duration,
    },
    /// A server came back, but connecting to it failed.
    #[error("reconnecting after a server restart failed: {0}")]
    Reconnect(Box<ConnectError>),
    /// No capture from a sensor within the timeout.
    #[error("no capture from sensor {sensor} of world '{world}' within {timeout:?}{}", last_frame.map(|f| format!(" (last capture: frame {f})")).unwrap_or_else(|| " (none yet; is the world ticking, and is the sensor's period shorter than that?)".to_owned()))]
    NoCapture {
        /// The sensor.
        sensor: u64,
        /// The world.
        world: String,
        /// How long the client waited.
        timeout: Duration,
        /// The frame of the last capture this reader received.
        last_frame: Option<u64>,
    },
    /// The sensor is gone: its stream ended.
    #[error("sensor {sensor} ended: {reason}")]
    SensorEnded {
        /// The sensor.
        sensor: u64,
        /// Why.
        reason: SensorEnd,
    },
    /// A frame of another protocol version arrived.
    #[error("received a frame of protocol version {got}; this client speaks {client}")]
    ProtocolMismatch {
        /// The frame's version.
        got: u32,
        /// This client's version.
        client: u32,
    },
    /// iceoryx2 refused an operation.
    #[error("shared-memory transport failed at {what}: {source}")]
    Transport {
        /// What was being done.
        what: &'static str,
        /// iceoryx2's error, kept with its type.
        #[source]
        source: TransportError,
    },
}

/// The lower layer's error (iceoryx2's, typed), boxed so every operation's
/// error can carry it as its source.
pub type TransportError = Box<dyn std::error::Error + Send + Sync + 'static>;

macro_rules! transport_ctor {
    ($($t:ty),*) => {$(
        impl $t {
            pub(crate) fn transport(what: &'static str, error: impl Into<TransportError>) -> Self {
                Self::Transport { what, source: error.into() }
            }
        }
    )*};
}
transport_ctor!(ConnectError, RequestError, WaitError);

impl From<SettingsError> for ApplySettingsError {
    fn from(error: SettingsError) -> Self {
        Self::Invalid(error)
    }
}

/// Why claiming tick ownership or ticking failed.
#[derive(Debug, thiserror::Error)]
pub enum TickError {
    /// Another client is the ticker (or the server says this one is not).
    #[error("world '{world}' already has a ticker: {}; only one client may tick", owner.map_or_else(|| "another process holds the tick service".to_owned(), |o| o.to_string()))]
    NotTicker {
        /// The world.
        world: String,
        /// The current owner, when the server could name it.
        owner: Option<shared_types::TickerInfo>,
    },
    /// Another client left synchronous mode, which ended this ticker's
    /// ownership.
    #[error("synchronous mode of world '{world}' was turned off by {} (pid {}) at frame {}; this client is no longer the ticker", by.node_name.to_string_lossy(), by.pid, by.since_frame)]
    Revoked {
        /// The world.
        world: String,
        /// Who left synchronous mode, and at which frame.
        by: TickerInfo,
    },
    /// The tick waited for a lockstep participant longer than the server's
    /// lockstep timeout (plus a margin) without an answer.
    #[error("the tick of world '{world}' waited {waited:?} for lockstep participant {participant} (pid {pid}) and got no answer")]
    HeldUp {
        /// The world.
        world: String,
        /// The name of the participant the server said it waits for.
        participant: String,
        /// Its process id.
        pid: u32,
        /// How long the tick waited.
        waited: Duration,
    },
    /// A standby ticker waited `waited` and the world still had a ticker.
    #[error("world '{world}' still has a ticker after {waited:?} on standby: {}", owner.as_ref().map_or_else(|| "unknown".to_owned(), |o| o.to_string()))]
    StandbyTimedOut {
        /// The world.
        world: String,
        /// How long the standby waited.
        waited: Duration,
        /// The ticker it waited behind, as the server last named it.
        owner: Option<Box<TickerInfo>>,
    },
    /// The tick service admits no more ports: the ticker, a dead ticker's
    /// port until the server removes it, and the standbys already waiting.
    #[error("world '{world}' admits {max} tick ports (the ticker, a dead ticker's port until it is removed, and standby tickers); too many standby tickers wait")]
    StandbyFull {
        /// The world.
        world: String,
        /// The tick ports the world admits.
        max: usize,
    },
    /// The request failed (timeout, server gone, protocol).
    #[error(transparent)]
    Request(#[from] RequestError),
    /// Reading the ticked frame failed ([`crate::Ticker::tick_and_read`]).
    #[error(transparent)]
    Frame(#[from] WaitError),
    /// The server exited and another came back on the world; this ticker
    /// claimed it ([`crate::Ticker::set_follow_restarts`]). Whether the
    /// tick that noticed was computed is not known: the world resumed at
    /// `resumed_at`, and the next tick computes the frame after it.
    #[error("{0}; this ticker claimed the world again")]
    Restarted(crate::Reconnected),
}

impl TickError {
    pub(crate) fn transport(what: &'static str, error: impl Into<TransportError>) -> Self {
        Self::Request(RequestError::transport(what, error))
    }
}

/// Why [`crate::Client::load_world`] or [`crate::Client::reload_world`] failed.
#[derive(Debug, thiserror::Error)]
pub enum LoadWorldError {
    /// No such scene (refused before asking, or by the server); nothing
    /// changed. The reason states the rule (`boxes:N needs N in 1..=100000`).
    #[error("{reason}")]
    UnknownScene {
        /// The scene asked for.
        scene: String,
        /// Which rule of the scene grammar it breaks.
        reason: shared_types::scene::SceneNameError,
    },
    /// `--reset-settings` while a ticker holds the world: only it changes
    /// settings; nothing changed.
    #[error("world has a ticker: {owner}; while it ticks only it changes settings, so the world cannot be loaded with its settings reset")]
    TickerHolds {
        /// The ticker.
        owner: TickerInfo,
    },
    /// The server could not load the world (its log says why); the world
    /// is unchanged.
    #[error(
        "the server of world '{world}' could not load the world (see its log); nothing changed"
    )]
    Failed {
        /// The world.
        world: String,
    },
    /// The request failed.
    #[error(transparent)]
    Request(#[from] RequestError),
}

/// A server's protocol version for a message.
fn server_version(server: Option<u32>) -> String {
    match server {
        Some(v) => format!("version {v}"),
        None => "another version (its message types differ)".into(),
    }
}
