//! `tick`: the synchronous tick round trip against its floor and against TCP.
//!
//! In one run, on one machine, each between two processes:
//! (a) raw iceoryx2 ping-pong (u64 there, u64 back) — the floor — and
//!     raw iceoryx2 in the tick's message shapes (`crate::shapes`);
//! (b) simbus: `Ticker::tick` sent → that frame's snapshot received, on an
//!     empty scene, spinning and blocking; and spinning with the tick
//!     answered by its frame (`Ticker::tick_and_read`: one message each way);
//! (c) the same exchange (an 8-byte tick, a frame header back) over TCP
//!     loopback, the transport CARLA uses.

use std::time::{Duration, Instant};

use clap::Args;
use iceoryx2::prelude::*;
use iceoryx2::service::Service;
use sim_client::WaitMode;
use simbus_process::ChildGuard;
use simbus_transport::Bus;

use crate::baselines::{raw_ports, tcp_exchange};
use crate::stats::{header, Latencies};
use crate::support::{machine_state, spawn_peer, BackgroundLoad, BenchServer, Placement};

#[derive(Debug, Args)]
pub(crate) struct TickArgs {
    /// Round trips measured per row (after a warm-up of 10%).
    #[arg(long, default_value_t = 20_000)]
    iterations: u64,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
    /// Instead of the table: split the simbus blocking round trip into its
    /// two hops (tick sent -> frame published, published -> snapshot held),
    /// with the server and the clients in `--hops MODE` (spin, hybrid, block).
    #[arg(long, value_name = "MODE")]
    hops: Option<WaitMode>,
    /// Run with this many lowest-priority spinning processes beside the
    /// benchmark ("the machine busy with other work"); 0: as the machine is.
    #[arg(long, default_value_t = 0)]
    busy: usize,
    /// Also draw the rows' latency distributions (percentile plot, log µs)
    /// into this PNG.
    #[arg(long, value_name = "FILE.png")]
    plot: Option<std::path::PathBuf>,
    /// Instead of the table: the median time of each stage of a simbus
    /// round trip (client sends, server wakes, takes the tick, steps,
    /// publishes, answers, notifies; client wakes, holds the frame), per
    /// wait mode, with sleeps, system calls and CPU migrations per round
    /// trip.
    #[arg(long, conflicts_with = "hops")]
    breakdown: bool,
    /// Where the processes run: `same` (all on CPU 0), `split` (this
    /// process on CPU 0, its peers and the server on CPU 1) or `unpinned`.
    /// Without it: each placement in turn, each against its own floor.
    #[arg(long, value_enum)]
    placement: Option<Placement>,
}

const WARMUP_FRACTION: u64 = 10;

/// One exchange of the benchmark: its round trip, and the processes that
/// serve it (stopped with SIGSTOP while other rows run, so that a spinning
/// peer does not take a core from them).
struct Row {
    name: &'static str,
    round_trip: Box<dyn FnMut() -> anyhow::Result<()>>,
    peers: Vec<u32>,
    _guards: Vec<ChildGuard>,
    _server: Option<BenchServer>,
    latencies: Latencies,
}

impl Row {
    /// A row whose peer is `server`, measuring `round_trip`.
    fn on_server(
        name: &'static str,
        server: BenchServer,
        round_trip: impl FnMut() -> anyhow::Result<()> + 'static,
    ) -> Self {
        Row {
            name,
            peers: vec![server.pid()],
            _guards: Vec::new(),
            _server: Some(server),
            round_trip: Box::new(round_trip),
            latencies: Latencies::new(),
        }
    }

    fn signal(&self, signal: i32) {
        for &pid in &self.peers {
            let _ = simbus_process::send_signal(pid, signal);
        }
    }
}

/// `S`: iceoryx2's `ipc::Service` (its event a Unix datagram socket) or
/// simbus's [`Bus`] (a futex); `kind` names the peer that runs the same.
fn raw_row<S: Service + 'static>(name: &'static str, kind: &str) -> anyhow::Result<Row> {
    let block = !kind.starts_with("iceoryx-spin");
    let world = format!("bench-raw-{kind}-{}", std::process::id());
    let ports = raw_ports::<S>(&world, "ping", "pong")?;
    let (peer, _) = spawn_peer(kind, &world)?;
    let mut n = 0;
    Ok(Row {
        name,
        peers: vec![peer.id()],
        _guards: vec![peer],
        _server: None,
        round_trip: Box::new(move || {
            n += 1;
            ports.send(n, block)?;
            anyhow::ensure!(ports.receive(block)? == n, "ping-pong out of order");
            Ok(())
        }),
        latencies: Latencies::new(),
    })
}

/// Raw iceoryx2 in one of the tick's message shapes (`crate::shapes`).
fn shape_row(name: &'static str, shape: crate::shapes::Shape) -> anyhow::Result<Row> {
    let world = format!("bench-shape-{}-{}", shape.peer_kind(), std::process::id());
    let (peer, _) = spawn_peer(shape.peer_kind(), &world)?;
    let mut ticking = crate::shapes::Ticking::open(&world, shape)?;
    Ok(Row {
        name,
        peers: vec![peer.id()],
        _guards: vec![peer],
        _server: None,
        round_trip: Box::new(move || ticking.round_trip()),
        latencies: Latencies::new(),
    })
}

fn futex_row() -> anyhow::Result<Row> {
    let (peer, round_trip) = crate::futex::exchange()?;
    Ok(Row {
        name: "(f) futex, block (floor)",
        peers: vec![peer.id()],
        _guards: vec![peer],
        _server: None,
        round_trip: Box::new(round_trip),
        latencies: Latencies::new(),
    })
}

fn tcp_row() -> anyhow::Result<Row> {
    let (peer, round_trip) = tcp_exchange()?;
    Ok(Row {
        name: "(c) TCP loopback",
        peers: vec![peer.id()],
        _guards: vec![peer],
        _server: None,
        round_trip: Box::new(round_trip),
        latencies: Latencies::new(),
    })
}

/// `server`: extra server flags (how it waits for ticks); `mode`: how the
/// ticker and the subscriber wait.
fn simbus_row(name: &'static str, server: &[&str], mode: WaitMode) -> anyhow::Result<Row> {
    let (server, mut client, mut ticker) = simbus_world(&format!("tick-{mode:?}"), server, mode)?;
    let timeout = Duration::from_secs(10);
    Ok(Row::on_server(name, server, move || {
        let frame = ticker.tick(timeout)?;
        let snapshot = client.wait_for_tick(timeout)?;
        anyhow::ensure!(
            snapshot.frame() == frame,
            "snapshot of frame {} after tick {frame}",
            snapshot.frame()
        );
        Ok(())
    }))
}

/// A server on the empty scene ticked every 0.01 s (and `server` flags)
/// and its ticking client, both waiting as `mode` says.
fn simbus_world(
    tag: &str,
    server: &[&str],
    mode: WaitMode,
) -> anyhow::Result<(BenchServer, sim_client::Client, sim_client::Ticker)> {
    let mut server_args = vec!["--scene", "empty", "--fixed-delta-seconds", "0.01"];
    server_args.extend_from_slice(server);
    let server = BenchServer::start(tag, &server_args)?;
    let (client, ticker) = crate::support::ticking_client(&server.world, mode)?;
    Ok((server, client, ticker))
}

/// The simbus row with the tick answered by its frame
/// ([`sim_client::Ticker::tick_and_read`]): one message each way, the
/// server and the ticker waiting as `mode` says; the server with
/// `--max-clients max_clients` (None: its default).
fn simbus_by_frame_row(
    name: &'static str,
    mode: WaitMode,
    max_clients: Option<&str>,
) -> anyhow::Result<Row> {
    let mut server_args = vec!["--wait-mode", mode.name()];
    if let Some(max) = max_clients {
        server_args.extend(["--max-clients", max]);
    }
    let tag = format!(
        "tick-by-frame-{}-{}",
        mode.name(),
        max_clients.unwrap_or("default")
    );
    let (server, mut client, mut ticker) = simbus_world(&tag, &server_args, mode)?;
    let timeout = Duration::from_secs(10);
    let mut last: Option<u64> = None;
    Ok(Row::on_server(name, server, move || {
        let snapshot = ticker.tick_and_read(&mut client, timeout)?;
        anyhow::ensure!(
            last.is_none_or(|last| snapshot.frame() == last + 1),
            "frame {} after frame {last:?}",
            snapshot.frame()
        );
        last = Some(snapshot.frame());
        Ok(())
    }))
}

/// The two hops of a tick round trip, from the frame's platform timestamp
/// (taken as the server publishes it).
fn hops(mode: WaitMode, n: u64, machine: &str) -> anyhow::Result<()> {
    let name = mode.name();
    let server = BenchServer::start(
        "hops",
        &[
            "--scene",
            "empty",
            "--fixed-delta-seconds",
            "0.01",
            "--wait-mode",
            name,
        ],
    )?;
    let (mut client, mut ticker) = crate::support::ticking_client(&server.world, mode)?;
    let timeout = Duration::from_secs(10);
    let (mut to_server, mut to_client, mut whole) =
        (Latencies::new(), Latencies::new(), Latencies::new());
    for i in 0..n + n / 10 {
        let sent = crate::support::now_ns();
        let frame = ticker.tick(timeout)?;
        let snapshot = client.wait_for_tick(timeout)?;
        let held = crate::support::now_ns();
        anyhow::ensure!(snapshot.frame() == frame, "out of order");
        let published = (snapshot.timestamp().platform_timestamp * 1e9) as u64;
        if i >= n / 10 {
            to_server.record(published.saturating_sub(sent));
            to_client.record(held.saturating_sub(published));
            whole.record(held.saturating_sub(sent));
        }
    }
    println!("simbus tick round trip in two hops, server and clients in {name} mode ({n} ticks)");
    println!("machine: {machine}");
    println!("{}", header("hop"));
    println!("{}", to_server.row("tick sent -> frame published"));
    println!("{}", to_client.row("published -> snapshot held"));
    println!("{}", whole.row("round trip"));
    Ok(())
}

/// Rounds the measurement is cut into: every row runs a slice in each
/// round, so all rows see the same machine, however its load drifts.
const ROUNDS: u64 = 20;

/// Measures `n` round trips per row, interleaved: in each round every row
/// (its peers woken with SIGCONT, the others stopped) runs `n / ROUNDS`
/// round trips after a short warm-up that is not counted.
fn interleave(rows: &mut [Row], n: u64) -> anyhow::Result<()> {
    for row in rows.iter() {
        row.signal(libc::SIGSTOP);
    }
    let slice = (n / ROUNDS).max(1);
    for _ in 0..ROUNDS {
        for row in rows.iter_mut() {
            row.signal(libc::SIGCONT);
            for _ in 0..(slice / WARMUP_FRACTION).max(10) {
                (row.round_trip)()?;
            }
            for _ in 0..slice {
                let start = Instant::now();
                (row.round_trip)()?;
                row.latencies.record(start.elapsed().as_nanos() as u64);
            }
            row.signal(libc::SIGSTOP);
        }
    }
    for row in rows.iter() {
        row.signal(libc::SIGCONT);
    }
    Ok(())
}

pub(crate) fn run(args: TickArgs) -> anyhow::Result<()> {
    let n = args.iterations;
    let _load = BackgroundLoad::start(args.busy)?;
    let machine = machine_state(Duration::from_millis(500));
    if let Some(mode) = args.hops {
        return hops(mode, n, &machine);
    }
    let placements = args.placement.map_or(Placement::ALL.to_vec(), |p| vec![p]);
    let mut json = Vec::new();
    for placement in placements {
        json.push(if args.breakdown {
            let rows = crate::breakdown::measure(n, placement)?;
            crate::breakdown::print(placement, &rows, n, &machine, args.json)
        } else {
            table(&args, placement, &machine)?
        });
    }
    if args.json {
        println!("{}", serde_json::Value::Array(json));
    }
    Ok(())
}

/// Every row of the table under `placement`: printed, or returned as JSON.
fn table(
    args: &TickArgs,
    placement: Placement,
    machine: &str,
) -> anyhow::Result<serde_json::Value> {
    let n = args.iterations;
    let rows = measure_rows(n, placement)?;
    if let Some(path) = &args.plot {
        let series: Vec<(&str, &Latencies)> = rows.iter().map(|(n, l)| (*n, l)).collect();
        crate::plot::percentiles(
            path,
            &format!("Tick round trip, {n} per row, rows interleaved"),
            &series,
        )?;
    }
    let ratios = ratios(&rows);
    if args.json {
        let mut json = serde_json::Map::new();
        for (name, latencies) in &rows {
            json.insert((*name).into(), latencies.json());
        }
        for (name, ratio) in ratios {
            json.insert(name.into(), ratio.into());
        }
        json.insert("iterations".into(), n.into());
        json.insert("machine".into(), machine.into());
        json.insert("placement".into(), placement.name().into());
        return Ok(serde_json::Value::Object(json));
    }
    report(n, placement, machine, &rows, &ratios);
    Ok(serde_json::Value::Null)
}

/// Every row, pinned as `placement` says, `n` round trips each, interleaved.
/// On one CPU the spinning rows are left out: a spinner keeps its peer
/// from running for a whole timeslice (8 ms) each round trip.
fn measure_rows(n: u64, placement: Placement) -> anyhow::Result<Vec<(&'static str, Latencies)>> {
    let mut rows = Vec::new();
    if placement != Placement::Same {
        rows.extend(spinning_rows()?);
    }
    rows.extend([
        raw_row::<ipc::Service>("(a) raw iceoryx2, block", "iceoryx-block")?,
        raw_row::<Bus>("(a) raw iceoryx2 futex event, block", "iceoryx-bus-block")?,
        futex_row()?,
        shape_row(
            "(a) iox2 tick as request + step, block",
            crate::shapes::Shape::RequestBlock,
        )?,
        shape_row(
            "(a) iox2 request, futex wake-ups + step",
            crate::shapes::Shape::RequestFutex,
        )?,
        shape_row(
            "(a) futex tick + iox2 frame + step",
            crate::shapes::Shape::FutexBlock,
        )?,
        simbus_row("(b) simbus, hybrid", &[], WaitMode::Hybrid)?,
        simbus_row(
            "(b) simbus, block",
            &["--wait-mode", "block"],
            WaitMode::Block,
        )?,
        simbus_by_frame_row("(b) simbus, hybrid, by frame", WaitMode::Hybrid, None)?,
        simbus_by_frame_row("(b) simbus, block, by frame", WaitMode::Block, None)?,
        tcp_row()?,
    ]);
    let peers: Vec<u32> = rows.iter().flat_map(|r| r.peers.iter().copied()).collect();
    placement.apply(&peers)?;
    interleave(&mut rows, n)?;
    Placement::Unpinned.apply(&[])?;
    Ok(rows.into_iter().map(|r| (r.name, r.latencies)).collect())
}

/// The rows whose both ends spin.
fn spinning_rows() -> anyhow::Result<Vec<Row>> {
    Ok(vec![
        raw_row::<ipc::Service>("(a) raw iceoryx2, spin", "iceoryx-spin")?,
        raw_row::<ipc::Service>("(a) raw iox2 spin + step", "iceoryx-spin-step")?,
        shape_row(
            "(a) iox2 tick as request + step",
            crate::shapes::Shape::Request,
        )?,
        shape_row(
            "(a) iox2 same, frames no history",
            crate::shapes::Shape::RequestNoHistory,
        )?,
        shape_row(
            "(a) iox2 tick published + step",
            crate::shapes::Shape::Publish,
        )?,
        simbus_row(
            "(b) simbus, all spin",
            &["--wait-mode", "spin"],
            WaitMode::Spin,
        )?,
        simbus_by_frame_row("(b) simbus, spin, by frame", WaitMode::Spin, None)?,
        simbus_by_frame_row("(b) by frame, --max-clients 4", WaitMode::Spin, Some("4"))?,
    ])
}

/// The ratios the goals are stated in (p50 unless named).
fn ratios(rows: &[(&str, Latencies)]) -> Vec<(&'static str, f64)> {
    let at = |prefix: &str, q: f64| {
        rows.iter()
            .find(|(name, _)| name.starts_with(prefix))
            .map_or(f64::NAN, |(_, l)| l.quantile_us(q))
    };
    let p50 = |prefix: &str| at(prefix, 0.5);
    let (raw_spin, raw_block, raw_futex) = (
        p50("(a) raw iceoryx2, spin"),
        p50("(a) raw iceoryx2, block"),
        p50("(a) raw iceoryx2 futex"),
    );
    let (floor, tcp) = (p50("(f)"), p50("(c)"));
    let (spin, hybrid, block) = (
        p50("(b) simbus, all spin"),
        p50("(b) simbus, hybrid"),
        p50("(b) simbus, block"),
    );
    let raw_step = p50("(a) raw iox2 spin + step");
    let (request, published) = (
        p50("(a) iox2 tick as request"),
        p50("(a) iox2 tick published"),
    );
    let by_frame = p50("(b) simbus, spin, by frame");
    let block_by_frame = p50("(b) simbus, block, by frame");
    vec![
        ("b/a simbus all spin / raw spin", spin / raw_spin),
        ("b/a simbus all spin / raw + step", spin / raw_step),
        ("b/a spin by frame / raw spin", by_frame / raw_spin),
        ("a/a tick request + step / raw spin", request / raw_spin),
        ("a/a tick published + step / raw spin", published / raw_spin),
        ("b/a spin by frame / tick request", by_frame / request),
        (
            "b/b by frame: 4 clients / 64",
            p50("(b) by frame, --max-clients 4") / by_frame,
        ),
        ("b/a simbus block / raw block", block / raw_block),
        ("b/f simbus block / futex floor", block / floor),
        ("b/f simbus hybrid / futex floor", hybrid / floor),
        ("a/f raw iceoryx2 block / futex", raw_block / floor),
        ("a/f raw iox2 futex event / futex", raw_futex / floor),
        ("c/b TCP / simbus all spin", tcp / spin),
        ("c/b TCP / simbus hybrid", tcp / hybrid),
        ("c/b TCP / simbus block", tcp / block),
        ("b/f block by frame / futex floor", block_by_frame / floor),
        (
            "a/f futex tick + frame / futex floor",
            p50("(a) futex tick + iox2 frame") / floor,
        ),
        (
            "a/f request, futex wake-ups / futex floor",
            p50("(a) iox2 request, futex wake-ups") / floor,
        ),
        (
            "a/f tick request, block / futex floor",
            p50("(a) iox2 tick as request + step, block") / floor,
        ),
        (
            "b/a block by frame / tick request, block",
            block_by_frame / p50("(a) iox2 tick as request + step, block"),
        ),
        ("c/b TCP / block by frame", tcp / block_by_frame),
        (
            "b/c hybrid p99 / TCP p99",
            at("(b) simbus, hybrid", 0.99) / at("(c)", 0.99),
        ),
        (
            "b/c hybrid by frame p99 / TCP p99",
            at("(b) simbus, hybrid, by frame", 0.99) / at("(c)", 0.99),
        ),
    ]
    .into_iter()
    // A row left out (the spinning ones on one CPU) has no ratio.
    .filter(|(_, ratio)| ratio.is_finite())
    .collect()
}

/// Prints the table and its ratios.
fn report(
    n: u64,
    placement: Placement,
    machine: &str,
    rows: &[(&str, Latencies)],
    ratios: &[(&str, f64)],
) {
    println!("tick round trip: tick sent -> that frame's snapshot received ({n} round trips each, empty scene)");
    println!("rows interleaved: {ROUNDS} rounds, each row's peers running only during its slice");
    println!("machine: {machine}; placement: {}", placement.name());
    println!("all spin: server and clients --wait-mode spin (left out on one CPU: a timeslice per round trip); hybrid (the server's default): both poll 100 µs, yielding, then sleep;");
    println!("block: server and clients --wait-mode block (every hop a kernel wake-up);");
    println!("futex: two processes sleeping in futex(2) on a shared page (the blocking floor)");
    println!("iox2/futex tick ... block: the tick's shape with an empty world's step and no simbus code, both ends asleep (bench/src/shapes.rs)");
    println!("{}", header("exchange"));
    for (name, latencies) in rows {
        println!("{}", latencies.row(name));
    }
    println!();
    for (name, ratio) in ratios {
        println!("{name:<38} {ratio:>6.2}x");
    }
    println!();
}
