//! `simbus-bench gym`: environment steps per second of `simbus.gym`'s
//! `VectorEnv` (sync and async, state observations and an 84x84 camera)
//! beside Gymnasium's own `SyncVectorEnv` and `AsyncVectorEnv(shared_memory
//! =True)` over the same single-world env, and highway-env's
//! `highway-fast-v0` alone and vectorised the same ways, and CARLA's own
//! client driving the same task through the gateway, for N worlds, in one
//! run; the reset's p50 and Python's share of a step. The measuring is
//! `gym_bench.py`'s, run in the test suite's venv (highway-env from
//! `bench/requirements-gym.txt`).

use std::path::{Path, PathBuf};
use std::process::Command;

use anyhow::{bail, Context};
use clap::Args;

/// The Python side.
const SCRIPT: &str = include_str!("gym_bench.py");

#[derive(Debug, Args)]
pub(crate) struct GymArgs {
    /// Numbers of worlds, comma-separated.
    #[arg(long, default_value = "1,2,4,8,16")]
    envs: String,
    /// Steps timed per simbus row (Gymnasium's rows half as many).
    #[arg(long, default_value_t = 300)]
    steps: usize,
    /// Steps timed per highway-env row.
    #[arg(long, default_value_t = 40)]
    highway_steps: usize,
    /// Traffic vehicles in each world.
    #[arg(long, default_value_t = 10)]
    vehicles: usize,
    /// The physics substep of the driving worlds, seconds (0.1: one physics
    /// step per 0.1 s step).
    #[arg(long, default_value_t = 0.02)]
    max_substep_delta_time: f64,
    /// Leave highway-env's rows out.
    #[arg(long)]
    skip_highway: bool,
    /// Leave out the row of CARLA's client through the gateway.
    #[arg(long)]
    skip_carla: bool,
    /// A Python with simbus and gymnasium [default: the test suite's venv,
    /// target/simbus-venv; highway-env: `pip install -r
    /// bench/requirements-gym.txt` into it].
    #[arg(long)]
    python: Option<PathBuf>,
    /// Print one JSON object instead of the table.
    #[arg(long)]
    json: bool,
}

pub(crate) fn run(args: GymArgs) -> anyhow::Result<()> {
    let bin_dir = crate::support::sibling("sim-server")?
        .parent()
        .context("the binaries' directory")?
        .to_path_buf();
    let target = bin_dir.parent().context("the target directory")?;
    let python = args
        .python
        .clone()
        .unwrap_or_else(|| target.join("simbus-venv/bin/python"));
    if !imports(&python, "import simbus.gym") {
        bail!(
            "{} cannot import simbus.gym: build the package into it (the test suite does) and \
             pip install -r tests/python/requirements.txt (or --python)",
            python.display()
        );
    }
    if !args.skip_highway && !imports(&python, "import highway_env") {
        bail!(
            "{} has no highway-env: pip install -r bench/requirements-gym.txt into it (or --skip-highway)",
            python.display()
        );
    }
    let script = std::env::temp_dir().join(format!("simbus-gym-bench-{}.py", std::process::id()));
    std::fs::write(&script, SCRIPT)?;
    let mut command = Command::new(&python);
    command
        .arg(&script)
        .args(["--envs", &args.envs])
        .args(["--steps", &args.steps.to_string()])
        .args(["--highway-steps", &args.highway_steps.to_string()])
        .args(["--vehicles", &args.vehicles.to_string()])
        .args([
            "--max-substep-delta-time",
            &args.max_substep_delta_time.to_string(),
        ])
        .env("SIMBUS_BIN_DIR", &bin_dir)
        .env("SDL_VIDEODRIVER", "dummy");
    if args.skip_highway {
        command.arg("--skip-highway");
    }
    if args.skip_carla {
        command.arg("--skip-carla");
    }
    if args.json {
        command.arg("--json");
    }
    let status = command
        .status()
        .with_context(|| format!("running {}", python.display()));
    let _ = std::fs::remove_file(&script);
    if !status?.success() {
        bail!("the gym benchmark failed");
    }
    Ok(())
}

/// Whether `python` runs `code`.
fn imports(python: &Path, code: &str) -> bool {
    Command::new(python)
        .args(["-c", code])
        .stderr(std::process::Stdio::null())
        .status()
        .is_ok_and(|s| s.success())
}
