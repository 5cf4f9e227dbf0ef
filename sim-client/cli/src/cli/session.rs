//! Connecting to a world, and what a refused change of its settings means
//! for the exit code.

use anyhow::anyhow;

use super::failure::Failure;
use super::interrupt::interrupted;

/// [`sim_client::Client::connect`] that Ctrl-C and SIGTERM end
/// ([`Failure::Interrupted`]; [`sim_client::connect_until_stopped`] looks
/// at [`interrupted`] every 200 ms): a world whose server is not up used to
/// hold the command for its whole `--timeout`, whatever the user pressed.
pub(crate) fn connect(
    world: &str,
    timeout: std::time::Duration,
) -> Result<sim_client::Client, Failure> {
    sim_client::connect_until_stopped(timeout, interrupted(), |slice| {
        sim_client::Client::connect(world, slice)
    })?
    .ok_or_else(|| Failure::Interrupted(anyhow!("before the server of world '{world}' answered")))
}

/// A settings refusal is refused input (exit 2); a failed request is a
/// runtime failure (exit 1).
pub(crate) fn refused_or_runtime(e: sim_client::ApplySettingsError) -> Failure {
    match e {
        sim_client::ApplySettingsError::Request(e) => Failure::Runtime(e.into()),
        e => Failure::Refused(e.into()),
    }
}
