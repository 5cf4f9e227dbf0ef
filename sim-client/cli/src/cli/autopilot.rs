//! `sim-client autopilot`: a lockstep participant that drives the world's
//! vehicles with seeded randomness (CARLA's Traffic Manager, kept in step).

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::anyhow;
use clap::Args;
use rand::{RngExt, SeedableRng};
use rand_chacha::ChaCha8Rng;
use shared_types::{ActorKind, Command, WorldName};
use sim_client::{BatchError, WaitError};

use crate::cli::failure::Failure;

/// Options of `sim-client autopilot` (described on the command).
#[derive(Debug, Args)]
pub(crate) struct AutopilotArgs {
    /// Seed of the random driving.
    #[arg(long, default_value_t = 0, allow_negative_numbers = true)]
    seed: u64,
    /// New controls every N frames (N >= 1).
    #[arg(long, value_name = "N", default_value_t = 50, allow_negative_numbers = true, value_parser = simbus_input::count)]
    every: u64,
    /// Stop after N frames, N >= 1 (default: until Ctrl-C or the server
    /// goes away).
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = simbus_input::count)]
    frames: Option<u64>,
}

pub(crate) fn run(
    world: &WorldName,
    timeout: Duration,
    args: AutopilotArgs,
) -> Result<(), Failure> {
    if args.every == 0 {
        return Err(Failure::Refused(anyhow!("--every must be at least 1")));
    }
    let interrupted = super::interrupt::interrupted();
    let mut client = super::session::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    let participant = client.join_lockstep("autopilot")?;
    let (episode, frame) = participant.joined_at();
    eprintln!(
        "autopilot: driving world '{world}' from episode {episode} frame {frame}, seed {}",
        args.seed
    );
    let mut rng = ChaCha8Rng::seed_from_u64(args.seed);
    let mut episode = None;
    // The first frame of the current episode, which the cadence counts from.
    let mut start = 0;
    let mut handled = 0;
    // The last frame seen and when: no frame for --timeout is an error that
    // says why (a stopped server, a synchronous world nobody ticks).
    let mut last = (Some(frame), Instant::now());
    while args.frames.is_none_or(|n| handled < n) && !interrupted.load(Ordering::Relaxed) {
        let snapshot = match client.wait_for_tick(Duration::from_millis(200).min(timeout)) {
            Ok(snapshot) => snapshot,
            Err(WaitError::Timeout { .. }) if last.1.elapsed() < timeout => continue,
            Err(WaitError::Timeout { .. }) => {
                return Err(super::stall::no_frames(&mut client, timeout, last.0).into())
            }
            Err(e) => return Err(anyhow!(e).into()),
        };
        last = (Some(snapshot.frame()), Instant::now());
        if episode != Some(snapshot.episode()) {
            // Every episode drives the same way from its first frame: frame
            // 0 after a load, the next frame id after a replay (frame ids
            // never go back). The episode it joined counts from frame 0.
            if episode.is_some() {
                start = snapshot.frame();
            }
            episode = Some(snapshot.episode());
            rng = ChaCha8Rng::seed_from_u64(args.seed);
        }
        // A replayed frame follows the recording: nothing to drive (the
        // server refuses commands while it replays), only "done" to say.
        let due = snapshot
            .frame()
            .saturating_sub(start)
            .is_multiple_of(args.every);
        if due && !snapshot.header.is_replay() {
            let controls: Vec<Command> = snapshot
                .actors
                .iter()
                .filter(|a| a.actor_kind() == Some(ActorKind::Vehicle))
                .map(|a| {
                    let throttle = rng.random_range(0.2..=1.0);
                    let steer = rng.random_range(-0.6..=0.6);
                    Command::vehicle_control(a.id, throttle, steer, 0.0, false)
                })
                .collect();
            if !controls.is_empty() {
                match client.apply_batch_sync(&controls, false) {
                    // Replaying: a replay started after this frame; its
                    // frames come next.
                    Ok(_) | Err(BatchError::Replaying) => {}
                    Err(e) => return Err(anyhow!(e).into()),
                }
            }
        }
        participant.done(snapshot.episode(), snapshot.frame())?;
        handled += 1;
    }
    eprintln!(
        "autopilot: handled {}",
        super::words::count(handled, "frame")
    );
    Ok(())
}
