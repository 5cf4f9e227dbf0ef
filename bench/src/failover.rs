//! `failover`: how long after a ticker is SIGKILLed the server notices, and
//! how long until a new ticker holds ownership: one that claims after the
//! kill, and a standby ticker queued before it.

use std::time::{Duration, Instant};

use clap::Args;
use sim_client::{Client, TickError};

use crate::stats::Latencies;
use crate::support::spawn_peer;
use crate::support::BenchServer;
use simbus_process::ChildGuard;

#[derive(Debug, Args)]
pub(crate) struct FailoverArgs {
    /// Kills measured per figure.
    #[arg(long, default_value_t = 20)]
    trials: u64,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
}

/// Starts a ticker process and waits until it ticks.
fn start_a_ticker(world: &str) -> anyhow::Result<ChildGuard> {
    let (ticker, ready) = spawn_peer("ticker", world)?;
    anyhow::ensure!(ready == "ready", "the ticker did not start: {ready}");
    Ok(ticker)
}

/// Lets `ticker` tick a while, SIGKILLs it, and returns the instant of the kill.
fn kill(mut ticker: ChildGuard) -> anyhow::Result<Instant> {
    std::thread::sleep(Duration::from_millis(20));
    ticker.kill()?;
    Ok(Instant::now())
}

/// Starts a ticker process, waits until it ticks, SIGKILLs it, and returns
/// the instant of the kill.
fn kill_a_ticker(world: &str) -> anyhow::Result<Instant> {
    kill(start_a_ticker(world)?)
}

/// A standby ticker, its ports open and its claim queued before the kill:
/// when [`sim_client::StandbyTicker::wait`] returns the ticker.
fn standby_takes_over(client: &Client, world: &str, trials: u64) -> anyhow::Result<Latencies> {
    let mut taken = Latencies::new();
    for _ in 0..trials {
        let owner = start_a_ticker(world)?;
        let standby = client.standby_ticker()?;
        anyhow::ensure!(
            standby.owner().is_some(),
            "the standby was not queued behind the ticker"
        );
        let killed = kill(owner)?;
        let ticker = standby.wait(Duration::from_secs(10))?;
        taken.record(killed.elapsed().as_nanos() as u64);
        ticker.release()?;
    }
    Ok(taken)
}

pub(crate) fn run(args: FailoverArgs) -> anyhow::Result<()> {
    let server = BenchServer::start(
        "failover",
        &["--scene", "empty", "--fixed-delta-seconds", "0.01"],
    )?;
    let client = Client::connect(&server.world, Duration::from_secs(10))?;
    let deadline = Duration::from_secs(10);

    // (1) The server's own detection: status shows no ticker.
    let mut noticed = Latencies::new();
    for _ in 0..args.trials {
        let killed = kill_a_ticker(&server.world)?;
        while client.status()?.ticker.is_some() {
            anyhow::ensure!(
                killed.elapsed() < deadline,
                "the dead ticker was never noticed"
            );
            std::thread::sleep(Duration::from_micros(200));
        }
        noticed.record(killed.elapsed().as_nanos() as u64);
    }

    // (2) A new ticker trying right after the kill: when its claim succeeds.
    let mut replaced = Latencies::new();
    for _ in 0..args.trials {
        let killed = kill_a_ticker(&server.world)?;
        let ticker = loop {
            match client.claim_ticker() {
                Ok(ticker) => break ticker,
                Err(TickError::NotTicker { .. }) if killed.elapsed() < deadline => {
                    std::thread::sleep(Duration::from_micros(200));
                }
                Err(e) => return Err(e.into()),
            }
        };
        replaced.record(killed.elapsed().as_nanos() as u64);
        ticker.release()?;
    }

    // (3) The same with a standby ticker waiting.
    let standby = standby_takes_over(&client, &server.world, args.trials)?;

    // The reference: claiming a free world (the new ticker's own setup:
    // its node, ports and the claim round trip).
    let mut free_claim = Latencies::new();
    for _ in 0..args.trials {
        let started = Instant::now();
        let ticker = client.claim_ticker()?;
        free_claim.record(started.elapsed().as_nanos() as u64);
        ticker.release()?;
    }

    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "trials": args.trials,
                "server_notices_dead_ticker": noticed.json(),
                "new_ticker_claims": replaced.json(),
                "standby_ticker_takes_over": standby.json(),
                "claim_of_a_free_world": free_claim.json(),
            })
        );
        return Ok(());
    }
    println!(
        "ticker failover: SIGKILL of the ticker -> ... ({} trials each)",
        args.trials
    );
    println!("{:<28} {:>10} {:>10}", "after the kill", "p50 ms", "max ms");
    println!("{}", noticed.row_ms("server notices (status)"));
    println!("{}", replaced.row_ms("a new ticker holds it"));
    println!("{}", standby.row_ms("a standby holds it"));
    println!("{}", free_claim.row_ms("(claim of a free world)"));
    Ok(())
}
