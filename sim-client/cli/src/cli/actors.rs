//! `sim-client spawn | destroy | reload | load`: actors and worlds.

use std::time::Duration;

use anyhow::anyhow;
use clap::Args;
use shared_types::limits::MAX_ACTOR_POSITION;
use shared_types::{ActorKind, Command, CommandStatus, WorldName};
use sim_client::{BatchError, CommandError, LoadWorldError};

use crate::cli::failure::Failure;

/// Spawn an actor and print its id.
#[derive(Debug, Args)]
pub(crate) struct SpawnArgs {
    /// box, sphere, capsule, vehicle or walker (radius 0.25 m, 1.8 m tall).
    kind: String,
    /// Where, as x,y,z in metres (Y up).
    #[arg(
        long,
        value_name = "X,Y,Z",
        default_value = "0,5,0",
        allow_hyphen_values = true
    )]
    at: String,
    /// Print {"id": N, "kind": ..., "frame": F}.
    #[arg(long)]
    json: bool,
}

/// Destroy an actor.
#[derive(Debug, Args)]
pub(crate) struct DestroyArgs {
    /// The actor id.
    #[arg(allow_negative_numbers = true)]
    id: u64,
}

/// Reload the current scene as a new episode (frame 0, initial state).
#[derive(Debug, Args)]
pub(crate) struct ReloadArgs {
    /// Also reset the settings to the defaults (async, variable step).
    #[arg(long)]
    reset_settings: bool,
    /// Print {"scene", "episode", "frame", "actors"}.
    #[arg(long)]
    json: bool,
}

/// Load a scene as a new episode.
#[derive(Debug, Args)]
pub(crate) struct LoadArgs {
    /// default, empty, town (roads with 144 spawn points), flat (a 4 km ground) or boxes:N (N in 1..=100000).
    #[arg(value_parser = simbus_input::scene)]
    scene: String,
    /// Also reset the settings to the defaults (async, variable step).
    #[arg(long)]
    reset_settings: bool,
    /// Print {"scene", "episode", "frame", "actors"}.
    #[arg(long)]
    json: bool,
}

/// `--at x,y,z`, within the reach of the world.
fn parse_point(text: &str) -> Result<[f32; 3], Failure> {
    let point = super::parse::numbers::<3>(text, "--at")?;
    if point.iter().any(|v| v.abs() > MAX_ACTOR_POSITION) {
        return Err(Failure::Refused(anyhow!(
            "--at {text} is out of range: positions must be within +-{MAX_ACTOR_POSITION} m of the origin"
        )));
    }
    Ok(point)
}

fn command_failure(e: CommandError) -> Failure {
    match e {
        CommandError::Refused { .. }
        | CommandError::SpawnCollision { .. }
        | CommandError::Batch(BatchError::NotTicker) => Failure::Refused(e.into()),
        e => Failure::Runtime(e.into()),
    }
}

pub(crate) fn spawn(world: &WorldName, timeout: Duration, args: SpawnArgs) -> Result<(), Failure> {
    let at = parse_point(&args.at)?;
    let command = match ActorKind::from_name(&args.kind) {
        Some(ActorKind::Box) => Command::spawn_box(at, [0.5; 3]),
        Some(ActorKind::Sphere) => Command::spawn_sphere(at, 0.5),
        Some(ActorKind::Capsule) => Command::spawn_capsule(at, 0.3, 0.5),
        Some(ActorKind::Vehicle) => Command::spawn_vehicle(at),
        Some(ActorKind::Walker) => Command::spawn_walker(at, 0.25, 0.9),
        _ => {
            return Err(Failure::Refused(anyhow!(
                "unknown actor kind '{}': expected box, sphere, capsule, vehicle or walker",
                args.kind
            )))
        }
    };
    let mut client = super::session::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    let response = client
        .apply_batch_sync(&[command], false)
        .map_err(|e| command_failure(e.into()))?;
    if let Some((i, status)) = response.errors().first() {
        let occupant = response.results.get(*i).map_or(0, |r| r.actor);
        return Err(Failure::Refused(match status {
            CommandStatus::SpawnCollision => anyhow!(
                "{status}: actor {occupant} is there (see `sim-client --world {world} watch`); nothing was spawned"
            ),
            status => anyhow!("spawn refused: {status}"),
        }));
    }
    let Some(result) = response.results.first() else {
        return Err(Failure::Runtime(anyhow!(
            "the server answered the spawn without a result"
        )));
    };
    if args.json {
        println!(
            "{}",
            serde_json::json!({ "id": result.actor, "kind": args.kind, "frame": response.frame })
        );
    } else {
        println!(
            "spawned {} {} at ({}, {}, {}); it appears in frame {}",
            args.kind, result.actor, at[0], at[1], at[2], response.frame
        );
    }
    Ok(())
}

pub(crate) fn destroy(
    world: &WorldName,
    timeout: Duration,
    args: DestroyArgs,
) -> Result<(), Failure> {
    let mut client = super::session::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    client.destroy(args.id).map_err(command_failure)?;
    println!("destroyed actor {}", args.id);
    Ok(())
}

fn loaded(result: Result<sim_client::Status, LoadWorldError>, json: bool) -> Result<(), Failure> {
    match result {
        Ok(report) if json => {
            println!(
                "{}",
                serde_json::json!({"scene": report.scene, "episode": report.episode,
                    "frame": report.frame, "actors": report.actor_count})
            );
            Ok(())
        }
        Ok(report) => {
            println!(
                "loaded {} as episode {} ({}), frame {}",
                report.scene,
                report.episode,
                super::words::count(report.actor_count, "actor"),
                report.frame
            );
            Ok(())
        }
        Err(e @ (LoadWorldError::UnknownScene { .. } | LoadWorldError::TickerHolds { .. })) => {
            Err(Failure::Refused(e.into()))
        }
        Err(e) => Err(Failure::Runtime(e.into())),
    }
}

pub(crate) fn reload(
    world: &WorldName,
    timeout: Duration,
    args: ReloadArgs,
) -> Result<(), Failure> {
    let mut client = super::session::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    loaded(client.reload_world(args.reset_settings), args.json)
}

pub(crate) fn load(world: &WorldName, timeout: Duration, args: LoadArgs) -> Result<(), Failure> {
    let mut client = super::session::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    loaded(
        client.load_world(&args.scene, args.reset_settings),
        args.json,
    )
}
