//! Why a wait for frames came up empty, in words: the server does not
//! answer, the world is synchronous and nobody ticks it, or frames simply
//! stopped. `autopilot` says this when its `--timeout` runs out (the other
//! commands' waits end with the client library's own timeout errors).

use std::time::Duration;

use anyhow::anyhow;
use sim_client::Client;

/// The error of a wait for frames that saw none for `waited` (the last one
/// seen was `last_frame`), with the reason the server's status gives
/// (asked with at most a second's patience: the wait is already over).
pub(crate) fn no_frames(
    client: &mut Client,
    waited: Duration,
    last_frame: Option<u64>,
) -> anyhow::Error {
    client.set_request_timeout(waited.min(Duration::from_secs(1)));
    let world = client.world().clone();
    let last = last_frame.map_or(String::new(), |f| format!(" (last frame seen: {f})"));
    let waited = waited.as_secs_f64();
    match client.status() {
        Err(e) => anyhow!(
            "no frame of world '{world}' for {waited} s{last}, and its server does not answer ({e}): is it stopped or hung?"
        ),
        Ok(status) if status.settings.synchronous_mode && status.ticker.is_none() => {
            anyhow!(
                "no frame of world '{world}' for {waited} s{last}: it is in synchronous mode and nobody ticks it (start a ticker: `sim-client tick`)"
            )
        }
        Ok(_) => anyhow!("no frame of world '{world}' for {waited} s{last} (see --timeout)"),
    }
}
