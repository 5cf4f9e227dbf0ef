//! The measuring client of `simbus-bench zenoh`, run in the host it
//! measures from (its root and namespace), and the echo end of Zenoh's own
//! round trip.

use std::time::{Duration, Instant};

use clap::Args;
use shared_types::SensorSpec;
use sim_client::Client;
use simbus_transport::stamps::{self, Stage};

use simbus_tests::Proc;

use crate::stats::Latencies;
use crate::support::{now_ns, sync_ticker};
use crate::zenoh_hosts::{wait_line, Host};

/// Options of the measuring client (run in the host it measures from).
#[derive(Debug, Args)]
pub(crate) struct ZenohPeerArgs {
    /// The world.
    #[arg(long)]
    world: String,
    /// `tick` (round trips and frame latencies), `depth W H` (capture
    /// latencies) or `rate` (ticks per second over --count ticks).
    #[arg(long)]
    mode: String,
    /// Ticks or captures.
    #[arg(long)]
    count: u64,
    /// Depth image size for `depth`.
    #[arg(long, num_args = 2, value_names = ["W", "H"])]
    size: Vec<u32>,
    /// For `echo`: the Zenoh endpoint to listen on.
    #[arg(long, default_value = "")]
    endpoint: String,
}

/// The measuring client: one JSON line with its samples in nanoseconds.
pub(crate) fn peer(args: ZenohPeerArgs) -> anyhow::Result<()> {
    if args.mode == "echo" {
        return zenoh_echo(&args.endpoint);
    }
    // `SIMBUS_STAMPS=FILE`: this side's stamps of each tick, written at
    // the end (`simbus-bench zenoh --breakdown`).
    let stamps_file = stamps::enable_from_env();
    let mut client = Client::connect(&args.world, Duration::from_secs(20))?;
    let mut ticker = sync_ticker(&client, 0.01)?;
    let timeout = Duration::from_secs(30);
    let warmup = args.count / 10;
    match args.mode.as_str() {
        "tick" => {
            // The frame current at connection comes first.
            let mut last = client.wait_for_frame(timeout)?.frame();
            let (mut round_trips, mut frames) = (Vec::new(), Vec::new());
            for i in 0..args.count + warmup {
                let start = Instant::now();
                let frame = ticker.tick(timeout)?;
                let round_trip = start.elapsed().as_nanos() as u64;
                let mut snapshot = client.wait_for_frame(timeout)?;
                while snapshot.frame() < frame && snapshot.frame() > last {
                    last = snapshot.frame();
                    drop(snapshot);
                    snapshot = client.wait_for_frame(timeout)?;
                }
                anyhow::ensure!(
                    snapshot.frame() == frame,
                    "frame {} after tick {frame}",
                    snapshot.frame()
                );
                last = frame;
                stamps::stamp(Stage::ClientHolds, frame);
                let published = (snapshot.timestamp().platform_timestamp * 1e9) as u64;
                if i >= warmup {
                    round_trips.push(round_trip);
                    frames.push(now_ns().saturating_sub(published));
                }
            }
            println!(
                "{}",
                serde_json::json!({"round_trip": round_trips, "frame": frames})
            );
        }
        "depth" => {
            let &[width, height] = args.size.as_slice() else {
                anyhow::bail!("--size W H");
            };
            let spec = SensorSpec::depth([0.0, 3.0, 0.0], width, height, 90.0, 100.0);
            let mut sensor = client.spawn_sensor(spec)?;
            let mut latencies = Vec::new();
            for i in 0..args.count + warmup {
                let frame = ticker.tick(timeout)?;
                let capture = sensor.recv(timeout)?;
                anyhow::ensure!(capture.header().frame == frame, "capture of another frame");
                let published = (capture.header().platform_timestamp * 1e9) as u64;
                if i >= warmup {
                    latencies.push(now_ns().saturating_sub(published));
                }
            }
            client.destroy_sensor(sensor.id())?;
            println!("{}", serde_json::json!({"capture": latencies}));
        }
        "rate" => {
            let start = Instant::now();
            for _ in 0..args.count {
                ticker.tick(timeout)?;
            }
            let rate = args.count as f64 / start.elapsed().as_secs_f64();
            println!("{}", serde_json::json!({"ticks_per_second": rate}));
        }
        mode => anyhow::bail!("unknown mode {mode}"),
    }
    ticker.release()?;
    if let Some(path) = stamps_file {
        stamps::write(&path, &stamps::take())?;
    }
    Ok(())
}

pub(crate) fn zenoh_session(key: &str, endpoint: &str) -> anyhow::Result<zenoh::Session> {
    use zenoh::Wait as _;
    let mut config = zenoh::Config::default();
    let error = |e: zenoh::Error| anyhow::anyhow!("{e}");
    config
        .insert_json5("scouting/multicast/enabled", "false")
        .map_err(error)?;
    config
        .insert_json5(key, &serde_json::to_string(&[endpoint])?)
        .map_err(error)?;
    zenoh::open(config).wait().map_err(error)
}

/// The echo end of the Zenoh floor: every sample on `bench/ping` is put
/// back on `bench/pong`, express.
fn zenoh_echo(endpoint: &str) -> anyhow::Result<()> {
    use zenoh::Wait as _;
    let session = zenoh_session("listen/endpoints", endpoint)?;
    let pong = session
        .declare_publisher("bench/pong")
        .express(true)
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    let ping = session
        .declare_subscriber("bench/ping")
        .wait()
        .map_err(|e| anyhow::anyhow!("{e}"))?;
    println!("ready");
    while let Ok(sample) = ping.recv() {
        pong.put(sample.payload().clone())
            .wait()
            .map_err(|e| anyhow::anyhow!("{e}"))?;
    }
    Ok(())
}

/// Zenoh's own round trip, the floor under a mirrored tick: a put on
/// `bench/ping` and an echo process's put back on `bench/pong`, express.
pub(crate) struct ZenohFloor {
    _echo: Proc,
    _session: zenoh::Session,
    ping: zenoh::pubsub::Publisher<'static>,
    pong: zenoh::pubsub::Subscriber<zenoh::handlers::FifoChannelHandler<zenoh::sample::Sample>>,
}

impl ZenohFloor {
    /// Starts the echo and waits until it answers.
    pub(crate) fn start() -> anyhow::Result<Self> {
        use zenoh::Wait as _;
        let endpoint = format!("tcp/127.0.0.1:{}", 16_000 + std::process::id() % 1000);
        let echo = Host::default().spawn(
            "simbus-bench",
            &[
                "zenoh-peer",
                "--world",
                "floor",
                "--mode",
                "echo",
                "--count",
                "0",
                "--endpoint",
                &endpoint,
            ],
        );
        wait_line(&echo, "ready")?;
        let session = zenoh_session("connect/endpoints", &endpoint)?;
        let error = |e: zenoh::Error| anyhow::anyhow!("{e}");
        let ping = session
            .declare_publisher("bench/ping")
            .express(true)
            .wait()
            .map_err(error)?;
        let pong = session
            .declare_subscriber("bench/pong")
            .wait()
            .map_err(error)?;
        // Until the echo's subscription has reached us and answers.
        let deadline = Instant::now() + Duration::from_secs(20);
        loop {
            ping.put(vec![0u8; 8]).wait().map_err(error)?;
            if pong
                .recv_timeout(Duration::from_millis(100))
                .map_err(error)?
                .is_some()
            {
                break;
            }
            anyhow::ensure!(Instant::now() < deadline, "the Zenoh echo never answered");
        }
        while pong.try_recv().map_err(error)?.is_some() {}
        Ok(Self {
            _echo: echo,
            _session: session,
            ping,
            pong,
        })
    }

    /// Records `n` round trips (after n / 10 not recorded) in `latencies`.
    pub(crate) fn measure(&mut self, n: u64, latencies: &mut Latencies) -> anyhow::Result<()> {
        use zenoh::Wait as _;
        let error = |e: zenoh::Error| anyhow::anyhow!("{e}");
        latencies.time(n, || {
            self.ping.put(vec![0u8; 8]).wait().map_err(error)?;
            self.pong.recv().map_err(error)?;
            Ok(())
        })
    }
}
