//! Starting a server in its own process for a benchmark.

use std::process::{Command, Stdio};
use std::time::{Duration, SystemTime, UNIX_EPOCH};

use anyhow::Context;
use shared_types::WorldSettings;
use sim_client::process::ChildGuard;
use sim_client::{Client, Ticker};

/// Wall-clock nanoseconds (what `platform_timestamp` is measured in).
pub(crate) fn now_ns() -> u64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0, |d| d.as_nanos() as u64)
}

/// Claims the ticker of `client`'s world in synchronous mode, fixed step `dt`.
pub(crate) fn sync_ticker(client: &Client, dt: f64) -> anyhow::Result<Ticker> {
    let mut ticker = client.claim_ticker()?;
    ticker.apply_settings(WorldSettings {
        synchronous_mode: true,
        fixed_delta_seconds: Some(dt),
        ..client.get_settings()?
    })?;
    Ok(ticker)
}

/// A server child process (this binary's hidden `serve`), stopped on drop.
pub(crate) struct BenchServer {
    pub world: String,
    _guard: ChildGuard,
}

impl BenchServer {
    /// Starts `serve --world <unique> <args>` and waits until it answers.
    pub(crate) fn start(tag: &str, args: &[&str]) -> anyhow::Result<Self> {
        let world = format!("bench-{tag}-{}", std::process::id());
        let child = Command::new(std::env::current_exe()?)
            .arg("serve")
            .args(["--world", &world])
            .args(args)
            .env("RUST_LOG", "error")
            .stdin(Stdio::null())
            .stdout(Stdio::null())
            .spawn()
            .context("starting the benchmark server")?;
        let guard = ChildGuard::new(child, Duration::from_secs(5));
        Client::connect(&world, Duration::from_secs(20)).context("benchmark server")?;
        Ok(Self {
            world,
            _guard: guard,
        })
    }
}
