//! `sim-client snapshot save|restore|list|drop`: whole-world snapshots in
//! the server's memory.

use std::time::Duration;

use clap::{Args, Subcommand};
use shared_types::WorldName;
use sim_client::{SnapshotError, SnapshotId};

use crate::cli::failure::Failure;

/// Options of `sim-client snapshot` (described on the command).
#[derive(Debug, Args)]
pub(crate) struct SnapshotArgs {
    #[command(subcommand)]
    action: Action,

    /// One JSON object per line.
    #[arg(long, global = true)]
    json: bool,
}

#[derive(Debug, Subcommand)]
enum Action {
    /// Save the world as it is after the current frame; prints its id.
    Save,
    /// Restore a snapshot as a new episode (published at once as the next
    /// frame id; the time, actors, ids, sensors and settings are the
    /// snapshot's).
    Restore {
        /// The snapshot's id (`snapshot list`).
        id: u64,
    },
    /// List the snapshots the server holds.
    List,
    /// Forget a snapshot.
    Drop {
        /// The snapshot's id.
        id: u64,
    },
}

/// A refusal is refused input (exit 2): nothing changed.
fn refused(error: SnapshotError) -> Failure {
    match error {
        SnapshotError::Request(e) => Failure::Runtime(e.into()),
        e => Failure::Refused(e.into()),
    }
}

pub(crate) fn run(world: &WorldName, timeout: Duration, args: SnapshotArgs) -> Result<(), Failure> {
    let mut client = super::session::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    match args.action {
        Action::Save => {
            let id = client.save_snapshot().map_err(refused)?;
            let saved = client.snapshots()?.into_iter().find(|s| s.id == id.0);
            let frame = saved.map_or(0, |s| s.frame);
            if args.json {
                println!("{}", serde_json::json!({"id": id.0, "frame": frame}));
            } else {
                println!("snapshot {id} saved at frame {frame}");
            }
        }
        Action::Restore { id } => {
            let frame = client.restore_snapshot(SnapshotId(id)).map_err(refused)?;
            if args.json {
                println!("{}", serde_json::json!({"id": id, "frame": frame}));
            } else {
                println!("snapshot {id} restored as frame {frame}");
            }
        }
        Action::List => {
            let list = client.snapshots()?;
            for s in &list {
                if args.json {
                    println!(
                        "{}",
                        serde_json::json!({
                            "id": s.id,
                            "frame": s.frame,
                            "source_frame": s.source_frame,
                            "episode": s.episode,
                            "elapsed_seconds": shared_types::nanos_to_seconds(s.elapsed_ns),
                            "actors": s.actors,
                            "sensors": s.sensors,
                        })
                    );
                } else {
                    println!(
                        "snapshot {:>3}  frame {:>8}  episode {:>3}  t = {:>12.6} s  {}  {}",
                        s.id,
                        s.frame,
                        s.episode,
                        shared_types::nanos_to_seconds(s.elapsed_ns),
                        super::words::count(u64::from(s.actors), "actor"),
                        super::words::count(u64::from(s.sensors), "sensor"),
                    );
                }
            }
            if list.is_empty() && !args.json {
                println!("no snapshots");
            }
        }
        Action::Drop { id } => {
            client.drop_snapshot(SnapshotId(id)).map_err(refused)?;
            if args.json {
                println!("{}", serde_json::json!({"id": id, "dropped": true}));
            } else {
                println!("snapshot {id} dropped");
            }
        }
    }
    Ok(())
}
