//! `simbus-bench substeps`: the seeds' three physics-substepping graphs,
//! drawn from simbus's own physics.
//!
//! A ray-cast vehicle on flat ground: it settles for 0.6 s, drives at full
//! throttle for 2 s, then coasts with the throttle released until 4 s (the
//! control changes on frame boundaries common to every frame step).
//! Synchronous, fixed steps, the same start every run; the server's world
//! and substep plan are used as they are, in this process.

use std::path::PathBuf;

use anyhow::Context;
use clap::Args;
use rapier3d::prelude::Vector;
use shared_types::{ActorKind, Command, WorldSettings};
use sim_server::clock::SubstepPlan;
use sim_server::scene::Placement;
use sim_server::world::World;

use crate::plot::{self, Series};

/// Draw the seeds' substep-convergence graphs (PNG + CSV) from simbus's physics
#[derive(Debug, Args)]
pub(crate) struct SubstepsArgs {
    /// Directory for the PNGs and the CSVs behind them
    #[arg(long, default_value = "substeps")]
    out: PathBuf,
    /// Simulated seconds per run
    #[arg(long, default_value_t = 4.0)]
    seconds: f64,
    /// Print one JSON object (the deviation table) instead of the table
    #[arg(long)]
    json: bool,
}

/// When the throttle opens and closes (multiples of every frame step).
const THROTTLE_ON: f64 = 0.6;
const THROTTLE_OFF: f64 = 2.6;

/// One frame of a run.
#[derive(Debug, Clone, Copy)]
pub(crate) struct Sample {
    /// Simulated seconds at the end of the frame.
    pub(crate) t: f64,
    /// The vehicle's speed, m/s.
    pub(crate) speed: f64,
    /// Its vertical velocity, m/s (simbus is Y up: CARLA's z).
    pub(crate) vertical: f64,
    /// Its vertical acceleration over the frame, m/s².
    pub(crate) vertical_acceleration: f64,
}

/// A run's frame step and largest physics step (`max_substep_delta_time`).
#[derive(Debug, Clone, Copy, PartialEq)]
pub(crate) struct Steps {
    pub(crate) frame: f64,
    pub(crate) physics: f64,
}

impl Steps {
    fn name(&self) -> String {
        format!("frame {} s, physics {} s", self.frame, self.physics)
    }
}

/// Runs the vehicle for `seconds` with `steps`.
pub(crate) fn simulate(steps: Steps, seconds: f64) -> anyhow::Result<Vec<Sample>> {
    let settings = WorldSettings {
        synchronous_mode: true,
        fixed_delta_seconds: Some(steps.frame),
        substepping: true,
        max_substep_delta_time: steps.physics,
        max_substeps: 16,
        substep_rule: Default::default(),
    };
    settings
        .validate()
        .map_err(|e| anyhow::anyhow!("{}: {e}", steps.name()))?;
    let ground = Placement {
        kind: ActorKind::Static,
        extent: Vector::new(200.0, 0.5, 200.0),
        position: Vector::new(0.0, -0.5, 0.0),
        rotation: Vector::ZERO,
        linear_velocity: Vector::ZERO,
        density: 1.0,
        signal: None,
    };
    let mut world = World::new(&[ground], 1);
    let vehicle = world
        .apply(&Command::spawn_vehicle([-100.0, 0.8, 0.0]))
        .actor;
    let frame_ns = (steps.frame * 1e9).round() as u64;
    let plan = SubstepPlan::new(frame_ns, &settings);
    let frames = (seconds / steps.frame).round() as u64;
    let mut samples = Vec::new();
    for n in 0..frames {
        let t = n as f64 * steps.frame;
        let throttle = if (THROTTLE_ON - 1e-9..THROTTLE_OFF - 1e-9).contains(&t) {
            1.0
        } else {
            0.0
        };
        world.apply(&Command::vehicle_control(
            vehicle, throttle, 0.0, 0.0, false,
        ));
        world.step(&plan);
        let index = world
            .states()
            .iter()
            .position(|a| a.id == vehicle)
            .context("the vehicle is gone")?;
        let state = world.actor_state(index);
        let v = Vector::from_array(state.linear_velocity);
        samples.push(Sample {
            t: (n + 1) as f64 * steps.frame,
            speed: f64::from(v.length()),
            vertical: f64::from(v.y),
            vertical_acceleration: f64::from(state.acceleration[1]),
        });
    }
    Ok(samples)
}

/// The reference run's sample at time `t` (the reference's frame step
/// divides every other).
fn at(reference: &[Sample], t: f64) -> Option<&Sample> {
    reference.iter().find(|s| (s.t - t).abs() < 1e-6)
}

/// The largest difference in speed between `run` and `reference` at the
/// run's frames.
pub(crate) fn speed_deviation(run: &[Sample], reference: &[Sample]) -> f64 {
    run.iter()
        .filter_map(|s| Some((s.speed - at(reference, s.t)?.speed).abs()))
        .fold(0.0, f64::max)
}

/// The largest difference in vertical acceleration between `run` (frame
/// step `frame`) and the reference's acceleration averaged over the same
/// frames (its velocity change over `frame`).
pub(crate) fn acceleration_deviation(run: &[Sample], reference: &[Sample], frame: f64) -> f64 {
    run.iter()
        .filter_map(|s| {
            let now = at(reference, s.t)?.vertical;
            let before = if s.t - frame < 1e-6 {
                0.0
            } else {
                at(reference, s.t - frame)?.vertical
            };
            Some((s.vertical_acceleration - (now - before) / frame).abs())
        })
        .fold(0.0, f64::max)
}

/// The runs of the seeds' graphs: frame steps with the physics step fixed
/// at 0.01, and physics steps with the frame step fixed at 0.04.
const FRAME_STEPS: [f64; 5] = [0.01, 0.02, 0.04, 0.05, 0.1];
const PHYSICS_STEPS: [f64; 3] = [0.01, 0.02, 0.04];

/// A run: its steps and what it sampled each frame.
type Run = (Steps, Vec<Sample>);

pub(crate) fn run(args: SubstepsArgs) -> anyhow::Result<()> {
    std::fs::create_dir_all(&args.out)
        .with_context(|| format!("creating {}", args.out.display()))?;
    let reference_steps = Steps {
        frame: 0.01,
        physics: 0.01,
    };
    let reference = simulate(reference_steps, args.seconds)?;
    let by_frame: Vec<Run> = FRAME_STEPS
        .iter()
        .map(|&frame| {
            let steps = Steps {
                frame,
                physics: 0.01,
            };
            Ok((steps, simulate(steps, args.seconds)?))
        })
        .collect::<anyhow::Result<_>>()?;
    let by_physics: Vec<Run> = PHYSICS_STEPS
        .iter()
        .map(|&physics| {
            let steps = Steps {
                frame: 0.04,
                physics,
            };
            Ok((steps, simulate(steps, args.seconds)?))
        })
        .collect::<anyhow::Result<_>>()?;
    let written = draw(&args.out, &by_frame, &by_physics)?;

    // Deviation of every curve from the finest run.
    let rows: Vec<(Steps, f64, f64)> = by_frame
        .iter()
        .chain(&by_physics)
        .map(|(steps, samples)| {
            (
                *steps,
                speed_deviation(samples, &reference),
                acceleration_deviation(samples, &reference, steps.frame),
            )
        })
        .collect();
    report(&args, &rows, &written);
    Ok(())
}

/// Draws the three pictures (PNG, and the CSV behind each) into `out`;
/// returns the files written.
fn draw(
    out: &std::path::Path,
    by_frame: &[Run],
    by_physics: &[Run],
) -> anyhow::Result<Vec<PathBuf>> {
    let curves = |runs: &[Run], value: fn(&Sample) -> f64| -> Vec<Series> {
        runs.iter()
            .map(|(steps, samples)| Series {
                name: steps.name(),
                points: samples.iter().map(|s| (s.t, value(s))).collect(),
            })
            .collect()
    };
    let pictures = [
        (
            "velocity_fixed_physics_step",
            "Speed over time, physics step 0.01 s, frame step varied",
            ("time, s", "speed, m/s"),
            curves(by_frame, |s| s.speed),
        ),
        (
            "velocity_fixed_frame_step",
            "Speed over time, frame step 0.04 s, physics step varied",
            ("time, s", "speed, m/s"),
            curves(by_physics, |s| s.speed),
        ),
        (
            "vertical_acceleration",
            "Vertical (CARLA z) acceleration, frame step 0.04 s, physics step varied",
            ("time, s", "acceleration, m/s²"),
            curves(by_physics, |s| s.vertical_acceleration),
        ),
    ];
    let mut written = Vec::new();
    for (stem, title, labels, series) in &pictures {
        let png = out.join(format!("{stem}.png"));
        let csv = out.join(format!("{stem}.csv"));
        plot::lines(&png, title, *labels, series)?;
        plot::csv(
            &csv,
            ("t_seconds", labels.1.split(',').next().unwrap_or("value")),
            series,
        )?;
        written.push(png);
        written.push(csv);
    }
    Ok(written)
}

/// Prints the deviation table and the files written (or, with --json,
/// one object).
fn report(args: &SubstepsArgs, rows: &[(Steps, f64, f64)], written: &[PathBuf]) {
    if args.json {
        let rows: Vec<_> = rows
            .iter()
            .map(|(steps, speed, acceleration)| {
                serde_json::json!({"frame_seconds": steps.frame, "physics_seconds": steps.physics,
                    "max_speed_deviation": speed, "max_vertical_acceleration_deviation": acceleration})
            })
            .collect();
        println!(
            "{}",
            serde_json::json!({"reference": {"frame_seconds": 0.01, "physics_seconds": 0.01},
                "seconds": args.seconds, "deviations": rows,
                "files": written.iter().map(|p| p.display().to_string()).collect::<Vec<_>>()})
        );
        return;
    }
    println!(
        "substepping: ray-cast vehicle, full throttle {THROTTLE_ON}-{THROTTLE_OFF} s, {} s per run; deviation from frame 0.01 s / physics 0.01 s",
        args.seconds
    );
    println!(
        "{:<10} {:>10} {:>20} {:>28}",
        "frame s", "physics s", "max speed dev m/s", "max vertical accel dev m/s²"
    );
    for (steps, speed, acceleration) in rows {
        println!(
            "{:<10} {:>10} {speed:>20.4} {acceleration:>28.3}",
            steps.frame, steps.physics
        );
    }
    for path in written {
        println!("wrote {}", path.display());
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    /// The seeds' result on a short run: with the physics step fixed, the
    /// frame step barely changes the speed; with the physics step as long
    /// as the frame (0.04 s), the speed departs further than at 0.01 s.
    #[test]
    fn substepping_converges_with_the_physics_step_not_the_frame_step() {
        let seconds = 1.6;
        let run = |frame, physics| simulate(Steps { frame, physics }, seconds).expect("a run");
        let reference = run(0.01, 0.01);
        assert!(
            reference.last().expect("frames").speed > 1.0,
            "the vehicle drives"
        );
        for frame in [0.02, 0.04, 0.05] {
            let deviation = speed_deviation(&run(frame, 0.01), &reference);
            assert!(
                deviation < 0.05,
                "frame {frame} s with physics 0.01 s departs {deviation} m/s"
            );
        }
        let fine = speed_deviation(&run(0.04, 0.01), &reference);
        let coarse = speed_deviation(&run(0.04, 0.04), &reference);
        assert!(
            coarse > fine,
            "physics 0.04 s departs {coarse} m/s, 0.01 s {fine} m/s"
        );
    }
}
