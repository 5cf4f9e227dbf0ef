//! How a command failed, and the exit code that says so.

/// How a command failed, for the exit code: 1 for a runtime failure,
/// 2 for input that was refused, 130 for Ctrl-C or SIGTERM before the
/// command began.
#[derive(Debug)]
pub(crate) enum Failure {
    /// Something went wrong talking to the world.
    Runtime(anyhow::Error),
    /// The input was refused (invalid settings, bad flags); nothing changed.
    Refused(anyhow::Error),
    /// Ctrl-C or SIGTERM came while the command waited to begin (for its
    /// world's server); nothing changed. Once a command runs, a signal
    /// ends it as its own help says (most exit 0 after putting back what
    /// they changed).
    Interrupted(anyhow::Error),
}

impl<E: Into<anyhow::Error>> From<E> for Failure {
    fn from(e: E) -> Self {
        Self::Runtime(e.into())
    }
}
