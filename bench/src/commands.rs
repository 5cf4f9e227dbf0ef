//! `commands`: what a batch of 1000 commands costs, against 1000 single
//! commands and against a batch of 1000 spawns (each tested for overlap
//! with every body), and what a lockstep participant adds to the tick
//! round trip.

use std::time::{Duration, Instant};

use clap::Args;
use shared_types::{Command, WorldSettings};
use sim_client::Client;

use crate::stats::{header, Latencies};
use crate::support::spawn_peer;
use crate::support::BenchServer;

#[derive(Debug, Args)]
pub(crate) struct CommandsArgs {
    /// Batches of 1000 measured.
    #[arg(long, default_value_t = 200)]
    batches: u64,
    /// Tick round trips measured per lockstep row.
    #[arg(long, default_value_t = 5000)]
    ticks: u64,
    /// Print one JSON object instead of the tables.
    #[arg(long)]
    json: bool,
}

/// The participant peer: joins the lockstep, then reports every frame done.
pub(crate) fn participant(world: &str) -> anyhow::Result<()> {
    let mut client = Client::connect(world, Duration::from_secs(10))?;
    let participant = client.join_lockstep("bench-participant")?;
    println!("ready");
    loop {
        let snapshot = client.wait_for_tick(Duration::from_secs(30))?;
        participant.done(snapshot.episode(), snapshot.frame())?;
    }
}

fn sync_settings(client: &Client) -> anyhow::Result<WorldSettings> {
    Ok(WorldSettings {
        synchronous_mode: true,
        fixed_delta_seconds: Some(0.01),
        ..client.get_settings()?
    })
}

/// One tick plus receiving its snapshot, `n` times.
fn tick_round_trips(world: &str, n: u64) -> anyhow::Result<Latencies> {
    let mut client = Client::connect(world, Duration::from_secs(10))?;
    let mut ticker = client.claim_ticker()?;
    ticker.apply_settings(sync_settings(&client)?)?;
    while client.wait_for_tick(Duration::from_millis(200)).is_ok() {}
    let timeout = Duration::from_secs(10);
    let mut latencies = Latencies::new();
    latencies.time(n, || {
        let frame = ticker.tick(timeout)?;
        let snapshot = client.wait_for_tick(timeout)?;
        anyhow::ensure!(snapshot.frame() == frame, "snapshot of another frame");
        Ok(())
    })?;
    ticker.release()?;
    Ok(latencies)
}

pub(crate) fn run(args: CommandsArgs) -> anyhow::Result<()> {
    let (batch, singles, spawns) = batches(&args)?;

    // Lockstep: tick round trip without and with one participant.
    let plain = BenchServer::start("lockstep-none", &["--scene", "empty"])?;
    let without = tick_round_trips(&plain.world, args.ticks)?;
    drop(plain);
    let joined = BenchServer::start("lockstep-one", &["--scene", "empty"])?;
    let (_participant, ready) = spawn_peer("participant", &joined.world)?;
    anyhow::ensure!(ready == "ready", "the participant did not start: {ready}");
    let with = tick_round_trips(&joined.world, args.ticks)?;
    let floor = crate::futex::floor(args.ticks, Duration::ZERO)?;
    report(
        &args,
        [&batch, &singles, &spawns],
        Lockstep {
            without: &without,
            with: &with,
            floor: &floor,
        },
    );
    Ok(())
}

/// Batches: 1000 velocity commands on the 1000 boxes of boxes:1000, as
/// one batch and as 1000 single-command batches; and a batch of 1000
/// spawns above those boxes (each spawn tested against every body there,
/// the ones spawned before it in the batch included), destroyed again
/// untimed so that every batch meets the same world.
fn batches(args: &CommandsArgs) -> anyhow::Result<(Latencies, Latencies, Latencies)> {
    let server = BenchServer::start(
        "commands",
        &[
            "--scene",
            "boxes:1000",
            "--sync",
            "--fixed-delta-seconds",
            "0.01",
        ],
    )?;
    let client = Client::connect(&server.world, Duration::from_secs(10))?;
    let commands: Vec<Command> = (2..1002)
        .map(|id| Command::set_target_velocity(id, [0.0, 1.0, 0.0], [0.0; 3]))
        .collect();
    let mut batch = Latencies::new();
    for _ in 0..args.batches {
        let start = Instant::now();
        let response = client.apply_batch_sync(&commands, false)?;
        batch.record(start.elapsed().as_nanos() as u64);
        anyhow::ensure!(
            response.errors().is_empty(),
            "batch failed: {:?}",
            response.errors()
        );
    }
    let mut singles = Latencies::new();
    for _ in 0..(args.batches / 10).max(1) {
        let start = Instant::now();
        for command in &commands {
            client.apply_batch_sync(std::slice::from_ref(command), false)?;
        }
        singles.record(start.elapsed().as_nanos() as u64);
    }
    let grid: Vec<Command> = (0..1000)
        .map(|i| {
            let (x, z) = ((i % 32) as f32 * 3.0 - 48.0, (i / 32) as f32 * 3.0 - 48.0);
            Command::spawn_box([x, 300.0, z], [0.5; 3])
        })
        .collect();
    let mut spawns = Latencies::new();
    for _ in 0..(args.batches / 10).max(1) {
        let start = Instant::now();
        let response = client.apply_batch_sync(&grid, false)?;
        spawns.record(start.elapsed().as_nanos() as u64);
        anyhow::ensure!(
            response.errors().is_empty(),
            "spawns failed: {:?}",
            response.errors()
        );
        let destroy: Vec<Command> = response
            .results
            .iter()
            .map(|r| Command::destroy(r.actor))
            .collect();
        client.apply_batch_sync(&destroy, false)?;
    }
    drop(client);
    drop(server);
    Ok((batch, singles, spawns))
}

/// The lockstep rows: the tick round trip without and with one
/// participant, and a futex round trip for scale.
struct Lockstep<'a> {
    without: &'a Latencies,
    with: &'a Latencies,
    floor: &'a Latencies,
}

/// Prints the tables (or, with --json, one object).
fn report(args: &CommandsArgs, [batch, singles, spawns]: [&Latencies; 3], lockstep: Lockstep<'_>) {
    let Lockstep {
        without,
        with,
        floor,
    } = lockstep;
    let p50 = |l: &Latencies| l.quantile_us(0.5);
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "batch_of_1000": batch.json(),
                "1000_single_commands": singles.json(),
                "singles_over_batch_p50": p50(singles) / p50(batch),
                "batch_of_1000_spawns": spawns.json(),
                "spawns_over_batch_p50": p50(spawns) / p50(batch),
                "tick_without_participant": without.json(),
                "tick_with_one_participant": with.json(),
                "participant_cost_p50_us": p50(with) - p50(without),
                "futex_round_trip": floor.json(),
            })
        );
        return;
    }
    println!("commands: 1000 set_target_velocity on boxes:1000, apply_batch_sync round trip");
    println!("{}", header("how"));
    println!("{}", batch.row("one batch of 1000"));
    println!("{}", singles.row("1000 single-command batches"));
    println!("{}", spawns.row("one batch of 1000 spawns"));
    println!(
        "per command in a batch: {:.2} µs; 1000 singles / one batch at p50: {:.0}x",
        p50(batch) / 1000.0,
        p50(singles) / p50(batch)
    );
    println!(
        "per spawn among 1000-2000 bodies (the overlap test included): {:.2} µs, {:.1}x a velocity command",
        p50(spawns) / 1000.0,
        p50(spawns) / p50(batch)
    );
    println!();
    println!(
        "lockstep: sync tick round trip (tick sent -> snapshot received), blocking, empty scene"
    );
    println!("{}", header("participants"));
    println!("{}", without.row("none"));
    println!("{}", with.row("one (waits, reports done)"));
    println!("{}", floor.row("(a futex round trip)"));
    println!(
        "one participant adds {:.1} µs at p50 ({:.2}x), {:.2} futex round trips",
        p50(with) - p50(without),
        p50(with) / p50(without),
        (p50(with) - p50(without)) / p50(floor)
    );
}
