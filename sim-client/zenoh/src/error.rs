//! Why a bridge could not start or stopped: one enum per part (the Zenoh
//! link, the exporter, its frame thread, the mirror, this host's shared
//! memory), each lower layer's error kept as a typed source.

use std::path::PathBuf;
use std::time::Duration;

use shared_types::WorldName;

use crate::wire::PayloadError;

/// iceoryx2's error (or another lower layer's), boxed with its type so a
/// caller can downcast it.
pub type TransportError = Box<dyn std::error::Error + Send + Sync + 'static>;

/// Zenoh's error, shown without the source location Zenoh appends
/// (` at /root/.cargo/registry/…/lib.rs:183.`); the error itself is kept.
#[derive(Debug)]
pub struct ZenohError(zenoh::Error);

impl ZenohError {
    /// Zenoh's error as it came.
    pub fn get_ref(&self) -> &(dyn std::error::Error + Send + Sync + 'static) {
        &*self.0
    }

    /// Zenoh's error as it came, owned.
    pub fn into_inner(self) -> zenoh::Error {
        self.0
    }
}

impl From<zenoh::Error> for ZenohError {
    fn from(error: zenoh::Error) -> Self {
        Self(error)
    }
}

impl std::fmt::Display for ZenohError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        let text = self.0.to_string();
        match text.rfind(" at ") {
            Some(at) if text[at..].contains(".rs:") => f.write_str(&text[..at]),
            _ => f.write_str(&text),
        }
    }
}

impl std::error::Error for ZenohError {
    fn source(&self) -> Option<&(dyn std::error::Error + 'static)> {
        self.0.source()
    }
}

/// Why the Zenoh session could not be opened.
#[derive(Debug, thiserror::Error)]
pub enum LinkError {
    /// The endpoint is not `PROTOCOL/HOST:PORT`.
    #[error(
        "{flag} '{endpoint}' is not a Zenoh endpoint: give PROTOCOL/HOST:PORT, e.g. tcp/0.0.0.0:7447 \
         (listen on every address) or tcp/192.168.1.10:7447"
    )]
    BadEndpoint {
        /// `--listen` or `--connect`.
        flag: &'static str,
        /// As given.
        endpoint: String,
    },
    /// Well formed, but Zenoh refuses it (an unknown protocol, say). Zenoh's
    /// own error here is a JSON5 parser's dump, left out on purpose.
    #[error(
        "{flag} '{endpoint}' is not an endpoint Zenoh accepts: give PROTOCOL/HOST:PORT, \
         e.g. tcp/0.0.0.0:7447 (protocols of this build: tcp, tls)"
    )]
    UnacceptedEndpoint {
        /// `--listen` or `--connect`.
        flag: &'static str,
        /// As given.
        endpoint: String,
    },
    /// The Zenoh configuration file could not be read.
    #[error("--zenoh-config {}", path.display())]
    ConfigFile {
        /// The file.
        path: PathBuf,
        /// Zenoh's reason.
        #[source]
        source: ZenohError,
    },
    /// A setting of the configuration was refused.
    #[error(transparent)]
    Config(ZenohError),
    /// The endpoint could not be listened on.
    #[error("cannot listen on {endpoint}")]
    Listen {
        /// The endpoint.
        endpoint: String,
        /// Zenoh's reason.
        #[source]
        source: ZenohError,
    },
    /// No session towards the endpoint could be opened.
    #[error("cannot open a Zenoh session towards {endpoint}")]
    Connect {
        /// The endpoint.
        endpoint: String,
        /// Zenoh's reason.
        #[source]
        source: ZenohError,
    },
}

impl LinkError {
    /// Whether the input was refused (a bad endpoint or configuration), as
    /// opposed to a failure to open what was asked.
    pub fn is_refused(&self) -> bool {
        !matches!(self, Self::Listen { .. } | Self::Connect { .. })
    }
}

/// Why this host's shared memory could not hold or reach the world's
/// services.
#[derive(Debug, thiserror::Error)]
pub enum LocalError {
    /// simbus's environment (its iceoryx2 configuration) is unusable.
    #[error(transparent)]
    Environment(#[from] simbus_transport::environment::EnvironmentError),
    /// A service of the world could not be created here.
    #[error("creating a service of the world here (is a server or another mirror of it running on this host?)")]
    Create(#[source] TransportError),
    /// A sensor's service could not be created here.
    #[error("creating a sensor's service here")]
    CreateSensor(#[source] TransportError),
    /// Another iceoryx2 operation failed.
    #[error("{what}")]
    Transport {
        /// What was being done.
        what: String,
        /// iceoryx2's error.
        #[source]
        source: TransportError,
    },
    /// A capture's payload is not whole elements of its sensor's kind.
    #[error("{len} payload bytes are not whole elements of {size}")]
    PartialElement {
        /// Bytes received.
        len: usize,
        /// The element's size.
        size: usize,
    },
    /// A capture of a sensor kind this build does not know.
    #[error("unknown sensor kind {0}")]
    UnknownSensorKind(u32),
}

impl LocalError {
    pub(crate) fn transport(what: impl Into<String>, error: impl Into<TransportError>) -> Self {
        Self::Transport {
            what: what.into(),
            source: error.into(),
        }
    }
}

/// A Zenoh operation that failed: what was being done, and Zenoh's error
/// as its source.
#[derive(Debug, thiserror::Error)]
#[error("{what}")]
pub struct ZenohFailure {
    /// What was being done.
    pub what: &'static str,
    /// Zenoh's error.
    #[source]
    pub source: ZenohError,
}

/// Why the exporter's frame thread stopped forwarding.
#[derive(Debug, thiserror::Error)]
pub enum FramesError {
    /// Its client could not connect to the world.
    #[error(transparent)]
    Connect(#[from] sim_client::ConnectError),
    /// Waiting for a frame failed (the server is gone).
    #[error(transparent)]
    Wait(#[from] sim_client::WaitError),
    /// The world's frame-ready event could not be listened to.
    #[error(transparent)]
    Local(#[from] LocalError),
    /// Zenoh failed.
    #[error(transparent)]
    Zenoh(ZenohFailure),
}

/// Why the exporting bridge could not start or stopped.
#[derive(Debug, thiserror::Error)]
pub enum ExportError {
    /// The world's server could not be reached.
    #[error(transparent)]
    Connect(#[from] sim_client::ConnectError),
    /// The world's status could not be read.
    #[error(transparent)]
    Request(#[from] sim_client::RequestError),
    /// A request port of the world could not be opened.
    #[error(transparent)]
    Local(#[from] LocalError),
    /// Zenoh failed.
    #[error(transparent)]
    Zenoh(ZenohFailure),
    /// The frame thread could not be started.
    #[error("starting the frame thread")]
    Thread(#[source] std::io::Error),
    /// The current frame did not go out in time.
    #[error("the world's current frame was not forwarded within {0:?}")]
    FirstFrame(Duration),
    /// The frame thread stopped (the server is gone).
    #[error("stopped forwarding frames")]
    FramesEnded(#[source] FramesError),
}

/// How a query to the exporting bridge failed.
#[derive(Debug, thiserror::Error)]
pub enum QueryError {
    /// Nothing answered.
    #[error("nothing answered")]
    NoAnswer,
    /// The exporter answered with an error reply: its text.
    #[error("{0}")]
    Refused(String),
    /// Zenoh could not send the query.
    #[error(transparent)]
    Zenoh(ZenohError),
}

/// Why the mirroring bridge could not start or stopped.
#[derive(Debug, thiserror::Error)]
pub enum MirrorError {
    /// Nothing exported the world at the endpoint.
    #[error(
        "no bridge exports world '{world}' at {endpoint} (nothing answered within {timeout:?})"
    )]
    NotExported {
        /// The world.
        world: WorldName,
        /// The endpoint.
        endpoint: String,
        /// How long the mirror asked.
        timeout: Duration,
    },
    /// The exporter refused the status request.
    #[error("the exporting bridge refused")]
    Refused(#[source] QueryError),
    /// The exporter's answer is of another simbus version.
    #[error("cannot mirror world '{world}' from {endpoint}: {error} (mirror and exporter must be the same simbus version)")]
    Incompatible {
        /// The world.
        world: WorldName,
        /// The endpoint.
        endpoint: String,
        /// What is wrong with the answer.
        error: PayloadError,
    },
    /// The exporter had no frame to give.
    #[error("world '{world}' has no frame to mirror")]
    NoFrame {
        /// The world.
        world: WorldName,
        /// Why.
        #[source]
        source: QueryError,
    },
    /// The exporter's frame could not be read.
    #[error("the exporter's frame is unreadable")]
    UnreadableFrame(#[source] PayloadError),
    /// This host's shared memory failed.
    #[error(transparent)]
    Local(#[from] LocalError),
    /// Zenoh failed.
    #[error(transparent)]
    Zenoh(ZenohFailure),
}

/// Why a bridge could not start or stopped.
#[derive(Debug, thiserror::Error)]
pub enum BridgeError {
    /// The Zenoh session could not be opened.
    #[error(transparent)]
    Link(#[from] LinkError),
    /// The exporter failed.
    #[error(transparent)]
    Export(#[from] ExportError),
    /// The mirror failed.
    #[error(transparent)]
    Mirror(#[from] MirrorError),
}

impl BridgeError {
    /// Whether the input was refused (a bad endpoint or configuration):
    /// nothing was started.
    pub fn is_refused(&self) -> bool {
        matches!(self, Self::Link(e) if e.is_refused())
    }
}

macro_rules! zenoh_from {
    ($($t:ty),*) => {$(
        impl $t {
            /// A Zenoh failure while doing `what`.
            pub(crate) fn zenoh(what: &'static str) -> impl Fn(zenoh::Error) -> Self {
                move |e| {
                    Self::Zenoh(ZenohFailure {
                        what,
                        source: ZenohError(e),
                    })
                }
            }
        }
    )*};
}
zenoh_from!(FramesError, ExportError, MirrorError);

/// An error and its sources, `: `-separated, for logs.
pub(crate) struct Chain<'a>(pub(crate) &'a (dyn std::error::Error + 'static));

impl std::fmt::Display for Chain<'_> {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        write!(f, "{}", self.0)?;
        let mut source = self.0.source();
        while let Some(error) = source {
            write!(f, ": {error}")?;
            source = error.source();
        }
        Ok(())
    }
}
