//! The hidden `peer` command: the other end of every baseline and the
//! helper processes of the benchmarks, each in its own process.

use std::time::Duration;

use clap::Args;
use shared_types::WorldSettings;
use sim_client::Client;

/// The other end of the raw ping-pong and TCP baselines.
#[derive(Debug, Args)]
pub(crate) struct PeerArgs {
    /// `iceoryx-spin`, `iceoryx-spin-step` (a physics step before each
    /// answer), `iceoryx-block`, `iceoryx-bus-block`, `tcp`, or a tick
    /// shape's answering end: `shape-request`, `shape-request-no-history`,
    /// `shape-publish`, `shape-request-block`, `shape-request-futex`,
    /// `shape-futex-block`.
    #[arg(long)]
    kind: String,
    /// Service prefix for the iceoryx2 kinds.
    #[arg(long, default_value = "bench")]
    name: String,
    /// Frames the `frame-reader` (blobs the `blob-reader`) reads before it
    /// reports.
    #[arg(long, default_value_t = 200)]
    samples: u64,
}

/// The hidden `peer` command: echoes (or ticks) until it is stopped.
pub(crate) fn peer(args: PeerArgs) -> anyhow::Result<()> {
    match args.kind.as_str() {
        "participant" => crate::commands::participant(&args.name),
        "tcp-blob" => crate::sensors::tcp_blob_peer(),
        "blob-reader" => crate::blob::reader(&args.name, args.samples),
        "futex" => crate::futex::peer(&args.name),
        "burn" => crate::support::burn(),
        "frame-reader" => crate::scaling::reader(&args.name, args.samples),
        "ticker" => {
            let client = Client::connect(&args.name, Duration::from_secs(10))?;
            let mut ticker = client.claim_ticker_as("bench-ticker")?;
            ticker.apply_settings(WorldSettings {
                synchronous_mode: true,
                fixed_delta_seconds: Some(0.01),
                ..client.get_settings()?
            })?;
            println!("ready");
            loop {
                ticker.tick(Duration::from_secs(10))?;
                std::thread::sleep(Duration::from_millis(1));
            }
        }
        "tcp" => crate::baselines::tcp_echo(),
        kind => match crate::shapes::Shape::of_peer(kind) {
            Some(shape) => crate::shapes::peer(&args.name, shape),
            None => crate::baselines::raw_peer(kind, &args.name),
        },
    }
}
