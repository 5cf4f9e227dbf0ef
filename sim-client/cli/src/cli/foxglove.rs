//! `sim-client foxglove`: the world live in Foxglove, served by the
//! `simbus-foxglove` crate; here its flags and what the command prints.

use std::time::Duration;

use clap::Args;
use shared_types::WorldName;
use simbus_foxglove::{Config, ServeError};

use crate::cli::failure::Failure;

/// Serve the world live to Foxglove over its WebSocket protocol.
#[derive(Debug, Args)]
pub(crate) struct FoxgloveArgs {
    /// Address to listen on.
    #[arg(long, default_value = "127.0.0.1")]
    host: String,
    /// Port to listen on (0: any free port; the one taken is printed).
    #[arg(long, default_value_t = 8765, allow_negative_numbers = true)]
    port: u16,
    /// Most frames sent per wall second, at most 1e6 (0: every frame).
    #[arg(long, value_name = "HZ", default_value_t = 30.0, allow_negative_numbers = true, value_parser = simbus_input::rate_limit)]
    max_hz: f64,
}

pub(crate) fn run(world: &WorldName, timeout: Duration, args: FoxgloveArgs) -> Result<(), Failure> {
    let config = Config {
        host: args.host,
        port: args.port,
        max_hz: args.max_hz,
        timeout,
    };
    let served = simbus_foxglove::serve(world, &config, super::interrupt::interrupted(), |listening| {
        println!(
            "foxglove: world '{world}' on ws://{}:{} (open it in Foxglove: Open connection → Foxglove WebSocket)",
            config.host, listening.port
        );
    })
    .map_err(|e: ServeError| {
        if e.is_refused() {
            Failure::Refused(e.into())
        } else {
            Failure::Runtime(e.into())
        }
    })?;
    eprintln!(
        "foxglove: {} sent",
        super::words::count(served.frames, "frame")
    );
    Ok(())
}
