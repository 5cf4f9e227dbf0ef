//! The errors every domain shares: why a port could not be opened or used
//! ([`PortError`]), and how an error reads in one line for a client
//! ([`message`]). What starting or running a server can fail with is
//! `ServerError`, in `server/error.rs`.

use simbus_transport::environment::EnvironmentError;

/// Why a domain could not open or use its iceoryx2 ports.
#[derive(Debug, thiserror::Error)]
pub enum PortError {
    /// Another live server already owns the world.
    #[error("world '{world}' already has a running server; stop it or pick another --world")]
    AlreadyRunning {
        /// The world name.
        world: String,
    },
    /// iceoryx2 cannot be used as configured (its configuration file, or a
    /// shared directory another user owns).
    #[error(transparent)]
    SharedDirectory(EnvironmentError),
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

impl PortError {
    /// iceoryx2 refused `what`, with `error`.
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
