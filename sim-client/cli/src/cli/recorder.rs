//! `sim-client recorder …` and `sim-client replay …`: CARLA's recorder API
//! on the command line. `info`, `collisions` and `blocked` read the file
//! directly (no server needed); the rest ask the world's server.

use std::path::PathBuf;
use std::time::{Duration, Instant};

use anyhow::anyhow;
use clap::{Args, Subcommand};
use indicatif::{ProgressBar, ProgressStyle};
use shared_types::{ReplayMode, ReplayState, WorldName};
use sim_client::{Client, RecorderError, RecorderStatus, ReplayOptions};
use simbus_input as input;
use simbus_recording::inspect;

use crate::cli::failure::Failure;
use crate::cli::words::count;

mod print;

/// Record the world into an MCAP file, or inspect a recording.
#[derive(Debug, Args)]
pub(crate) struct RecorderArgs {
    #[command(subcommand)]
    command: RecorderCommand,
}

#[derive(Debug, Subcommand)]
enum RecorderCommand {
    /// Start recording the world into FILE (created by the server).
    ///
    /// Every frame, applied command, spawn and destroy, settings change,
    /// episode, collision and keyframe is recorded, none dropped; with
    /// --sensors every sensor capture too.
    Start {
        /// The MCAP file to write.
        file: PathBuf,
        /// Record every sensor capture as well.
        #[arg(long)]
        sensors: bool,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Stop recording; prints the frames and bytes written and the path.
    Stop {
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// How the recorder and the replayer are doing.
    Status {
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
    },
    /// Set the running replay's time factor (CARLA's set_replayer_time_factor).
    TimeFactor {
        /// Simulation speed relative to the recording, 0.001..=1000.
        #[arg(allow_negative_numbers = true, value_parser = input::time_factor)]
        factor: f64,
    },
    /// Stop the running replay (CARLA's stop_replayer).
    StopReplay {
        /// Keep the replayed world live (else the world from before comes back).
        #[arg(long)]
        keep_actors: bool,
    },
    /// What a recording holds: versions, world, scene, seed, settings,
    /// frames, duration, actors, sensors, size and compression.
    Info {
        /// The recording.
        file: String,
        /// List every frame too.
        #[arg(long)]
        all: bool,
        /// Print one JSON object.
        #[arg(long)]
        json: bool,
        /// Print CARLA's text instead (its show_recorder_file_info layout:
        /// Version, Map, Date, frames with events, Frames, Duration).
        #[arg(long, conflicts_with = "json")]
        carla_text: bool,
    },
    /// The collisions in a recording (contacts that started), in order.
    Collisions {
        /// The recording.
        file: String,
        /// Category of one actor: a any, v vehicle, b box, s sphere, c capsule, x static.
        #[arg(long, default_value = "a")]
        kind1: char,
        /// Category of the other.
        #[arg(long, default_value = "a")]
        kind2: char,
        /// Print one JSON array.
        #[arg(long)]
        json: bool,
    },
    /// Actors that moved less than --min-distance for at least --min-time:
    /// each such actor once, with every stretch it stayed (nearly) still.
    Blocked {
        /// The recording.
        file: String,
        /// Seconds an actor must stay (nearly) still: finite, 0..=18446744073.
        #[arg(long, default_value = "30", allow_negative_numbers = true, value_parser = input::sim_time)]
        min_time: f64,
        /// Metres it may move meanwhile: positive, finite.
        #[arg(long, default_value = "0.1", allow_negative_numbers = true, value_parser = input::metres)]
        min_distance: f64,
        /// Print one JSON array: an object per actor with its stretches.
        #[arg(long)]
        json: bool,
    },
}

/// Replay a recording into the world.
///
/// In synchronous mode the replay starts with the next tick and advances
/// one recorded frame per tick; in asynchronous mode it runs at the
/// recording's pace times --time-factor. Every client sees ordinary frames
/// (flagged as a replay) of a new episode. The command follows the replay
/// to its end (a progress bar on a terminal); Ctrl-C stops it.
#[derive(Debug, Args)]
pub(crate) struct ReplayArgs {
    /// The recording (an MCAP file the server can read).
    file: PathBuf,
    /// Seconds from the recording's start (negative: from its end).
    #[arg(long, default_value = "0", allow_negative_numbers = true, value_parser = input::sim_offset)]
    start: f64,
    /// Seconds to replay, 0..=18446744073 (0: to the end).
    #[arg(long, default_value = "0", allow_negative_numbers = true, value_parser = input::sim_time)]
    duration: f64,
    /// Sensors spawned without a parent during the replay ride on this recorded actor.
    #[arg(
        long,
        value_name = "ID",
        default_value = "0",
        allow_negative_numbers = true
    )]
    follow: u64,
    /// Spawn the recorded sensors again; they capture the replayed scene.
    #[arg(long)]
    replay_sensors: bool,
    /// Speed relative to the recording, 0.001..=1000 (asynchronous mode).
    #[arg(long, default_value = "1", allow_negative_numbers = true, value_parser = input::time_factor)]
    time_factor: f64,
    /// exact: recorded deltas and states; interpolate: the server's own
    /// step, states interpolated; resimulate: recorded commands on real
    /// physics, compared frame by frame [default: exact for fixed-step
    /// recordings, interpolate otherwise].
    #[arg(long)]
    mode: Option<ReplayMode>,
    /// With resimulate: print `identical: N frames` or the first frame and
    /// actor that differ (exit 1).
    #[arg(long)]
    verify: bool,
    /// Keep the replayed world live when the replay ends.
    #[arg(long)]
    keep_actors: bool,
    /// Start the replay and return at once.
    #[arg(long)]
    detach: bool,
    /// Print one JSON object at the end.
    #[arg(long)]
    json: bool,
}

fn refused_or_runtime(e: RecorderError) -> Failure {
    match e {
        RecorderError::Request(e) => Failure::Runtime(e.into()),
        e => Failure::Refused(e.into()),
    }
}

fn connect(world: &WorldName, timeout: Duration) -> Result<Client, Failure> {
    let mut client = super::session::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    Ok(client)
}

fn print_json(value: &impl serde::Serialize) {
    println!("{}", serde_json::to_string(value).unwrap_or_default());
}

pub(crate) fn run(world: &WorldName, timeout: Duration, args: RecorderArgs) -> Result<(), Failure> {
    match args.command {
        RecorderCommand::Start {
            file,
            sensors,
            json,
        } => start(world, timeout, &file, sensors, json),
        RecorderCommand::Stop { json } => stop(world, timeout, json),
        RecorderCommand::Status { json } => status(world, timeout, json),
        RecorderCommand::TimeFactor { factor } => time_factor(world, timeout, factor),
        RecorderCommand::StopReplay { keep_actors } => stop_replay(world, timeout, keep_actors),
        RecorderCommand::Info {
            file,
            all,
            json,
            carla_text,
        } => {
            if carla_text {
                carla_info(&file, all)
            } else {
                info(&file, all, json)
            }
        }
        RecorderCommand::Collisions {
            file,
            kind1,
            kind2,
            json,
        } => collisions(&file, kind1, kind2, json),
        RecorderCommand::Blocked {
            file,
            min_time,
            min_distance,
            json,
        } => blocked(&file, min_time, min_distance, json),
    }
}

/// `recorder start`: the server creates FILE and records into it.
fn start(
    world: &WorldName,
    timeout: Duration,
    file: &std::path::Path,
    sensors: bool,
    json: bool,
) -> Result<(), Failure> {
    let client = connect(world, timeout)?;
    let path = client
        .start_recorder(file, sensors)
        .map_err(refused_or_runtime)?;
    if json {
        print_json(&serde_json::json!({"recording": true, "path": path, "sensors": sensors}));
    } else {
        println!(
            "recording world '{world}' into {}{}",
            path.display(),
            if sensors {
                " (with sensor captures)"
            } else {
                ""
            }
        );
    }
    Ok(())
}

/// `recorder stop`: what was written, and where.
fn stop(world: &WorldName, timeout: Duration, json: bool) -> Result<(), Failure> {
    let client = connect(world, timeout)?;
    let status = client.stop_recorder().map_err(refused_or_runtime)?;
    if json {
        print_json(&status);
    } else {
        println!(
            "recording stopped: {}, {}, {}",
            count(status.frames, "frame"),
            count(status.bytes, "byte"),
            status.path
        );
        if !status.message.is_empty() {
            println!("warning: {}", status.message);
        }
    }
    Ok(())
}

/// `recorder status`: the recorder and the replayer.
fn status(world: &WorldName, timeout: Duration, json: bool) -> Result<(), Failure> {
    let client = connect(world, timeout)?;
    let status = client.recorder_status().map_err(refused_or_runtime)?;
    if json {
        print_json(&status);
    } else {
        print::status(&status);
    }
    Ok(())
}

/// `recorder time-factor`: the running replay's speed.
fn time_factor(world: &WorldName, timeout: Duration, factor: f64) -> Result<(), Failure> {
    let client = connect(world, timeout)?;
    client
        .set_replayer_time_factor(factor)
        .map_err(refused_or_runtime)?;
    println!("replay time factor {factor}");
    Ok(())
}

/// `recorder stop-replay`: how far the replay got.
fn stop_replay(world: &WorldName, timeout: Duration, keep_actors: bool) -> Result<(), Failure> {
    let client = connect(world, timeout)?;
    let status = client
        .stop_replayer(keep_actors)
        .map_err(refused_or_runtime)?;
    println!(
        "replay stopped after {} of {}{}",
        status.replay.frames,
        count(status.replay.total, "frame"),
        if keep_actors {
            "; the replayed world goes on live"
        } else {
            ""
        }
    );
    Ok(())
}

/// A recording that cannot be read is refused; with --json a script gets
/// the error as data too (and exit 2).
fn file_error(json: bool) -> impl Fn(simbus_recording::RecordingError) -> Failure {
    move |e| {
        if json {
            print_json(&serde_json::json!({"error": e.code(), "message": e.to_string()}));
        }
        Failure::Refused(e.into())
    }
}

/// `recorder info`: what the file holds.
fn info(file: &str, all: bool, json: bool) -> Result<(), Failure> {
    let info = inspect::file_info(file, all).map_err(file_error(json))?;
    if json {
        print_json(&info);
    } else {
        print::info(&info);
    }
    Ok(())
}

/// `recorder info --carla-text`: what the file holds, in the text CARLA's
/// server answers to `show_recorder_file_info`.
#[cfg(feature = "carla")]
fn carla_info(file: &str, all: bool) -> Result<(), Failure> {
    let text = simbus_carla::recorder_text::file_info(file, all).map_err(file_error(false))?;
    print!("{text}");
    Ok(())
}

/// `recorder info --carla-text` in a build without the CARLA gateway.
#[cfg(not(feature = "carla"))]
fn carla_info(_: &str, _: bool) -> Result<(), Failure> {
    Err(Failure::Refused(anyhow!(
        "--carla-text needs a sim-client built with the `carla` feature"
    )))
}

/// `recorder collisions`: the contacts that started between two categories.
fn collisions(file: &str, kind1: char, kind2: char, json: bool) -> Result<(), Failure> {
    for kind in [kind1, kind2] {
        if !"avwtbscx".contains(kind) {
            return Err(Failure::Refused(anyhow!(
                "unknown category '{kind}': use a (any), v (vehicle), w (walker), t (traffic light), \
                 b (box), s (sphere), c (capsule) or x (static)"
            )));
        }
    }
    let list = inspect::collisions(file, kind1, kind2).map_err(file_error(json))?;
    if json {
        print_json(&list);
    } else {
        print::collisions(&list);
    }
    Ok(())
}

/// `recorder blocked`: the actors that stayed (nearly) still.
fn blocked(file: &str, min_time: f64, min_distance: f64, json: bool) -> Result<(), Failure> {
    let list = inspect::actors_blocked(file, min_time, min_distance).map_err(|e| match e {
        inspect::BlockedError::File(e) => file_error(json)(e),
        e => Failure::Refused(e.into()),
    })?;
    if json {
        print_json(&list);
    } else {
        print::blocked(&list, min_time, min_distance);
    }
    Ok(())
}

pub(crate) fn replay(
    world: &WorldName,
    timeout: Duration,
    args: ReplayArgs,
) -> Result<(), Failure> {
    if args.verify && args.mode != Some(ReplayMode::Resimulate) {
        return Err(Failure::Refused(anyhow!(
            "--verify needs --mode resimulate"
        )));
    }
    let client = connect(world, timeout)?;
    if !args.detach {
        refuse_unticked(world, &client)?;
    }
    let started = client
        .replay(&args.file, &replay_options(&args))
        .map_err(refused_or_runtime)?;
    // From here a replay this command follows is stopped however the
    // command ends early (a closed stdout, an error, giving up); --detach
    // leaves it running on purpose.
    let mut following = Following {
        client: &client,
        keep_actors: args.keep_actors,
        armed: !args.detach,
    };
    let synchronous = client
        .get_settings()
        .map(|s| s.synchronous_mode)
        .unwrap_or(false);
    if !args.json {
        println!(
            "replaying {} ({}, {}){}",
            args.file.display(),
            count(started.replay.total, "frame"),
            started.replay.mode,
            if synchronous {
                "; synchronous mode: it advances one frame per tick"
            } else {
                ""
            }
        );
    }
    if args.detach {
        // The replay as it starts; `recorder status --json` follows it.
        if args.json {
            print_json(&started);
        }
        return Ok(());
    }
    let bar = (!args.json && std::io::IsTerminal::is_terminal(&std::io::stdout()))
        .then(|| progress_bar(started.replay.total));
    let Some(status) = follow(
        &mut following,
        &args,
        timeout,
        synchronous,
        started.replay.frames,
        bar.as_ref(),
    )?
    else {
        return Ok(());
    };
    // It ended by itself: nothing to stop.
    following.armed = false;
    if let Some(bar) = &bar {
        bar.finish_and_clear();
    }
    replay_ended(&args, &status)
}

/// A synchronous replay advances one frame per tick: following one that
/// nobody ticks would wait for nothing. Nothing has changed yet.
fn refuse_unticked(world: &WorldName, client: &Client) -> Result<(), Failure> {
    let status = client.status()?;
    if status.settings.synchronous_mode && status.ticker.is_none() {
        return Err(Failure::Runtime(anyhow!(
            "world '{world}' is in synchronous mode and nobody ticks it: a replay there advances one recorded frame per tick; start a ticker first (`sim-client tick`), or start the replay with --detach and tick it yourself"
        )));
    }
    Ok(())
}

fn replay_options(args: &ReplayArgs) -> ReplayOptions {
    ReplayOptions {
        start: args.start,
        duration: args.duration,
        follow_id: args.follow,
        replay_sensors: args.replay_sensors,
        time_factor: args.time_factor,
        mode: args.mode,
        keep_actors: args.keep_actors,
    }
}

fn progress_bar(total: u64) -> ProgressBar {
    let bar = ProgressBar::new(total);
    bar.set_style(
        ProgressStyle::with_template("{bar:30} {pos}/{len} frames  {msg}").expect("valid template"),
    );
    bar
}

/// Follows the replay until it ends (its last status) or Ctrl-C stops it
/// (`None`, its answer printed); no progress for `timeout` is an error.
fn follow(
    following: &mut Following<'_>,
    args: &ReplayArgs,
    timeout: Duration,
    synchronous: bool,
    frames: u64,
    bar: Option<&ProgressBar>,
) -> Result<Option<RecorderStatus>, Failure> {
    let client = following.client;
    let mut last = (frames, Instant::now());
    loop {
        if super::interrupt::interrupted().load(std::sync::atomic::Ordering::Relaxed) {
            following.armed = false; // stopped here, with its answer printed
            let status = client
                .stop_replayer(args.keep_actors)
                .map_err(refused_or_runtime)?;
            if let Some(bar) = bar {
                bar.abandon();
            }
            println!(
                "replay stopped after {}",
                count(status.replay.frames, "frame")
            );
            return Ok(None);
        }
        let status = client.recorder_status().map_err(refused_or_runtime)?;
        if let Some(bar) = bar {
            bar.set_position(status.replay.frames);
        }
        if status.replay.replay_state() != ReplayState::Running {
            return Ok(Some(status));
        }
        if status.replay.frames != last.0 {
            last = (status.replay.frames, Instant::now());
        } else if last.1.elapsed() > timeout {
            return Err(Failure::Runtime(anyhow!(
                "the replay made no progress for {timeout:?}{}; stopped it",
                if synchronous {
                    " (synchronous mode: is the ticker ticking?)"
                } else {
                    ""
                }
            )));
        }
        std::thread::sleep(Duration::from_millis(20));
    }
}

/// Prints how the replay ended (and, with --verify, how it compared); a
/// failed replay or a re-simulation that differs is an error.
fn replay_ended(args: &ReplayArgs, status: &RecorderStatus) -> Result<(), Failure> {
    let r = &status.replay;
    if args.json {
        print_json(status);
    } else {
        println!(
            "replay {}: {} of {}",
            r.state,
            r.frames,
            count(r.total, "frame")
        );
        if args.verify {
            match r.mismatch {
                None => println!("identical: {}", count(r.verified, "frame")),
                Some(m) => println!(
                    "differs: frame {} (actor {}) is not the recorded one; {} before it {} identical",
                    m.frame,
                    m.actor,
                    count(r.verified, "frame"),
                    if r.verified == 1 { "was" } else { "were" }
                ),
            }
        }
    }
    if r.replay_state() == ReplayState::Failed {
        return Err(Failure::Runtime(anyhow!(
            "the replay failed: {}",
            status.message
        )));
    }
    if args.verify && (r.mismatch.is_some() || r.verified != r.total) {
        return Err(Failure::Runtime(anyhow!(
            "the re-simulation differs from the recording"
        )));
    }
    Ok(())
}

/// A replay `replay` follows: stopped when dropped, so a command that ends
/// early (a closed stdout, an error, no progress) gives the world back as
/// it was before the replay (or keeps the replayed one with
/// `--keep-actors`), as Ctrl-C does.
struct Following<'a> {
    client: &'a sim_client::Client,
    keep_actors: bool,
    /// Whether the replay still needs stopping.
    armed: bool,
}

impl Drop for Following<'_> {
    fn drop(&mut self) {
        if !self.armed {
            return;
        }
        if let Err(e) = self.client.stop_replayer(self.keep_actors) {
            tracing::debug!("stopping the replay on the way out: {e}");
        }
    }
}
