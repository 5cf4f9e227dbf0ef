//! `simbus-bench walkers`: the server's physics step per walker. N walkers
//! on the flat scene's ground, 2 m apart, each walking its own way at
//! 1.4 m/s (a CARLA pedestrian's walk), stepped in frames of 0.05 s (five
//! physics steps of 0.01 s, the seeds' synchronous settings); beside them,
//! in the same run, the same ground with no walker (the floor). The
//! server's world and substep plan are used as they are, in this process.

use std::time::Instant;

use clap::Args;
use shared_types::{Command, WorldSettings};
use sim_server::clock::SubstepPlan;
use sim_server::world::World;
use sim_server::Scene;

/// Time the physics step of 100 and 1 000 walkers against the empty ground
#[derive(Debug, Args)]
pub(crate) struct WalkersArgs {
    /// How many walkers, comma-separated
    #[arg(long, value_delimiter = ',', default_value = "100,1000")]
    counts: Vec<usize>,
    /// Frames timed per count (after 20 to settle)
    #[arg(long, default_value_t = 200)]
    frames: usize,
    /// Print one JSON object instead of the table
    #[arg(long)]
    json: bool,
}

/// The flat scene with `count` walkers, each walking its own way.
fn world_of(count: usize) -> anyhow::Result<World> {
    let mut world = World::new(&Scene::Flat.placements(0), 1);
    let side = (count as f64).sqrt().ceil() as usize;
    for i in 0..count {
        let (row, column) = (i / side.max(1), i % side.max(1));
        let at = [column as f32 * 2.0, 0.0, row as f32 * 2.0];
        let spawned = world.apply(&Command::spawn_walker(at, 0.25, 0.9));
        anyhow::ensure!(spawned.status == 0, "walker {i} at {at:?} was refused");
        let angle = i as f32 * 2.399_963; // the golden angle: every way once
        let direction = [angle.cos(), 0.0, angle.sin()];
        world.apply(&Command::walker_control(
            spawned.actor,
            direction,
            1.4,
            false,
        ));
    }
    Ok(world)
}

/// Seconds per frame of `world`, over `frames` frames after 20.
fn seconds_per_frame(world: &mut World, plan: &SubstepPlan, frames: usize) -> f64 {
    for _ in 0..20 {
        world.step(plan);
    }
    let started = Instant::now();
    for _ in 0..frames {
        world.step(plan);
    }
    started.elapsed().as_secs_f64() / frames.max(1) as f64
}

pub(crate) fn run(args: WalkersArgs) -> anyhow::Result<()> {
    let settings = WorldSettings {
        fixed_delta_seconds: Some(0.05),
        ..Default::default()
    };
    let plan = SubstepPlan::new(50_000_000, &settings);
    let floor = seconds_per_frame(&mut world_of(0)?, &plan, args.frames);
    let mut rows = Vec::new();
    for &count in &args.counts {
        let frame = seconds_per_frame(&mut world_of(count)?, &plan, args.frames);
        let per_walker = (frame - floor).max(0.0) / count.max(1) as f64;
        rows.push((count, frame, per_walker));
    }
    if args.json {
        let rows: Vec<serde_json::Value> = rows
            .iter()
            .map(|&(count, frame, per_walker)| {
                serde_json::json!({
                    "walkers": count,
                    "frame_ms": frame * 1e3,
                    "per_walker_us": per_walker * 1e6,
                })
            })
            .collect();
        let out = serde_json::json!({
            "substeps_per_frame": plan.count,
            "empty_ground_frame_ms": floor * 1e3,
            "rows": rows,
        });
        println!("{out}");
        return Ok(());
    }
    println!(
        "physics step per frame of 0.05 s ({} substeps), the flat scene's ground",
        plan.count
    );
    println!(
        "{:>8} {:>12} {:>16}",
        "walkers", "frame ms", "per walker µs"
    );
    println!("{:>8} {:>12.3} {:>16}", 0, floor * 1e3, "(the floor)");
    for (count, frame, per_walker) in rows {
        println!(
            "{:>8} {:>12.3} {:>16.2}",
            count,
            frame * 1e3,
            per_walker * 1e6
        );
    }
    Ok(())
}
