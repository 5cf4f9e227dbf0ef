//! `zenoh --breakdown`: where a tick through the Zenoh bridges spends its
//! time, hop by hop, against Zenoh's own round trip in the same run.
//!
//! The ticker (on the mirror's host), the mirror, the exporter and the
//! server each keep `CLOCK_MONOTONIC` stamps of every tick
//! (`SIMBUS_STAMPS`, `simbus_transport::stamps`); both hosts are this
//! machine (two iceoryx2 roots, Zenoh on loopback), so the stamps share a
//! clock. They are joined by frame id and the median of each hop printed.

use simbus_tests::PrivateRoot;
use simbus_transport::stamps::{self, Stage};

use crate::breakdown::span_medians;
use crate::stats::Latencies;
use crate::zenoh_hosts::{latencies, Host, Launch, Setup};
use crate::zenoh_peer::ZenohFloor;

/// The hops of a mirrored tick, in order.
const HOPS: [(Stage, Stage, &str); 16] = [
    (
        Stage::ClientSend,
        Stage::MirrorTakes,
        "ticker sends -> mirror takes it",
    ),
    (
        Stage::MirrorTakes,
        Stage::MirrorAsked,
        "mirror's Zenoh put of the tick",
    ),
    (
        Stage::MirrorAsked,
        Stage::ExportGets,
        "put -> exporter's callback has it",
    ),
    (
        Stage::ExportGets,
        Stage::ExportSends,
        "callback -> frame thread sends it",
    ),
    (
        Stage::ExportSends,
        Stage::ServerWake,
        "sent -> server wakes",
    ),
    (
        Stage::ServerWake,
        Stage::StepBegin,
        "server wakes -> step begins",
    ),
    (Stage::StepBegin, Stage::StepEnd, "server's physics step"),
    (
        Stage::StepEnd,
        Stage::Published,
        "step ends -> frame published",
    ),
    (
        Stage::Published,
        Stage::Notified,
        "published -> answered and rung",
    ),
    (
        Stage::Notified,
        Stage::ExportTakes,
        "ring -> frame thread takes answer",
    ),
    (
        Stage::ExportTakes,
        Stage::ExportPuts,
        "frame thread's Zenoh put of frame",
    ),
    (
        Stage::ExportPuts,
        Stage::MirrorGets,
        "put -> mirror's callback has it",
    ),
    (
        Stage::MirrorGets,
        Stage::MirrorPublishes,
        "callback -> mirror publishes it",
    ),
    (
        Stage::MirrorPublishes,
        Stage::MirrorAnswers,
        "published -> answer to the ticker",
    ),
    (
        Stage::MirrorAnswers,
        Stage::ClientWake,
        "answer -> ticker wakes",
    ),
    (
        Stage::ClientWake,
        Stage::ClientHolds,
        "ticker wakes -> holds the frame",
    ),
];

/// Measures `ticks` mirrored ticks with every process stamping, then
/// Zenoh's own round trip; prints the hops (or one JSON line).
/// `launch` says how the processes run (its stamps directory is this
/// run's own).
pub(crate) fn run(ticks: u64, launch: Launch<'_>, json: bool, machine: &str) -> anyhow::Result<()> {
    let dir = std::env::temp_dir().join(format!("simbus-zenoh-stamps-{}", std::process::id()));
    std::fs::create_dir_all(&dir)?;
    let (root_a, root_b) = (PrivateRoot::new("bka"), PrivateRoot::new("bkb"));
    let (a, b) = (Host::of_root(&root_a, None), Host::of_root(&root_b, None));
    let launch = Launch {
        stamps: Some(&dir),
        ..launch
    };
    let setup = Setup::start("brk", a, Some(b), "127.0.0.1", launch)?;
    let ticker = dir.join("ticker");
    let measured = setup
        .mirror_host
        .with_env(stamps::SIMBUS_STAMPS, &ticker)
        .measure(
            &setup.world,
            &["--mode", "tick", "--count", &ticks.to_string()],
        )?;
    setup.stop()?;
    let read = |name: &str| stamps::read(&dir.join(name));
    let sets = [
        ("ticker", read("ticker")?),
        ("mirror", read("mirror")?),
        ("exporter", read("exporter")?),
        ("server", read("server")?),
    ];
    let _ = std::fs::remove_dir_all(&dir);
    let named: Vec<(&str, &[stamps::Stamp])> =
        sets.iter().map(|(n, s)| (*n, s.as_slice())).collect();
    let (hops, whole) = span_medians(&named, &HOPS)?;
    let round_trip = latencies(&measured, "round_trip").quantile_us(0.5);
    let mut floor = Latencies::new();
    ZenohFloor::start()?.measure(ticks, &mut floor)?;
    let floor = floor.quantile_us(0.5);
    if json {
        let value = serde_json::json!({
            "machine": machine,
            "ticks": ticks,
            "server_args": launch.server_args,
            "poll_us": launch.poll_us,
            // In the order they happen (a JSON object's keys have none).
            "hops": HOPS.iter().zip(&hops)
                .map(|((_, _, name), us)| serde_json::json!({"hop": name, "median_us": us}))
                .collect::<Vec<_>>(),
            "stamped_round_trip_us": whole,
            "round_trip_p50_us": round_trip,
            "zenoh_round_trip_p50_us": floor,
        });
        println!("{value}");
        return Ok(());
    }
    println!(
        "a tick through the mirror, hop by hop ({ticks} ticks, loopback, server {}, bridges' poll {} µs), median µs",
        launch.server_args.join(" "),
        launch.poll_us
    );
    println!("machine: {machine}");
    for ((_, _, name), us) in HOPS.iter().zip(&hops) {
        println!("{name:<36} {us:>9.2}");
    }
    println!("{:<36} {whole:>9.2}", "whole (stamped)");
    println!("{:<36} {round_trip:>9.2}", "mirror tick round trip, p50");
    println!("{:<36} {floor:>9.2}", "Zenoh's own round trip, p50");
    println!(
        "mirror / Zenoh's own: {:.2}x",
        round_trip / floor.max(f64::EPSILON)
    );
    Ok(())
}
