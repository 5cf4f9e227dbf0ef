//! `fanout`: one publisher, many subscribers — how long until the *last*
//! subscriber holds a frame, or an 8 MiB sensor capture, with 1, 4, 16 and
//! 64 subscriber processes, spinning and blocking.
//!
//! The bench is the ticker of a synchronous world (empty scene; a 2048x1024
//! depth camera for the sensor rows) and paces its ticks so that every
//! subscriber can keep up. Each subscriber is its own process: it records,
//! per frame, the time from publication (the header's platform timestamp,
//! taken just before `send`) until it held the sample and had read its first
//! and last element, and reports them at the end. A frame's fan-out latency
//! is the largest of its subscribers'.

use std::collections::BTreeMap;
use std::io::{BufRead, BufReader};
use std::process::{Command, Stdio};
use std::time::Duration;

use anyhow::Context;
use clap::Args;
use shared_types::SensorSpec;
use sim_client::{Client, WaitMode};
use simbus_process::ChildGuard;

use crate::stats::Latencies;
use crate::support::{machine_state, now_ns, sync_ticker, BenchServer};

#[derive(Debug, Args)]
pub(crate) struct FanoutArgs {
    /// Frames measured per row (after 10% warm-up).
    #[arg(long, default_value_t = 300)]
    samples: u64,
    /// Subscriber counts to measure.
    #[arg(long, value_delimiter = ',', default_value = "1,4,16,64")]
    subscribers: Vec<usize>,
    /// Spinning rows only up to this many subscribers (more spinning
    /// processes than cores measure the scheduler, not the transport).
    #[arg(long, default_value_t = 16)]
    max_spinners: usize,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
    /// Also draw every row's distribution of the last subscriber's latency
    /// (percentile plot, log µs) into this PNG.
    #[arg(long, value_name = "FILE.png")]
    plot: Option<std::path::PathBuf>,
}

/// The subscriber peer's arguments, passed on its command line.
#[derive(Debug, Args)]
pub(crate) struct FanoutPeerArgs {
    /// The world.
    #[arg(long)]
    world: String,
    /// `spin` or `block`.
    #[arg(long)]
    mode: String,
    /// The sensor to read (0: frames).
    #[arg(long, default_value_t = 0)]
    sensor: u64,
    /// Samples to record before reporting.
    #[arg(long)]
    samples: u64,
    /// Subscriber ports in this one process, polled in turn by one spinning
    /// thread (the transport's fan-out without more spinners than cores);
    /// a frame's latency is then the time until the last port held it.
    #[arg(long, default_value_t = 1)]
    ports: usize,
}

/// The subscriber: prints `ready`, records `frame latency_ns` per sample,
/// and prints them all on one line when it has `samples`, or when nothing
/// came for 3 s (it lost frames: the bench counts what is missing).
pub(crate) fn peer(args: FanoutPeerArgs) -> anyhow::Result<()> {
    let mode = if args.mode == "spin" {
        WaitMode::Spin
    } else {
        WaitMode::Block
    };
    let timeout = Duration::from_secs(3);
    let mut out = Vec::with_capacity(args.samples as usize);
    if args.ports > 1 {
        polled_ports(&args, &mut out)?;
        let line: Vec<String> = out.iter().map(|(f, l)| format!("{f}:{l}")).collect();
        println!("{}", line.join(" "));
        return Ok(());
    }
    let mut client = Client::connect(&args.world, Duration::from_secs(30))?;
    if args.sensor == 0 {
        client.set_wait_mode(mode);
        println!("ready");
        while (out.len() as u64) < args.samples {
            let Ok(snapshot) = client.wait_for_tick(timeout) else {
                break;
            };
            let held = now_ns();
            let published = (snapshot.timestamp().platform_timestamp * 1e9) as u64;
            out.push((snapshot.frame(), held.saturating_sub(published)));
        }
    } else {
        let mut sensor = client.sensor(args.sensor)?;
        sensor.set_wait_mode(mode);
        println!("ready");
        while (out.len() as u64) < args.samples {
            let Ok(capture) = sensor.recv(timeout) else {
                break;
            };
            let depth = capture.depth().context("a depth capture")?;
            // Hold it: the header and the first and last element read.
            anyhow::ensure!(depth[0].is_finite() && depth[depth.len() - 1].is_finite());
            let held = now_ns();
            let published = (capture.header().platform_timestamp * 1e9) as u64;
            out.push((capture.header().frame, held.saturating_sub(published)));
        }
    }
    let line: Vec<String> = out.iter().map(|(f, l)| format!("{f}:{l}")).collect();
    println!("{}", line.join(" "));
    Ok(())
}

/// `args.ports` frame subscribers (or sensor readers) in this process, one
/// thread spinning over them in turn.
fn polled_ports(args: &FanoutPeerArgs, out: &mut Vec<(u64, u64)>) -> anyhow::Result<()> {
    let mut clients = (0..args.ports)
        .map(|_| {
            Client::connect(&args.world, Duration::from_secs(30)).map(|mut c| {
                c.set_wait_mode(WaitMode::Spin);
                c
            })
        })
        .collect::<Result<Vec<_>, _>>()?;
    let mut sensors = if args.sensor == 0 {
        Vec::new()
    } else {
        clients
            .iter()
            .map(|c| c.sensor(args.sensor))
            .collect::<Result<Vec<_>, _>>()?
    };
    println!("ready");
    let n = args.ports;
    // Per frame: how many ports have it, and the latest time one got it.
    let mut pending: BTreeMap<u64, (usize, u64, u64)> = BTreeMap::new();
    let mut idle_since = std::time::Instant::now();
    while (out.len() as u64) < args.samples && idle_since.elapsed() < Duration::from_secs(3) {
        for i in 0..n {
            let got = if args.sensor == 0 {
                match clients[i].wait_for_frame(Duration::ZERO) {
                    Ok(view) => Some((
                        view.frame(),
                        (view.timestamp().platform_timestamp * 1e9) as u64,
                    )),
                    Err(sim_client::WaitError::Timeout { .. }) => None,
                    Err(e) => return Err(e.into()),
                }
            } else {
                sensors[i].try_recv()?.map(|c| {
                    let depth = c.depth().unwrap_or(&[]);
                    std::hint::black_box((depth.first(), depth.last()));
                    (
                        c.header().frame,
                        (c.header().platform_timestamp * 1e9) as u64,
                    )
                })
            };
            if let Some((frame, published)) = got {
                idle_since = std::time::Instant::now();
                let held = now_ns();
                let entry = pending.entry(frame).or_insert((0, published, 0));
                entry.0 += 1;
                entry.2 = entry.2.max(held);
                if entry.0 == n {
                    out.push((frame, entry.2.saturating_sub(entry.1)));
                    pending.remove(&frame);
                }
            }
        }
    }
    Ok(())
}

struct Subscriber {
    guard: ChildGuard,
    lines: std::sync::mpsc::Receiver<String>,
}

fn spawn_subscriber(
    world: &str,
    mode: &str,
    sensor: u64,
    samples: u64,
    ports: usize,
) -> anyhow::Result<Subscriber> {
    let mut child = Command::new(std::env::current_exe()?)
        .args(["fanout-peer", "--world", world, "--mode", mode])
        .args(["--ports", &ports.to_string()])
        .args([
            "--sensor",
            &sensor.to_string(),
            "--samples",
            &samples.to_string(),
        ])
        .stdin(Stdio::null())
        .stdout(Stdio::piped())
        .spawn()
        .context("starting a fan-out subscriber")?;
    let stdout = child.stdout.take().context("subscriber stdout")?;
    let (tx, lines) = std::sync::mpsc::channel();
    std::thread::spawn(move || {
        for line in BufReader::new(stdout).lines().map_while(Result::ok) {
            if tx.send(line).is_err() {
                break;
            }
        }
    });
    Ok(Subscriber {
        guard: ChildGuard::new(child, Duration::from_secs(2)),
        lines,
    })
}

/// One row: `n` subscribers of frames (`sensor` 0) or of a sensor.
#[allow(clippy::too_many_arguments)]
pub(crate) fn row(
    world: &str,
    ticker: &mut sim_client::Ticker,
    n: usize,
    mode: &str,
    sensor: u64,
    samples: u64,
    pace: Duration,
) -> anyhow::Result<(Latencies, u64)> {
    let warmup = samples / 10;
    let total = samples + warmup;
    // "ports": n subscriber ports in one process, polled by one thread.
    let subscribers: Vec<Subscriber> = if mode == "ports" {
        vec![spawn_subscriber(world, "spin", sensor, total, n)?]
    } else {
        (0..n)
            .map(|_| spawn_subscriber(world, mode, sensor, total, 1))
            .collect::<anyhow::Result<_>>()?
    };
    for s in &subscribers {
        let ready = s.lines.recv_timeout(Duration::from_secs(60))?;
        anyhow::ensure!(ready == "ready", "a subscriber did not start: {ready}");
    }
    // Paced ticks, the ticker asleep in between (a spinning ticker would
    // take a core from the subscribers): each has the frame long before the
    // next.
    let mut first_frame = None;
    for _ in 0..total {
        std::thread::sleep(pace);
        let frame = ticker.tick(Duration::from_secs(30))?;
        first_frame.get_or_insert(frame);
    }
    let first = first_frame.unwrap_or(0);
    let mut worst: BTreeMap<u64, u64> = BTreeMap::new();
    let mut lost = 0;
    for mut s in subscribers {
        let report = s
            .lines
            .recv_timeout(Duration::from_secs(120))
            .context("a subscriber's report")?;
        lost += total.saturating_sub(report.split_whitespace().count() as u64);
        // A frame counts only when every subscriber reported it.
        for item in report.split_whitespace() {
            let (frame, latency) = item.split_once(':').context("frame:latency")?;
            let (frame, latency): (u64, u64) = (frame.parse()?, latency.parse()?);
            let w = worst.entry(frame).or_insert(0);
            *w = (*w).max(latency);
        }
        s.guard.wait_timeout(Duration::from_secs(10))?;
    }
    let mut latencies = Latencies::new();
    for (_, latency) in worst.range(first + warmup..) {
        latencies.record(*latency);
    }
    Ok((latencies, lost))
}

/// One row: the stream, the wait mode, the subscribers, the last
/// subscriber's latencies and the samples lost.
type Row = (&'static str, &'static str, usize, Latencies, u64);

pub(crate) fn run(args: FanoutArgs) -> anyhow::Result<()> {
    let machine = machine_state(Duration::from_millis(500));
    let most = args.subscribers.iter().copied().max().unwrap_or(1);
    let limit = (most + 8).to_string();
    let server = BenchServer::start(
        "fanout",
        &[
            "--scene",
            "empty",
            "--max-clients",
            &limit,
            "--max-sensor-readers",
            &limit,
        ],
    )?;
    let client = Client::connect(&server.world, Duration::from_secs(10))?;
    let mut ticker = sync_ticker(&client, 0.01)?;
    let sensor = client.spawn_sensor(SensorSpec::depth([0.0; 3], 2048, 1024, 90.0, 100.0))?;
    let sensor_id = sensor.id();
    drop(sensor);
    let rows = measure_rows(&args, &server.world, &mut ticker, sensor_id)?;
    ticker.release()?;
    if let Some(path) = &args.plot {
        plot_rows(path, &rows)?;
    }
    report(&args, &machine, &rows);
    Ok(())
}

/// Every row: frames and the 8 MiB depth sensor `sensor_id`, each wait
/// mode, each number of subscribers.
fn measure_rows(
    args: &FanoutArgs,
    world: &str,
    ticker: &mut sim_client::Ticker,
    sensor_id: u64,
) -> anyhow::Result<Vec<Row>> {
    let mut rows = Vec::new();
    for stream in ["frames", "8 MiB depth"] {
        for mode in ["spin", "ports", "block"] {
            for &n in &args.subscribers {
                // More spinning processes than cores measure the scheduler,
                // not the transport.
                if mode == "spin" && n > args.max_spinners || mode == "ports" && n == 1 {
                    continue;
                }
                // Room for every subscriber to be woken and run on 2 cores.
                let pace = Duration::from_micros(1000 + 100 * n as u64);
                let id = if stream == "frames" { 0 } else { sensor_id };
                let (latencies, lost) = row(world, ticker, n, mode, id, args.samples, pace)?;
                rows.push((stream, mode, n, latencies, lost));
            }
        }
    }
    Ok(rows)
}

/// The last subscriber's latency distributions, one per row, into `path`.
fn plot_rows(path: &std::path::Path, rows: &[Row]) -> anyhow::Result<()> {
    let names: Vec<String> = rows
        .iter()
        .map(|(stream, mode, n, ..)| format!("{stream}, {mode}, {n}"))
        .collect();
    let series: Vec<(&str, &Latencies)> = names
        .iter()
        .zip(rows)
        .map(|(name, (.., l, _))| (name.as_str(), l))
        .collect();
    crate::plot::percentiles(
        path,
        "Fan-out: the last subscriber's latency (stream, mode, subscribers)",
        &series,
    )
}

/// Prints the table (or, with --json, one object).
fn report(args: &FanoutArgs, machine: &str, rows: &[Row]) {
    if args.json {
        let json: Vec<_> = rows
            .iter()
            .map(|(stream, mode, n, l, lost)| {
                serde_json::json!({"stream": stream, "mode": mode, "subscribers": n, "last_subscriber": l.json(), "samples_lost": lost})
            })
            .collect();
        println!(
            "{}",
            serde_json::json!({"machine": machine, "rows": json, "samples": args.samples})
        );
        return;
    }
    println!(
        "fan-out: publish -> the LAST of N subscriber processes holds the sample ({} frames per row, paced ticks)",
        args.samples
    );
    println!("machine: {machine}");
    println!(
        "{:<12} {:<6} {:>5} {:>10} {:>10} {:>10} {:>6}",
        "stream", "wait", "subs", "p50 µs", "p99 µs", "p999 µs", "lost"
    );
    for (stream, mode, n, l, lost) in rows {
        println!(
            "{stream:<12} {mode:<6} {n:>5} {:>10.1} {:>10.1} {:>10.1} {lost:>6}",
            l.quantile_us(0.5),
            l.quantile_us(0.99),
            l.quantile_us(0.999)
        );
    }
}
