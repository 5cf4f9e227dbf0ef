//! `sim-client watch`: one line per frame.

use std::time::Duration;

use clap::Args;
use shared_types::{LightState, WorldName};
use sim_client::{Client, FrameView, WaitError, WaitMode};

use crate::cli::failure::Failure;

/// Options of `sim-client watch` (described on the command).
#[derive(Debug, Args)]
pub(crate) struct WatchArgs {
    /// Stop after N frames (N >= 1).
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = simbus_input::count)]
    frames: Option<u64>,

    /// One JSON object per line.
    #[arg(long)]
    json: bool,

    /// How to wait for each frame: block (sleep on the frame-ready event),
    /// spin (lowest latency, one core busy) or hybrid (poll 100 µs, then sleep).
    #[arg(long, value_name = "MODE", default_value = "block")]
    wait_mode: WaitMode,

    /// Print every frame in order in asynchronous mode too, instead of
    /// skipping to the newest (16 frames of slack; beyond that frames are
    /// lost and counted as missed).
    #[arg(long)]
    every_frame: bool,

    /// Print `frame F digest D` per frame (a replayed frame: its recorded
    /// id, so a replay's digests diff against the original run's; the digest covers the frame's
    /// time and every actor's state, bit for bit): `diff` two runs' output.
    /// A frame this watcher did not see is printed as a `missed` line, and
    /// the command then exits 1: a digest list with gaps proves nothing.
    #[arg(long)]
    digest: bool,

    /// Join the lockstep: in synchronous mode the server waits for this
    /// watcher every frame, so it sees every frame however fast the ticker
    /// ticks (use it with --digest). If the server drops it (it stopped
    /// reading for longer than --lockstep-timeout) it says so and exits 1.
    #[arg(long)]
    lockstep: bool,

    /// With --lockstep, a window of N frames (CARLA's per-participant
    /// synchronous windows): the server may run up to N frames ahead of this
    /// watcher before it holds the ticker, so a watcher that stalls for
    /// fewer frames never slows the world; it still sees every frame
    /// (0..=15: its frame queue holds 16). 0, the default, waits every frame.
    #[arg(long, value_name = "N", requires = "lockstep", allow_negative_numbers = true, value_parser = simbus_input::watch_window)]
    window: Option<u32>,

    /// Ride through a server restart (`sim-server --resume DIR`): when the
    /// server exits, wait up to --timeout for one to come back on the
    /// world, print a `restarted` line marking the gap (JSON: an object
    /// with "event": "restarted"), and go on with its frames (rejoining
    /// the lockstep with --lockstep). Without it, a server that exits ends
    /// the watch with an error.
    #[arg(long)]
    follow_restarts: bool,
}

/// The line (or JSON object) that marks a restart in a watch.
pub(crate) fn restarted_line(r: &sim_client::Reconnected, json: bool) -> String {
    if json {
        serde_json::json!({
            "event": "restarted",
            "resumed_at": r.resumed_at,
            "episode": r.episode,
            "server_pid": r.server_pid,
            "previous_pid": r.previous_pid,
        })
        .to_string()
    } else {
        format!("restarted: {r}")
    }
}

/// The JSON object of one frame.
pub(crate) fn frame_json(s: &FrameView) -> serde_json::Value {
    let t = s.timestamp();
    serde_json::json!({
        "frame": t.frame,
        "episode": s.episode(),
        "elapsed_seconds": t.elapsed_seconds(),
        "elapsed_ns": t.elapsed_ns,
        "delta_seconds": t.delta_seconds(),
        "delta_ns": t.delta_ns,
        "platform_timestamp": t.platform_timestamp,
        "actors": s.actors().len(),
        "physics_substeps": s.header().physics_substeps,
        // The substep rule `clamp` (CARLA's): physics ran less than delta.
        "physics_clamped": s.is_physics_clamped(),
        "physics_seconds": s.physics_seconds(),
        "substep_rule": s.settings().substep_rule.name(),
        "synchronous_mode": s.settings().synchronous_mode,
        "fixed_delta_seconds": s.settings().fixed_delta_seconds,
        "missed": s.missed(),
        "replay": s.header().is_replay(),
        // A replayed frame: its id and time in the recording.
        "recorded_frame": s.header().is_replay().then_some(s.header().recorded_frame),
        "recorded_elapsed_seconds": s.header().is_replay().then(|| {
            shared_types::nanos_to_seconds(s.header().recorded_elapsed_ns)
        }),
        "digest": format!("{:016x}", s.digest()),
        "traffic_lights": light_counts(s).map(|counts| {
            serde_json::Map::from_iter(
                LightState::ALL
                    .iter()
                    .zip(counts)
                    .map(|(state, n)| (state.name().to_owned(), n.into())),
            )
        }),
    })
}

/// How many traffic lights show red, yellow, green and off (in
/// [`LightState::ALL`]'s order); `None` in a world without lights.
fn light_counts(s: &FrameView) -> Option<[u32; 4]> {
    let mut counts = [0u32; 4];
    let mut any = false;
    for light in s.actors().iter().filter_map(|a| a.light()) {
        counts[light.state as usize] += 1;
        any = true;
    }
    any.then_some(counts)
}

fn frame_line(s: &FrameView) -> String {
    let t = s.timestamp();
    let mut line = format!(
        "frame {:>8}  t = {:>12.6} s  dt = {:.6} s  actors = {}  substeps = {}",
        t.frame,
        t.elapsed_seconds(),
        t.delta_seconds(),
        s.actors().len(),
        s.header().physics_substeps,
    );
    if s.is_physics_clamped() {
        line.push_str(&format!(
            "  (physics clamped to {} s)",
            simbus_input::Readable(s.physics_seconds())
        ));
    }
    if let Some(counts) = light_counts(s) {
        let shown: Vec<String> = LightState::ALL
            .iter()
            .zip(counts)
            .filter(|(_, n)| *n > 0)
            .map(|(state, n)| format!("{n} {}", state.name()))
            .collect();
        line.push_str(&format!("  lights = {}", shown.join(" ")));
    }
    if s.missed() > 0 {
        line.push_str(&format!("  (missed {})", s.missed()));
    }
    if s.header().is_replay() {
        line.push_str(&format!(
            "  (replay of recorded frame {})",
            s.header().recorded_frame
        ));
    }
    line
}

/// Waits up to `timeout` for the next frame; `Ok(None)` when interrupted.
pub(crate) fn next_frame(
    client: &mut Client,
    timeout: Duration,
) -> Result<Option<FrameView>, WaitError> {
    super::interrupt::in_slices(timeout, |slice| client.wait_for_frame(slice))
}

pub(crate) fn run(world: &WorldName, timeout: Duration, args: WatchArgs) -> Result<(), Failure> {
    super::interrupt::interrupted();
    let mut client = super::session::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    client.set_wait_mode(args.wait_mode);
    client.set_every_frame(args.every_frame);
    let join = |client: &Client| {
        args.lockstep
            .then(|| client.join_lockstep_with_window("watch", args.window.unwrap_or(0)))
            .transpose()
    };
    let mut participant = join(&client)?;
    let (mut seen, mut missed) = (0, 0);
    // The last frame printed, (episode, frame): a resumed server publishes
    // the frame it resumed at again, which was printed already when this
    // watcher saw it before the crash.
    let mut printed: Option<(u64, u64)> = None;
    // The run watched: a fresh server (another run) starts its frames again.
    let mut run_pid = if args.follow_restarts {
        client.status()?.run_pid
    } else {
        0
    };
    while args.frames.is_none_or(|n| seen < n) {
        let snapshot = match next_frame(&mut client, timeout) {
            Ok(Some(snapshot)) => snapshot,
            Ok(None) => break,
            Err(WaitError::ServerGone { .. }) if args.follow_restarts => {
                drop(participant.take());
                let restarted = client.reconnect(timeout)?;
                let run = client.status()?.run_pid;
                if run != run_pid {
                    (run_pid, printed) = (run, None);
                }
                println!("{}", restarted_line(&restarted, args.json));
                participant = join(&client)?;
                continue;
            }
            Err(e) => return Err(e.into()),
        };
        let this = (snapshot.episode(), snapshot.frame());
        if printed.is_some_and(|p| this <= p) {
            if let Some(participant) = &participant {
                participant.done(this.0, this.1)?;
            }
            continue;
        }
        printed = Some(this);
        seen += 1;
        missed += snapshot.missed();
        if args.json {
            println!("{}", frame_json(&snapshot));
        } else if args.digest {
            if snapshot.missed() > 0 {
                println!(
                    "missed {} ({}..={})",
                    super::words::count(snapshot.missed(), "frame"),
                    snapshot.frame() - snapshot.missed(),
                    snapshot.frame() - 1
                );
            }
            // A replayed frame goes by its recorded id, as its digest does:
            // a replay's digests diff against the original run's.
            println!(
                "frame {} digest {:016x}",
                snapshot.recorded_frame().unwrap_or(snapshot.frame()),
                snapshot.digest()
            );
        } else {
            println!("{}", frame_line(&snapshot));
        }
        if let Some(participant) = &participant {
            participant.done(snapshot.episode(), snapshot.frame())?;
        }
        // A digest list with a gap proves nothing: stop at the first one,
        // in every output format.
        if args.digest && missed > 0 {
            return Err(Failure::Runtime(anyhow::anyhow!(
                "missed {} before frame {}, so the digests have gaps; add \
                 --lockstep so the server waits for this watcher",
                super::words::count(missed, "frame"),
                snapshot.frame()
            )));
        }
    }
    Ok(())
}
