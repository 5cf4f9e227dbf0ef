//! `simbus-bench zenoh`: the Zenoh bridge against shared memory and TCP, in
//! one run: tick round trip and frame latency (server publish to reader)
//! for a ticker on the server's host, through a mirror on loopback, through
//! a mirror across a veth pair between two network namespaces (needs root),
//! and CARLA-style TCP loopback; 1 MiB and 8 MiB depth captures across the
//! link; ticks per second a mirror sustains with 1000 actors; and how long
//! after the link drops the server releases a remote ticker's ownership.
//!
//! Every process runs the real binaries (`sim-server` as the
//! server, `sim-client bridge zenoh` as the bridges, `simbus-bench
//! zenoh-peer` as the measuring client), each in its host's iceoryx2 root.

use std::time::{Duration, Instant};

use anyhow::Context as _;
use clap::Args;
use simbus_tests::{PrivateRoot, TwoHosts};

use crate::stats::{header, Latencies};
use crate::support::machine_state;
use crate::zenoh_hosts::{add_latencies, latencies, wait_line, Host, Launch, Setup};
use crate::zenoh_peer::ZenohFloor;

/// Options of `simbus-bench zenoh`.
#[derive(Debug, Args)]
pub(crate) struct ZenohArgs {
    /// Ticks per latency row.
    #[arg(long, default_value_t = 2000)]
    ticks: u64,
    /// Captures per sensor row.
    #[arg(long, default_value_t = 100)]
    captures: u64,
    /// Trials of the ownership release after the link drops (veth only).
    #[arg(long, default_value_t = 3)]
    release_trials: u32,
    /// Skip the veth rows (they need root for `ip netns`).
    #[arg(long)]
    no_veth: bool,
    /// Only the tick round trips and Zenoh's own (no captures, rates or
    /// ownership release).
    #[arg(long)]
    ticks_only: bool,
    /// Where a mirrored tick's time goes: every process stamps each tick
    /// (`SIMBUS_STAMPS`) and the median of each hop is printed, beside
    /// Zenoh's own round trip (loopback only; nothing else is measured).
    #[arg(long)]
    breakdown: bool,
    /// The scene of the tick rows' server: an empty world by default, as
    /// in `tick` (a step of the demo scene, `default`, is ~20 µs of the
    /// world's physics on each tick, not the bridge's).
    #[arg(long, default_value = "empty")]
    scene: String,
    /// The bridges' `--poll-us` (0: they sleep at once).
    #[arg(long, default_value_t = 100)]
    poll_us: u64,
    /// One JSON object instead of tables.
    #[arg(long)]
    json: bool,
}

struct Figures {
    rows: Vec<(String, Latencies, Latencies)>,
    captures: Vec<(String, Latencies)>,
    rates: Vec<(String, f64)>,
    release: Option<Latencies>,
}

pub(crate) fn run(args: ZenohArgs) -> anyhow::Result<()> {
    // The binaries live next to this one (target/<profile>).
    crate::support::sibling("sim-server")?;
    let dir = crate::support::sibling("sim-client")?
        .parent()
        .context("the bench's directory")?
        .to_path_buf();
    std::env::set_var("SIMBUS_BIN_DIR", &dir);
    let state = machine_state(Duration::from_secs(2));
    if args.breakdown {
        let launch = Launch {
            server_args: &["--scene", args.scene.as_str()],
            poll_us: args.poll_us,
            stamps: None,
        };
        return crate::zenoh_breakdown::run(args.ticks, launch, args.json, &state);
    }
    let mut figures = Figures {
        rows: Vec::new(),
        captures: Vec::new(),
        rates: Vec::new(),
        release: None,
    };
    let (root_a, root_b) = (PrivateRoot::new("bza"), PrivateRoot::new("bzb"));
    let (a, b) = (Host::of_root(&root_a, None), Host::of_root(&root_b, None));
    let hosts = if args.no_veth {
        None
    } else {
        Some(TwoHosts::new("bzv"))
    };
    let launch = |server_args| Launch {
        server_args,
        poll_us: args.poll_us,
        stamps: None,
    };
    let scene = ["--scene", args.scene.as_str()];
    let setups = start_setups("", (&a, &b), hosts.as_ref(), launch(&scene))?;
    tick_rows(&args, &setups, &mut figures)?;
    drop(setups);
    if args.ticks_only {
        report(&args, &state, &figures);
        return Ok(());
    }
    // The captures see the demo scene.
    let capture_setups = start_setups("c", (&a, &b), hosts.as_ref(), launch(&[]))?;
    capture_rows(&args, &capture_setups, &mut figures)?;
    drop(capture_setups);
    // 1000 actors: ticks per second a ticker sustains here and through mirrors.
    let rate_setups = start_setups(
        "r",
        (&a, &b),
        hosts.as_ref(),
        launch(&["--scene", "boxes:1000"]),
    )?;
    for (name, setup) in &rate_setups {
        let json = setup
            .mirror_host
            .measure(&setup.world, &["--mode", "rate", "--count", "500"])?;
        figures.rates.push((
            name.to_string(),
            json["ticks_per_second"].as_f64().unwrap_or(0.0),
        ));
    }
    drop(rate_setups);
    if let Some(hosts) = &hosts {
        figures.release = Some(release_bound(hosts, args.release_trials, args.poll_us)?);
    }
    report(&args, &state, &figures);
    Ok(())
}

/// A server with its measuring client here, through a mirror on loopback,
/// and through a mirror across the veth pair (when there is one); `tag`
/// keeps their worlds apart from another set's.
fn start_setups(
    tag: &str,
    (a, b): (&Host, &Host),
    hosts: Option<&TwoHosts>,
    launch: Launch<'_>,
) -> anyhow::Result<Vec<(&'static str, Setup)>> {
    let mut setups = vec![
        (
            "local (shared memory)",
            Setup::start(&format!("{tag}local"), a.clone(), None, "127.0.0.1", launch)?,
        ),
        (
            "mirror, loopback",
            Setup::start(
                &format!("{tag}loop"),
                a.clone(),
                Some(b.clone()),
                "127.0.0.1",
                launch,
            )?,
        ),
    ];
    if let Some(hosts) = hosts {
        let (va, vb) = (
            Host::of_root(&hosts.a.root, Some(hosts.a.namespace())),
            Host::of_root(&hosts.b.root, Some(hosts.b.namespace())),
        );
        setups.push((
            "mirror, veth",
            Setup::start(
                &format!("{tag}veth"),
                va,
                Some(vb),
                hosts.a.address(),
                launch,
            )?,
        ));
    }
    Ok(setups)
}

/// How many slices each tick row is cut into: the rows take turns, slice
/// by slice, so that all of them see the same machine (this VM's speed
/// changes within a minute).
const ROUNDS: u64 = 10;

/// The tick round trip (and frame latency) of every setup, TCP's and
/// Zenoh's own round trips, interleaved: [`ROUNDS`] rounds, each row a
/// slice of its ticks in each.
fn tick_rows(
    args: &ZenohArgs,
    setups: &[(&str, Setup)],
    figures: &mut Figures,
) -> anyhow::Result<()> {
    let slice = (args.ticks / ROUNDS).max(1);
    let count = slice.to_string();
    let mut rows: Vec<(String, Latencies, Latencies)> = setups
        .iter()
        .map(|(name, _)| (name.to_string(), Latencies::new(), Latencies::new()))
        .collect();
    let (_tcp_peer, mut tcp_exchange) = crate::baselines::tcp_exchange()?;
    let (mut tcp, mut zenoh) = (Latencies::new(), Latencies::new());
    let mut floor = ZenohFloor::start()?;
    for round in 0..ROUNDS {
        for ((_, setup), (_, round_trips, frames)) in setups.iter().zip(rows.iter_mut()) {
            let json = setup
                .mirror_host
                .measure(&setup.world, &["--mode", "tick", "--count", &count])?;
            add_latencies(&json, "round_trip", round_trips);
            add_latencies(&json, "frame", frames);
        }
        tcp.time(slice, &mut tcp_exchange)?;
        floor.measure(slice, &mut zenoh)?;
        eprintln!("zenoh: round {} of {ROUNDS} done", round + 1);
    }
    figures.rows.extend(rows);
    figures
        .rows
        .push(("TCP loopback (CARLA-style)".into(), tcp, Latencies::new()));
    figures
        .rows
        .push(("Zenoh put/echo, loopback".into(), zenoh, Latencies::new()));
    Ok(())
}

/// 1 MiB and 8 MiB depth captures through each mirror.
fn capture_rows(
    args: &ZenohArgs,
    setups: &[(&str, Setup)],
    figures: &mut Figures,
) -> anyhow::Result<()> {
    let captures = args.captures.to_string();
    for (name, setup) in setups.iter().skip(1) {
        for (label, size) in [("1 MiB", ["512", "512"]), ("8 MiB", ["2048", "1024"])] {
            let json = setup.mirror_host.measure(
                &setup.world,
                &[
                    "--mode", "depth", "--count", &captures, "--size", size[0], size[1],
                ],
            )?;
            figures
                .captures
                .push((format!("{label}, {name}"), latencies(&json, "capture")));
        }
    }
    Ok(())
}

/// Link down under a remote ticker, until the server's status names no
/// ticker (polled with `sim-client status`, ~10 ms resolution).
fn release_bound(hosts: &TwoHosts, trials: u32, poll_us: u64) -> anyhow::Result<Latencies> {
    let (va, vb) = (
        Host::of_root(&hosts.a.root, Some(hosts.a.namespace())),
        Host::of_root(&hosts.b.root, Some(hosts.b.namespace())),
    );
    let mut bound = Latencies::new();
    for trial in 0..trials {
        let setup = Setup::start(
            &format!("rel{trial}"),
            va.clone(),
            Some(vb.clone()),
            hosts.a.address(),
            Launch {
                server_args: &[],
                poll_us,
                stamps: None,
            },
        )?;
        let holder = setup.mirror_host.spawn(
            "sim-client",
            &[
                "--world",
                &setup.world,
                "--timeout",
                "10",
                "tick",
                "--rate",
                "50",
                "--leave-sync",
            ],
        );
        wait_line(&holder, "frame")?;
        let down = Instant::now();
        hosts.b.set_link(false);
        loop {
            let status = setup
                .server_host
                .spawn("sim-client", &["--world", &setup.world, "status", "--json"])
                .finish(Duration::from_secs(30));
            let held = status
                .json()
                .first()
                .is_some_and(|s| !s["ticker"].is_null());
            if !held {
                break;
            }
            anyhow::ensure!(
                down.elapsed() < Duration::from_secs(30),
                "ownership never released"
            );
        }
        bound.record(down.elapsed().as_nanos() as u64);
        hosts.b.set_link(true);
        drop(holder);
    }
    Ok(bound)
}

fn report(args: &ZenohArgs, state: &str, figures: &Figures) {
    let p50 = |l: &Latencies| l.quantile_us(0.5);
    if args.json {
        let json = serde_json::json!({
            "machine": state,
            "scene": args.scene,
            "poll_us": args.poll_us,
            "ticks": figures.rows.iter().map(|(n, rt, f)| serde_json::json!({"path": n, "round_trip": rt.json(), "frame": f.json()})).collect::<Vec<_>>(),
            "captures": figures.captures.iter().map(|(n, l)| serde_json::json!({"row": n, "latency": l.json()})).collect::<Vec<_>>(),
            "ticks_per_second_1000_actors": figures.rates.iter().map(|(n, r)| serde_json::json!({"path": n, "rate": r})).collect::<Vec<_>>(),
            "ownership_release_ms": figures.release.as_ref().map(|l| serde_json::json!({"p50": l.quantile_us(0.5) / 1e3, "max": l.quantile_us(1.0) / 1e3})),
        });
        println!("{json}");
        return;
    }
    println!("machine: {state}");
    println!("\ntick round trip, µs ({} ticks per row)", args.ticks);
    println!("{}", header("path"));
    for (name, round_trip, _) in &figures.rows {
        println!("{}", round_trip.row(name));
    }
    println!("\nframe latency, server publish to reader, µs");
    println!("{}", header("path"));
    for (name, _, frame) in figures.rows.iter().filter(|(_, _, f)| f.len() > 0) {
        println!("{}", frame.row(name));
    }
    if let (Some(local), Some(tcp)) = (
        figures.rows.first(),
        figures.rows.iter().find(|r| r.0.starts_with("TCP")),
    ) {
        let floor = figures.rows.iter().find(|r| r.0.starts_with("Zenoh"));
        for (name, round_trip, _) in figures.rows.iter().filter(|r| r.0.starts_with("mirror")) {
            println!(
                "{name}: {:.1}x the local round trip, {:.2}x TCP loopback's, {:.2}x Zenoh's own round trip",
                p50(round_trip) / p50(&local.1),
                p50(round_trip) / p50(&tcp.1),
                floor.map_or(f64::NAN, |f| p50(round_trip) / p50(&f.1)),
            );
        }
    }
    println!(
        "\ndepth capture latency across the link, µs ({} captures per row)",
        args.captures
    );
    println!("{}", header("row"));
    for (name, latency) in &figures.captures {
        println!("{}", latency.row(name));
    }
    println!(
        "\nticks per second with 1000 actors (frame {} KiB)",
        (96 + 96 * 1001) / 1024
    );
    for (name, rate) in &figures.rates {
        println!("{name:<28} {rate:>10.0}");
    }
    if let Some(release) = &figures.release {
        println!("\nownership released after the link drops (lease 1000 ms), ms");
        println!("{}", release.row_ms("veth link down"));
    }
}
