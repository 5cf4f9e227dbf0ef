//! `tick --breakdown`: where a synchronous round trip's time goes, stage by
//! stage, in each wait mode.
//!
//! The server (the real binary, `SIMBUS_STAMPS=FILE`) and this client stamp
//! each stage with `CLOCK_MONOTONIC` (one clock for every process of the
//! machine; `simbus_transport::stamps`); the two files are joined by frame
//! id. Beside the stages: the sleeps (voluntary context switches) of each
//! side per round trip, from `/proc`, and, where `perf` runs, the system
//! calls and CPU migrations per round trip.

use std::collections::BTreeMap;
use std::process::{Child, Command, Stdio};
use std::time::Duration;

use sim_client::WaitMode;
use simbus_transport::stamps::{self, Stage, Stamp};

use crate::support::{sleeps, ticking_client, BenchServer, Placement};

/// The spans between consecutive stages, each named by where its time goes.
const SPANS: [(Stage, Stage, &str); 9] = [
    (
        Stage::ClientSend,
        Stage::ServerWake,
        "client sends -> server wakes",
    ),
    (
        Stage::ServerWake,
        Stage::ServerTick,
        "server wakes -> takes the tick",
    ),
    (
        Stage::ServerTick,
        Stage::StepBegin,
        "takes the tick -> step begins",
    ),
    (Stage::StepBegin, Stage::StepEnd, "physics step"),
    (
        Stage::StepEnd,
        Stage::Published,
        "step ends -> frame published",
    ),
    (
        Stage::Published,
        Stage::Answered,
        "published -> answer sent",
    ),
    (
        Stage::Answered,
        Stage::Notified,
        "answer sent -> clients notified",
    ),
    (
        Stage::Notified,
        Stage::ClientWake,
        "notified -> client wakes",
    ),
    (
        Stage::ClientWake,
        Stage::ClientHolds,
        "client wakes -> holds the frame",
    ),
];

/// One mode's breakdown.
pub(crate) struct Breakdown {
    mode: WaitMode,
    /// Ticks answered by their frame (`Ticker::tick_and_read`).
    by_frame: bool,
    /// Median of each span, µs, in [`SPANS`] order.
    spans: Vec<f64>,
    /// Median whole round trip (client sends -> holds the frame), µs.
    whole: f64,
    /// Per round trip: sleeps of the server and of the client.
    sleeps: (f64, f64),
    /// Per round trip, from perf: the server's and the client's system
    /// calls and CPU migrations (None where perf does not run).
    perf: Option<PerfCounts>,
}

/// What `perf stat` counted on both sides, per round trip.
#[derive(Debug, Clone, Copy)]
struct PerfCounts {
    server_syscalls: f64,
    client_syscalls: f64,
    migrations: f64,
}

/// Measures `n` round trips in each wait mode under `placement`, then
/// spinning and blocking with the tick answered by its frame.
pub(crate) fn measure(n: u64, placement: Placement) -> anyhow::Result<Vec<Breakdown>> {
    [
        (WaitMode::Spin, false),
        (WaitMode::Spin, true),
        (WaitMode::Hybrid, false),
        (WaitMode::Block, false),
        (WaitMode::Block, true),
    ]
    .into_iter()
    .map(|(mode, by_frame)| one_mode((mode, by_frame), n, placement))
    .collect()
}

impl Breakdown {
    /// Its column's name.
    fn name(&self) -> &'static str {
        match (self.by_frame, self.mode) {
            (false, mode) => mode.name(),
            (true, WaitMode::Block) => "blk frame",
            (true, _) => "by frame",
        }
    }
}

fn one_mode(
    (mode, by_frame): (WaitMode, bool),
    n: u64,
    placement: Placement,
) -> anyhow::Result<Breakdown> {
    let file = std::env::temp_dir().join(format!(
        "simbus-stamps-{}-{}-{by_frame}",
        std::process::id(),
        mode.name()
    ));
    let server = BenchServer::start_with_env(
        &format!("breakdown-{}", mode.name()),
        &[
            "--scene",
            "empty",
            "--fixed-delta-seconds",
            "0.01",
            "--wait-mode",
            mode.name(),
        ],
        &[(stamps::SIMBUS_STAMPS, file.as_os_str())],
    )?;
    placement.apply(&[server.pid()])?;
    let (mut client, mut ticker) = ticking_client(&server.world, mode)?;
    let timeout = Duration::from_secs(10);
    for _ in 0..(n / 10).max(100) {
        ticker.tick(timeout)?;
        client.wait_for_tick(timeout)?;
    }
    stamps::enable(16 * n as usize);
    let (server_pid, me) = (server.pid(), std::process::id());
    let before = (sleeps(server_pid), sleeps(me));
    let perf = Perf::start(server_pid, me);
    for _ in 0..n {
        let held = if by_frame {
            ticker.tick_and_read(&mut client, timeout)?.frame()
        } else {
            let frame = ticker.tick(timeout)?;
            let snapshot = client.wait_for_tick(timeout)?;
            anyhow::ensure!(snapshot.frame() == frame, "snapshot out of order");
            frame
        };
        stamps::stamp(Stage::ClientHolds, held);
    }
    let perf = perf.map(|p| p.finish(n));
    let after = (sleeps(server_pid), sleeps(me));
    let mine = stamps::take();
    drop((ticker, client));
    server.stop()?;
    Placement::Unpinned.apply(&[])?;
    let theirs = stamps::read(&file)?;
    let _ = std::fs::remove_file(&file);
    let per_trip = |a: u64, b: u64| b.saturating_sub(a) as f64 / n as f64;
    let (spans, whole) = medians(&mine, &theirs)?;
    Ok(Breakdown {
        mode,
        by_frame,
        spans,
        whole,
        sleeps: (per_trip(before.0, after.0), per_trip(before.1, after.1)),
        perf: perf.flatten(),
    })
}

/// The median of each span and of the whole round trip, µs, over the
/// frames the client stamped.
fn medians(client: &[Stamp], server: &[Stamp]) -> anyhow::Result<(Vec<f64>, f64)> {
    span_medians(&[("client", client), ("server", server)], &SPANS)
}

/// The median, µs, of each of `spans` and of the whole round trip (the
/// first span's start to the last span's end) over the frames whose every
/// stage of `spans` was stamped; `sets` are the stamps of each process
/// (named for the error), joined by frame id.
pub(crate) fn span_medians(
    sets: &[(&str, &[Stamp])],
    spans: &[(Stage, Stage, &str)],
) -> anyhow::Result<(Vec<f64>, f64)> {
    let mut frames: BTreeMap<u64, [Option<u64>; Stage::ALL.len()]> = BTreeMap::new();
    for (_, stamps) in sets {
        for s in *stamps {
            frames.entry(s.frame).or_default()[s.stage as usize] = Some(s.ns);
        }
    }
    let needed: Vec<usize> = spans
        .iter()
        .flat_map(|(from, to, _)| [*from as usize, *to as usize])
        .collect();
    let complete: Vec<_> = frames
        .values()
        .filter(|stages| needed.iter().all(|&i| stages[i].is_some()))
        .map(|stages| stages.map(|s| s.unwrap_or(0) as i64))
        .collect();
    if complete.is_empty() {
        let counts: Vec<String> = sets
            .iter()
            .map(|(name, stamps)| format!("{} {name}", stamps.len()))
            .collect();
        anyhow::bail!(
            "no round trip has every stage stamped ({} stamps)",
            counts.join(", ")
        );
    }
    let median = |mut v: Vec<i64>| {
        v.sort_unstable();
        v[v.len() / 2] as f64 / 1000.0
    };
    let spans_us = spans
        .iter()
        .map(|(from, to, _)| {
            median(
                complete
                    .iter()
                    .map(|s| s[*to as usize] - s[*from as usize])
                    .collect(),
            )
        })
        .collect();
    let (first, last) = (spans[0].0 as usize, spans[spans.len() - 1].1 as usize);
    let whole = median(complete.iter().map(|s| s[last] - s[first]).collect());
    Ok((spans_us, whole))
}

/// `perf stat` on both sides of the exchange, while it runs.
struct Perf {
    server: Child,
    client: Child,
}

impl Perf {
    /// Starts counting, or None where perf is missing or refuses.
    fn start(server: u32, client: u32) -> Option<Self> {
        let spawn = |pid: u32| {
            Command::new("perf")
                .args(["stat", "-x", ",", "-e"])
                .arg("raw_syscalls:sys_enter,cpu-migrations")
                .args(["-p", &pid.to_string()])
                .stdin(Stdio::null())
                .stdout(Stdio::null())
                .stderr(Stdio::piped())
                .spawn()
                .ok()
        };
        let server = spawn(server)?;
        let client = spawn(client)?;
        // perf has attached once it has read the process's tasks; give it
        // the time a first measurement would (it prints nothing before).
        std::thread::sleep(Duration::from_millis(300));
        Some(Self { server, client })
    }

    /// Stops both and reads their counts, per round trip.
    fn finish(self, n: u64) -> Option<PerfCounts> {
        let read = |child: Child| -> Option<(f64, f64)> {
            let _ = simbus_process::send_signal(child.id(), libc::SIGINT);
            let out = child.wait_with_output().ok()?;
            let text = String::from_utf8_lossy(&out.stderr);
            let count = |event: &str| {
                text.lines()
                    .find(|l| l.contains(event))
                    .and_then(|l| l.split(',').next())
                    .and_then(|v| v.trim().parse::<f64>().ok())
            };
            Some((count("raw_syscalls")?, count("cpu-migrations")?))
        };
        let (server_calls, server_moves) = read(self.server)?;
        let (client_calls, client_moves) = read(self.client)?;
        let n = n as f64;
        Some(PerfCounts {
            server_syscalls: server_calls / n,
            client_syscalls: client_calls / n,
            migrations: (server_moves + client_moves) / n,
        })
    }
}

/// Prints the breakdowns as a table (one column per mode) or JSON.
pub(crate) fn print(
    placement: Placement,
    rows: &[Breakdown],
    n: u64,
    machine: &str,
    json: bool,
) -> serde_json::Value {
    let value = serde_json::json!({
        "placement": placement.name(),
        "round_trips": n,
        "machine": machine,
        "modes": rows.iter().map(|b| serde_json::json!({
            "mode": b.name(),
            "spans_us": SPANS.iter().zip(&b.spans)
                .map(|((_, _, name), us)| (name.to_string(), serde_json::json!(us)))
                .collect::<serde_json::Map<_, _>>(),
            "round_trip_us": b.whole,
            "server_sleeps": b.sleeps.0,
            "client_sleeps": b.sleeps.1,
            "server_syscalls": b.perf.map(|p| p.server_syscalls),
            "client_syscalls": b.perf.map(|p| p.client_syscalls),
            "cpu_migrations": b.perf.map(|p| p.migrations),
        })).collect::<Vec<_>>(),
    });
    if json {
        return value;
    }
    println!(
        "tick round trip by stage, {} ({n} round trips per mode, empty scene), median µs",
        placement.name()
    );
    println!("machine: {machine}");
    let mut head = format!("{:<34}", "stage");
    for b in rows {
        head += &format!(" {:>9}", b.name());
    }
    println!("{head}");
    for (i, (_, _, name)) in SPANS.iter().enumerate() {
        let mut line = format!("{name:<34}");
        for b in rows {
            line += &format!(" {:>9.2}", b.spans[i]);
        }
        println!("{line}");
    }
    let add = |name: &str, value: &dyn Fn(&Breakdown) -> Option<f64>| {
        let mut line = format!("{name:<34}");
        for b in rows {
            match value(b) {
                Some(v) => line += &format!(" {v:>9.2}"),
                None => line += &format!(" {:>9}", "n/a"),
            }
        }
        println!("{line}");
    };
    add("whole round trip", &|b| Some(b.whole));
    add("server sleeps per round trip", &|b| Some(b.sleeps.0));
    add("client sleeps per round trip", &|b| Some(b.sleeps.1));
    add("server syscalls per round trip", &|b| {
        b.perf.map(|p| p.server_syscalls)
    });
    add("client syscalls per round trip", &|b| {
        b.perf.map(|p| p.client_syscalls)
    });
    add("CPU migrations per round trip", &|b| {
        b.perf.map(|p| p.migrations)
    });
    println!();
    value
}
