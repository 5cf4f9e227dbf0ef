//! The `sim-server` command line: the binary's, not the library's (which
//! knows no clap and no anyhow). The benchmarks start this binary itself.

use std::process::ExitCode;
use std::sync::atomic::{AtomicBool, Ordering};
use std::sync::Arc;

use std::time::Duration;

use anyhow::Context;
use clap::Parser;
use shared_types::limits::{self, WorldLimits};
use shared_types::{WaitMode, WorldName, WorldSettings};
use simbus_input as input;
use tracing_subscriber::EnvFilter;

use sim_server::{OnTickerLoss, Scene, Server, ServerConfig, ServerError};

/// Run a simbus world: step a rapier3d physics scene and publish every frame
/// over iceoryx2 shared memory.
///
/// Starts in asynchronous mode. Without --delta-seconds / --fps the step
/// is variable: each frame advances by the wall time since the previous one.
/// With a fixed step the server runs as fast as it can, or at wall-clock speed
/// with --realtime. Stop it with Ctrl-C (or SIGTERM).
#[derive(Debug, Parser)]
#[command(name = "sim-server", version)]
#[command(group = clap::ArgGroup::new("journal_or_resume").args(["journal", "resume"]).multiple(true))]
pub(crate) struct ServerArgs {
    /// World name: prefixes every service, so worlds never meet [default:
    /// default; with --resume: the journal's world].
    #[arg(long, env = "SIMBUS_WORLD")]
    pub(crate) world: Option<WorldName>,

    /// Scene to load: default, empty, town (roads with 144 spawn points), flat (a 4 km ground) or boxes:N (N in 1..=100000).
    #[arg(long, default_value = "default")]
    pub(crate) scene: Scene,

    /// Journal the run into DIR (created if missing; it must hold no
    /// journal yet): frames, commands, episodes, sensors and a keyframe
    /// every --keyframe-seconds, so that after a crash `--resume DIR`
    /// goes on from the last durable frame. Each run writes a segment
    /// DIR/journal-NNNNNN.mcap, an MCAP recording any tool reads.
    #[arg(long, value_name = "DIR")]
    pub(crate) journal: Option<std::path::PathBuf>,

    /// How often the journal is made durable (end the chunk, flush,
    /// fdatasync), before the frame's tick is answered: frames:N, at least
    /// every N frames. A crash then loses at most the frames after the last
    /// sync; with frames:1 never a frame a ticker was told of. Default:
    /// frames:1 in synchronous mode, frames:50 in asynchronous mode.
    #[arg(long, value_name = "frames:N", requires = "journal_or_resume")]
    pub(crate) journal_sync: Option<sim_server::JournalSync>,

    /// Resume the world journaled in DIR after a crash: its last keyframe,
    /// then the journaled commands re-simulated (each frame checked against
    /// the journal) up to the last complete frame, served live from the
    /// next frame with the same world name, actor and sensor ids, episode
    /// and settings. The journal goes on in DIR (a new segment). The
    /// scene, settings and seed are the journal's.
    #[arg(long, value_name = "DIR", conflicts_with_all = ["scene", "fixed_delta_seconds", "fps", "sync", "seed", "no_substepping"])]
    pub(crate) resume: Option<std::path::PathBuf>,

    /// With --resume: fork a new world from journaled frame FRAME (>= 1;
    /// the nearest keyframe before it, then the journaled commands up to
    /// it) instead of the last one; name it with --world. The original
    /// journal is left untouched (journal the fork with --journal NEWDIR).
    /// A world at frame 0 is a fresh server's with the same scene and seed.
    #[arg(long, value_name = "FRAME", requires = "resume", allow_negative_numbers = true, value_parser = input::count)]
    pub(crate) at: Option<u64>,

    /// Fixed time-step in seconds: 1e-6..=3600 (0 = variable step). Also
    /// spelled --fixed-delta-seconds, CARLA's name.
    #[arg(
        long = "delta-seconds",
        visible_alias = "fixed-delta-seconds",
        value_name = "S",
        conflicts_with = "fps",
        allow_negative_numbers = true,
        value_parser = input::fixed_delta_seconds
    )]
    pub(crate) fixed_delta_seconds: Option<f64>,

    /// Fixed time-step as frames per simulated second (dt = 1/N, so N in
    /// 0.000277778..=1e6; 0 = variable).
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = input::fps)]
    pub(crate) fps: Option<f64>,

    /// Run each frame as one physics step, however long.
    #[arg(long)]
    pub(crate) no_substepping: bool,

    /// Longest physics substep in seconds (1e-6..=3600).
    #[arg(long, value_name = "S", default_value_t = 0.01, allow_negative_numbers = true, value_parser = input::max_substep_delta_time)]
    pub(crate) max_substep_delta_time: f64,

    /// Most physics substeps per frame (1..=16).
    #[arg(long, value_name = "N", default_value_t = 10, allow_negative_numbers = true, value_parser = input::max_substeps)]
    pub(crate) max_substeps: u32,

    /// Fixed step: pace frames so simulation time follows wall time.
    #[arg(long)]
    pub(crate) realtime: bool,

    /// Variable step: compute at most this many frames per second (at most
    /// 1e6; 0 = no limit).
    #[arg(long, value_name = "HZ", default_value_t = 100.0, allow_negative_numbers = true, value_parser = input::rate_limit)]
    pub(crate) max_fps: f64,

    /// When the ticker dies in synchronous mode: wait for a new ticker, or
    /// fall back to asynchronous mode.
    #[arg(long, value_enum, default_value_t = TickerLoss::Wait)]
    pub(crate) on_ticker_loss: TickerLoss,

    /// Synchronous mode: how to wait for the next tick — block (sleep on
    /// the wake-up event), spin (poll: lowest latency, one core busy) or
    /// hybrid (poll for --hybrid-window-us after each frame, yielding the
    /// CPU between polls, then sleep). The same words as clients' wait
    /// modes. SIMBUS_STAMPS=FILE keeps the tick path's stamps and writes
    /// them to FILE on exit (`simbus-bench tick --breakdown` reads them).
    #[arg(long, value_name = "MODE", default_value = "hybrid")]
    pub(crate) wait_mode: WaitMode,

    /// Start in synchronous mode, waiting for the first ticker (needs a fixed
    /// step), so a run is deterministic from frame 0.
    #[arg(long)]
    pub(crate) sync: bool,

    /// Seed for the scene's placement: the same seed, the same world
    /// (any whole number in 0..=18446744073709551615).
    #[arg(
        long,
        value_name = "S",
        default_value_t = 0,
        allow_negative_numbers = true
    )]
    pub(crate) seed: u64,

    /// Hybrid waiting: after each frame, poll this many microseconds for the
    /// next tick before sleeping (0..=1000000).
    #[arg(long = "hybrid-window-us", value_name = "US", default_value = "100", allow_negative_numbers = true, value_parser = input::hybrid_window)]
    pub(crate) hybrid_window: Duration,

    /// Drop a lockstep participant that keeps a tick waiting this many
    /// seconds. A tick held up by a participant is told so, and waits for
    /// this long too, whatever its own timeout.
    #[arg(long, value_name = "S", default_value = "10", allow_negative_numbers = true, value_parser = input::timeout)]
    pub(crate) lockstep_timeout: Duration,

    /// Threads that render cameras and lidars, the server's loop thread the
    /// first of them (1..=1024; default: rayon's pool, one per CPU, while
    /// the loop waits). A reader spinning on a capture wants a CPU of its
    /// own: on a machine with N CPUs, `--render-threads N-1` leaves it one
    /// (rendering then takes longer); 1 renders on the loop's thread alone.
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = input::render_threads)]
    pub(crate) render_threads: Option<std::num::NonZeroUsize>,

    /// Simulation seconds between two keyframes of a recording (the
    /// serialized world a replay seeks to): 0.001..=1e9.
    #[arg(long, value_name = "S", default_value = "10", allow_negative_numbers = true, value_parser = input::keyframe_seconds)]
    pub(crate) keyframe_seconds: f64,

    /// How many clients of each kind the world admits: frame subscribers,
    /// control, batch, lockstep and sensor-request clients (each costs
    /// shared memory; see the book's Limits chapter, docs/src/limits.md):
    /// 1..=1024.
    #[arg(long, value_name = "N", default_value_t = limits::DEFAULT_MAX_CLIENTS, allow_negative_numbers = true, value_parser = input::max_clients)]
    pub(crate) max_clients: usize,

    /// How many readers each sensor admits: 1..=256.
    #[arg(long, value_name = "N", default_value_t = limits::DEFAULT_MAX_SENSOR_READERS, allow_negative_numbers = true, value_parser = input::max_sensor_readers)]
    pub(crate) max_sensor_readers: usize,

    /// Exit after computing N frames (N >= 1).
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = input::count)]
    pub(crate) max_frames: Option<u64>,

    /// Print a JSON summary (frames, wall_seconds, fps) on exit.
    #[arg(long)]
    pub(crate) json: bool,

    /// More logging (-v debug, -vv trace); RUST_LOG overrides.
    #[arg(short, long, action = clap::ArgAction::Count)]
    pub(crate) verbose: u8,
}

impl ServerArgs {
    /// The start settings these options describe, validated.
    pub(crate) fn settings(&self) -> anyhow::Result<WorldSettings> {
        let fixed_delta_seconds = match (self.fixed_delta_seconds, self.fps) {
            (_, Some(fps)) => WorldSettings::delta_from_fps(fps)?,
            (dt, None) => dt,
        };
        let settings = WorldSettings {
            synchronous_mode: self.sync,
            fixed_delta_seconds,
            substepping: !self.no_substepping,
            max_substep_delta_time: self.max_substep_delta_time,
            max_substeps: self.max_substeps,
            substep_rule: Default::default(),
        };
        settings.validate()?;
        if self.sync && settings.normalized().fixed_delta_seconds.is_none() {
            anyhow::bail!(
                "--sync needs a fixed step (--fixed-delta-seconds or --fps): in synchronous mode a variable step makes every frame as long as the ticker's wait"
            );
        }
        Ok(settings.normalized())
    }
}

/// The policy when the ticker dies in synchronous mode, as the command
/// line spells it ([`OnTickerLoss`]).
#[derive(Debug, Clone, Copy, PartialEq, Eq, clap::ValueEnum)]
pub(crate) enum TickerLoss {
    /// Stay in synchronous mode and wait for a new ticker.
    Wait,
    /// Fall back to asynchronous mode.
    Async,
}

impl From<TickerLoss> for OnTickerLoss {
    fn from(loss: TickerLoss) -> Self {
        match loss {
            TickerLoss::Wait => Self::Wait,
            TickerLoss::Async => Self::Async,
        }
    }
}

/// Runs a server as `args` say, logging to stderr; a failure is printed
/// and becomes the exit code (2: refused input, 1: failed).
pub(crate) fn main(args: ServerArgs) -> ExitCode {
    init_logging(args.verbose);
    match run(args) {
        Ok(()) => ExitCode::SUCCESS,
        Err(e) => {
            eprintln!("sim-server: {e}");
            ExitCode::from(e.exit_code())
        }
    }
}

/// Why a server run failed: input refused before anything started (exit
/// 2), or a failure while starting or running (exit 1).
#[derive(Debug)]
pub(crate) enum RunError {
    /// Invalid settings or flags; nothing was started.
    Refused(anyhow::Error),
    /// The server could not start or stopped on an error.
    Failed(anyhow::Error),
}

impl RunError {
    /// The process exit code for this failure.
    pub(crate) fn exit_code(&self) -> u8 {
        match self {
            Self::Refused(_) => 2,
            Self::Failed(_) => 1,
        }
    }
}

impl std::fmt::Display for RunError {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        match self {
            Self::Refused(e) => write!(f, "refused: {e:#}"),
            Self::Failed(e) => write!(f, "error: {e:#}"),
        }
    }
}

/// Logs to stderr through `tracing`: `RUST_LOG` if set, else info (-v debug,
/// -vv trace); iceoryx2's own log goes through the same subscriber.
fn init_logging(verbose: u8) {
    iceoryx2::prelude::set_log_level_from_env_or(iceoryx2::prelude::LogLevel::Error);
    let default = match verbose {
        0 => "info",
        1 => "debug",
        _ => "trace",
    };
    let filter = EnvFilter::try_from_default_env().unwrap_or_else(|_| EnvFilter::new(default));
    tracing_subscriber::fmt()
        .with_env_filter(filter)
        .with_writer(std::io::stderr)
        .with_ansi(std::io::IsTerminal::is_terminal(&std::io::stderr()))
        .init();
}

/// Runs a server as the options say, until Ctrl-C / SIGTERM or `--max-frames`.
fn run(args: ServerArgs) -> Result<(), RunError> {
    let settings = args.settings().map_err(RunError::Refused)?;
    let limits = WorldLimits {
        max_clients: args.max_clients,
        max_sensor_readers: args.max_sensor_readers,
    };
    limits
        .validate()
        .map_err(|e| RunError::Refused(anyhow::anyhow!(e)))?;
    let shutdown = Arc::new(AtomicBool::new(false));
    let flag = shutdown.clone();
    ctrlc::set_handler(move || flag.store(true, Ordering::Relaxed))
        .context("installing the SIGINT/SIGTERM handler")
        .map_err(RunError::Failed)?;

    let world = match (&args.world, &args.resume) {
        (Some(world), _) => world.clone(),
        (None, Some(dir)) => journal_world(dir).map_err(RunError::Refused)?,
        (None, None) => WorldName::new("default").map_err(|e| RunError::Refused(e.into()))?,
    };
    if args.at.is_some() && args.world.is_none() {
        return Err(RunError::Refused(anyhow::anyhow!(
            "--at forks a new world: name it with --world NEW"
        )));
    }
    let journal = match (&args.journal, &args.resume, args.at) {
        (Some(dir), _, _) => Some(dir.clone()),
        // A resume goes on journaling where it left off; a fork only when asked.
        (None, Some(dir), None) => Some(dir.clone()),
        _ => None,
    }
    .map(|dir| sim_server::JournalOptions {
        dir,
        sync: args.journal_sync.unwrap_or_default(),
    });
    let config = ServerConfig {
        world: world.clone(),
        journal,
        scene: args.scene,
        settings,
        realtime: args.realtime,
        max_fps: args.max_fps,
        max_frames: args.max_frames,
        on_ticker_loss: args.on_ticker_loss.into(),
        wait_mode: args.wait_mode,
        hybrid_window: args.hybrid_window,
        seed: args.seed,
        lockstep_timeout: args.lockstep_timeout,
        keyframe_seconds: Some(args.keyframe_seconds),
        render_threads: args.render_threads,
        limits,
    };
    // `SIMBUS_STAMPS=FILE`: the tick path's stamps, written on exit
    // (`simbus-bench tick --breakdown` reads them).
    let stamps_file = simbus_transport::stamps::enable_from_env();
    let started = match &args.resume {
        Some(dir) => Server::resume(
            config,
            &sim_server::ResumeOptions {
                dir: dir.clone(),
                at: args.at,
            },
        ),
        None => Server::start(config),
    };
    let mut server = started.map_err(|e| match e {
        ServerError::Settings(_)
        | ServerError::Resume(_)
        | ServerError::OtherWorld { .. }
        | ServerError::ForkIntoOriginal { .. }
        | ServerError::Journal(sim_server::JournalError::NotEmpty { .. }) => {
            RunError::Refused(e.into())
        }
        e => RunError::Failed(e.into()),
    })?;
    let summary = server
        .run(&shutdown)
        .map_err(|e| RunError::Failed(e.into()))?;
    if let Some(path) = stamps_file {
        let stamps = simbus_transport::stamps::take();
        simbus_transport::stamps::write(&path, &stamps)
            .with_context(|| format!("writing the stamps to {}", path.display()))
            .map_err(RunError::Failed)?;
    }
    if args.json {
        println!(
            "{}",
            serde_json::json!({
                "world": world.as_str(),
                "scene": args.scene.to_string(),
                "frames": summary.frames,
                "wall_seconds": summary.wall_seconds,
                "elapsed_seconds": summary.elapsed_seconds,
                "fps": summary.frames_per_second(),
            })
        );
    }
    Ok(())
}

/// The world a journal was written by (its newest segment's header).
fn journal_world(dir: &std::path::Path) -> anyhow::Result<WorldName> {
    let segments = sim_server::journal::segments(dir)
        .with_context(|| format!("reading the journal directory {}", dir.display()))?;
    let newest = segments.iter().rev().find_map(|(_, path)| {
        simbus_recording::RecordingReader::open(&path.to_string_lossy()).ok()
    });
    match newest {
        Some(reader) => Ok(WorldName::new(&reader.header().world)?),
        None => anyhow::bail!(
            "{} holds no readable journal (no journal-NNNNNN.mcap)",
            dir.display()
        ),
    }
}
