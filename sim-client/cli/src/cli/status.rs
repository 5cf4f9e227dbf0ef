//! `sim-client status`: mode, settings, current frame.

use std::time::Duration;

use clap::Args;
use shared_types::{Timestamp, WorldName};
use sim_client::{JournalStatus, Status};

use crate::cli::failure::Failure;

/// Show the world's mode, settings and current frame.
#[derive(Debug, Args)]
pub(crate) struct StatusArgs {
    /// Print one JSON object.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(world: &WorldName, timeout: Duration, args: StatusArgs) -> Result<(), Failure> {
    let mut client = super::session::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    let report = client.status()?;
    let settings = report.settings;
    let elapsed = Timestamp {
        elapsed_ns: report.elapsed_ns,
        ..Default::default()
    }
    .elapsed_seconds();
    if args.json {
        let json = status_json(world, &report);
        println!("{json}");
        return Ok(());
    }
    if report.run_pid == report.server_pid {
        println!("world     {world} (server pid {})", report.server_pid);
    } else {
        println!(
            "world     {world} (server pid {}, resumed the run of pid {})",
            report.server_pid, report.run_pid
        );
    }
    println!(
        "scene     {} ({})",
        report.scene,
        super::words::count(report.actor_count, "actor")
    );
    println!(
        "frame     {} (t = {elapsed:.6} s, episode {})",
        report.frame, report.episode
    );
    for (name, value) in super::describe::settings_lines(&settings) {
        println!("{name:<9} {value}");
    }
    match &report.ticker {
        Some(ticker) => println!("ticker    {ticker}"),
        None => println!("ticker    none"),
    }
    println!(
        "lockstep  {}",
        super::words::count(report.participants, "participant")
    );
    for p in &report.lockstep {
        println!("          {}", super::describe::participant_line(p));
    }
    if report.seed != 0 {
        println!("seed      {}", report.seed);
    }
    match &report.journal {
        Some(JournalStatus::Writing { dir, durable_frame }) => {
            println!("journal   {dir} (durable through frame {durable_frame})")
        }
        Some(JournalStatus::Stopped {
            reason,
            durable_frame,
        }) => println!(
            "journal   STOPPED: {reason} (durable through frame {durable_frame}; the world runs on)"
        ),
        None => {}
    }
    if report.snapshots > 0 {
        println!(
            "snapshots {} (`sim-client snapshot list`)",
            report.snapshots
        );
    }
    Ok(())
}

/// The world's status as `status --json` prints it.
pub(crate) fn status_json(world: &WorldName, report: &Status) -> serde_json::Value {
    let mut json = super::describe::settings_json(&report.settings);
    let elapsed = Timestamp {
        elapsed_ns: report.elapsed_ns,
        ..Default::default()
    }
    .elapsed_seconds();
    let extra = serde_json::json!({
        "world": world.as_str(),
        "frame": report.frame,
        "elapsed_seconds": elapsed,
        "episode": report.episode,
        "scene": report.scene,
        "actors": report.actor_count,
        "server_pid": report.server_pid,
        "run_pid": report.run_pid,
        "participants": report.participants,
        "lockstep": report.lockstep.iter().map(super::describe::participant_json).collect::<Vec<_>>(),
        "seed": report.seed,
        "snapshots": report.snapshots,
        "journal": report.journal.as_ref().map(|j| match j {
            JournalStatus::Writing { dir, durable_frame } => serde_json::json!({
                "state": "writing", "dir": dir, "durable_frame": durable_frame,
            }),
            JournalStatus::Stopped { reason, durable_frame } => serde_json::json!({
                "state": "stopped", "reason": reason, "durable_frame": durable_frame,
            }),
        }),
        "ticker": report.ticker.as_ref().map(|t| serde_json::json!({
            "node": t.node_name,
            "pid": t.pid,
            "since_frame": t.since_frame,
        })),
    });
    if let (Some(json), serde_json::Value::Object(extra)) = (json.as_object_mut(), extra) {
        json.extend(extra);
    }
    json
}
