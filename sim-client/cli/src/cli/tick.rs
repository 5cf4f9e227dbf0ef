//! `sim-client tick`: be the ticker — claim ownership, enter synchronous
//! mode with a fixed step, tick, and leave everything as it was on exit
//! (a world that was synchronous before stays synchronous), riding
//! through a server resumed from its journal.

use std::sync::atomic::Ordering;
use std::time::{Duration, Instant};

use anyhow::anyhow;
use clap::Args;
use shared_types::{WorldName, WorldSettings};
use sim_client::{ApplySettingsError, Client, TakeOver, TickError, Ticker, WaitMode};
use simbus_input as input;

use super::tick_restarts::{ride_through, wait_for_participants, Restarts, TickLoopError};
use crate::cli::failure::Failure;

/// The node name others see as the owner while this command ticks.
const NODE_NAME: &str = "sim-client-tick";

/// Options of `sim-client tick` (described on the command).
#[derive(Debug, Args)]
pub(crate) struct TickArgs {
    /// Stop after N ticks (0: change nothing).
    #[arg(long, value_name = "N", allow_negative_numbers = true)]
    count: Option<u64>,

    /// At most HZ ticks per wall-clock second, at most 1e6 (default: as
    /// fast as possible).
    #[arg(long, value_name = "HZ", allow_negative_numbers = true, value_parser = input::rate)]
    rate: Option<f64>,

    /// Stop once simulation time reaches S seconds.
    #[arg(long, value_name = "S", allow_negative_numbers = true, value_parser = input::sim_time)]
    until_sim_time: Option<f64>,

    /// Fixed time-step in seconds, 1e-6..=3600 (default: the world's, else
    /// 0.05; 0: variable step, with --allow-variable-step).
    #[arg(long, value_name = "S", conflicts_with = "fps", allow_negative_numbers = true, value_parser = input::fixed_delta_seconds)]
    delta_seconds: Option<f64>,

    /// Fixed time-step as frames per simulated second: 0.000277778..=1e6
    /// (0: variable step, with --allow-variable-step).
    #[arg(long, value_name = "N", allow_negative_numbers = true, value_parser = input::fps)]
    fps: Option<f64>,

    /// What a fixed step longer than max_substeps x max_substep_delta_time
    /// does while this command ticks (default: the world's rule).
    #[arg(long, value_name = "RULE")]
    substep_rule: Option<super::config::SubstepRuleArg>,

    /// Before the first tick, wait (up to --timeout) until N lockstep
    /// participants (autopilot, `watch --lockstep`, ...) have joined, so
    /// none misses the first frame (0..=1024).
    #[arg(long, value_name = "N", default_value_t = 0, allow_negative_numbers = true, value_parser = input::participants)]
    participants: u32,

    /// Accept a variable step in synchronous mode (dt = the ticker's wait; not recommended).
    #[arg(long)]
    allow_variable_step: bool,

    /// Leave the world in synchronous mode on exit, with its own step (it
    /// then waits for the next ticker). Without it the world's settings go
    /// back to what they were before this run: a world that was
    /// synchronous (`sim-server --sync`) stays synchronous, one that was
    /// asynchronous runs free again.
    #[arg(long)]
    leave_sync: bool,

    /// How to wait for each frame: block (sleep on the frame-ready event),
    /// spin (lowest latency, one core busy) or hybrid (poll 100 µs, then
    /// sleep: near-spin latency in a tight loop, no CPU burnt while the
    /// server is slow).
    #[arg(long, value_name = "MODE", default_value = "block")]
    wait_mode: WaitMode,

    /// One JSON object per tick.
    #[arg(long)]
    json: bool,

    /// Stand by while another client ticks: open the ticker's ports now,
    /// queue a claim, and take over the moment the world has no ticker (it
    /// exits, dies or is revoked), then tick as without --standby. Several
    /// standbys are served first come, first served.
    #[arg(long)]
    standby: bool,

    /// Do not wait for the server to come back: end when it exits, even
    /// when its world journals (default: a server started with --journal
    /// that exits is waited for, up to --restart-timeout, and claimed again
    /// once resumed with `sim-server --resume`).
    #[arg(long)]
    no_follow_restarts: bool,

    /// How long to wait for a journaling world's server to be resumed
    /// after it exits (default 30 s); a fresh server (another run) or none
    /// in time ends the command (exit 1).
    #[arg(long, value_name = "S", default_value = "30", allow_negative_numbers = true, value_parser = input::timeout, conflicts_with = "no_follow_restarts")]
    restart_timeout: Duration,

    /// With --standby: give up after S seconds on standby (exit 1, naming
    /// the ticker waited for). Default: wait until Ctrl-C.
    #[arg(long, value_name = "S", requires = "standby", allow_negative_numbers = true, value_parser = input::timeout)]
    standby_timeout: Option<Duration>,
}

impl TickArgs {
    /// The substep rule to tick with: --substep-rule, else the world's.
    fn rule(&self, current: &WorldSettings) -> shared_types::SubstepRule {
        self.substep_rule
            .map_or(current.substep_rule, shared_types::SubstepRule::from)
    }

    /// The settings to tick with on a world whose settings are `current`,
    /// and the fixed step among them (`None`: variable); refused when they
    /// are invalid.
    fn wanted(&self, current: &WorldSettings) -> Result<(WorldSettings, Option<f64>), Failure> {
        let delta = self.delta(current)?;
        let sync = WorldSettings {
            synchronous_mode: true,
            fixed_delta_seconds: delta,
            substep_rule: self.rule(current),
            ..*current
        };
        sync.validate()
            .map_err(|e| Failure::Refused(ApplySettingsError::from(e).into()))?;
        Ok((sync, delta))
    }

    /// The fixed step to tick with; `None` is a variable step.
    fn delta(&self, current: &WorldSettings) -> Result<Option<f64>, Failure> {
        let delta = match (self.delta_seconds, self.fps) {
            (Some(dt), _) => (dt != 0.0).then_some(dt),
            (None, Some(fps)) => WorldSettings::delta_from_fps(fps)
                .map_err(|e| Failure::Refused(ApplySettingsError::from(e).into()))?,
            (None, None) => Some(current.fixed_delta_seconds.unwrap_or(0.05)),
        };
        if delta.is_none() && !self.allow_variable_step {
            return Err(Failure::Refused(anyhow!(
                "synchronous mode with a variable step makes every frame as long as the ticker's wait, \
                 so physics is unreliable; give --delta-seconds / --fps, or pass --allow-variable-step"
            )));
        }
        Ok(delta)
    }
}

pub(crate) fn run(world: &WorldName, timeout: Duration, args: TickArgs) -> Result<(), Failure> {
    let interrupted = super::interrupt::interrupted();
    let mut client = super::session::connect(world.as_str(), timeout)?;
    client.set_request_timeout(timeout);
    let status = client.status()?;
    // Only a journaling server can be resumed: another one's exit ends the run.
    let follow = (!args.no_follow_restarts && status.journal.is_some()).then_some(Restarts {
        run_pid: status.run_pid,
        patience: args.restart_timeout,
        participants: args.participants,
    });
    // Refuse bad input before anything changes, ownership included.
    args.wanted(&client.get_settings()?)?;
    if args.count == Some(0) {
        eprintln!("tick: --count 0: nothing to do; the world is unchanged");
        return Ok(());
    }
    wait_for_participants(&client, args.participants, timeout).map_err(Failure::Runtime)?;
    let mut ticker = if args.standby {
        let Some(ticker) = stand_by(&client, world, &args, interrupted)? else {
            eprintln!("tick: interrupted on standby; the world is unchanged");
            return Ok(());
        };
        ticker
    } else {
        client.claim_ticker_as(NODE_NAME)?
    };
    // The settings as they are now that this run holds the world (a ticker
    // that ended meanwhile may have changed them): what is put back.
    let current = client.get_settings()?;
    let (sync, delta) = args.wanted(&current)?;
    ticker.set_wait_mode(args.wait_mode);
    let from = ticker
        .apply_settings(sync)
        .map_err(super::session::refused_or_runtime)?;
    // From here on the world is given back however this run ends: a bound,
    // Ctrl-C, an error, a closed stdout or a panic (the guard's drop).
    let mut holding = Holding::new(ticker, sync, current, args.leave_sync);
    match delta {
        Some(dt) => eprintln!(
            "tick: ticker of world '{world}'; synchronous mode, fixed step {} s, from frame {from}",
            simbus_input::Readable(dt)
        ),
        None => eprintln!(
            "tick: warning: synchronous mode with a variable step (--allow-variable-step); physics is unreliable"
        ),
    }
    for warning in sync.warnings() {
        eprintln!("tick: warning: {warning}");
    }

    let mut restarts = follow.map(|r| (r, &mut client));
    let ticks = match tick_loop(holding.ticker(), timeout, &args, &mut restarts, interrupted) {
        Err(e) if e.nothing_to_give_back() => {
            // Ownership was revoked (the world already left synchronous
            // mode), the server is gone, or a fresh server's world is not
            // this run's: nothing to put back.
            holding.revoked();
            return Err(match e {
                e @ TickLoopError::InterruptedWaiting { .. } => Failure::Interrupted(e.into()),
                e => Failure::Runtime(e.into()),
            });
        }
        other => other,
    };
    let (restore, release) = holding.give_back();
    let ticks = ticks.map_err(anyhow::Error::from)?;
    restore?;
    release?;
    eprintln!(
        "tick: {}; released ownership, {}",
        super::words::count(ticks, "tick"),
        left_as(
            &left_with(&current, args.leave_sync),
            current.synchronous_mode
        )
    );
    Ok(())
}

/// The settings a run gives back: the world's from `before` it, in
/// synchronous mode if it was or `leave_sync` asks.
fn left_with(before: &WorldSettings, leave_sync: bool) -> WorldSettings {
    WorldSettings {
        synchronous_mode: before.synchronous_mode || leave_sync,
        ..*before
    }
}

/// How the world is left (`left`), as the last line says it; `was_sync`:
/// whether it was synchronous before the run.
fn left_as(left: &WorldSettings, was_sync: bool) -> String {
    if !left.synchronous_mode {
        return "world left in asynchronous mode, with its settings as before".to_owned();
    }
    let step = match left.fixed_delta_seconds {
        Some(dt) => format!("its own step ({} s)", simbus_input::Readable(dt)),
        None => "its own variable step".to_owned(),
    };
    let why = if was_sync { ", as before" } else { "" };
    format!("world left in synchronous mode with {step}{why}, waiting for the next ticker")
}

/// The ticker of a run and what to put back when the run ends. Dropped
/// without [`Holding::give_back`] (an early return, an unwind from a closed
/// stdout, a panic) it still puts the settings back and releases.
struct Holding {
    ticker: Option<Ticker>,
    /// The settings to put back: the world's before the run (synchronous
    /// too with --leave-sync); `None` once nothing is to be put back.
    restore: Option<WorldSettings>,
}

impl Holding {
    /// Holds `ticker`, which applied `applied` to a world whose settings
    /// were `before` this run.
    fn new(
        ticker: Ticker,
        applied: WorldSettings,
        before: WorldSettings,
        leave_sync: bool,
    ) -> Self {
        let restore = left_with(&before, leave_sync);
        Self {
            ticker: Some(ticker),
            restore: (restore != applied).then_some(restore),
        }
    }

    /// The ticker, to tick with.
    fn ticker(&mut self) -> &mut Ticker {
        self.ticker.as_mut().expect("held until given back")
    }

    /// Ownership was revoked and the world left synchronous mode: only
    /// release is left to do.
    fn revoked(mut self) {
        self.restore = None;
        if let Some(ticker) = self.ticker.take() {
            let _ = ticker.release();
        }
    }

    /// Puts the world's settings back, then releases ownership; both
    /// results, so a failed restore still releases.
    fn give_back(mut self) -> (anyhow::Result<()>, anyhow::Result<()>) {
        let mut ticker = self.ticker.take().expect("held until given back");
        let restore = match self.restore.take() {
            Some(settings) => ticker
                .apply_settings(settings)
                .map(|_| ())
                .map_err(|e| anyhow!(e).context("restoring the world's settings")),
            None => Ok(()),
        };
        let release = ticker.release().map_err(|e| anyhow!(e));
        (restore, release)
    }
}

impl Drop for Holding {
    fn drop(&mut self) {
        if self.ticker.is_none() {
            return;
        }
        let (restore, release) = Self {
            ticker: self.ticker.take(),
            restore: self.restore.take(),
        }
        .give_back();
        for e in [restore.err(), release.err()].into_iter().flatten() {
            eprintln!("tick: {e:#}");
        }
    }
}

/// Stands by until the world has no ticker, then returns the ticker;
/// `None` on Ctrl-C.
fn stand_by(
    client: &Client,
    world: &WorldName,
    args: &TickArgs,
    interrupted: &std::sync::atomic::AtomicBool,
) -> Result<Option<Ticker>, Failure> {
    let mut standby = client.standby_ticker_as(NODE_NAME)?;
    if let Some(owner) = standby.owner() {
        eprintln!("tick: standby for world '{world}': waiting for the ticker {owner} to go");
    }
    let deadline = args.standby_timeout.map(|t| Instant::now() + t);
    loop {
        if interrupted.load(Ordering::Relaxed) {
            return Ok(None);
        }
        let left = deadline.map_or(Duration::MAX, |d| {
            d.saturating_duration_since(Instant::now())
        });
        if left.is_zero() {
            return Err(Failure::Runtime(
                TickError::StandbyTimedOut {
                    world: world.to_string(),
                    waited: args.standby_timeout.unwrap_or_default(),
                    owner: standby.owner().map(Box::new),
                }
                .into(),
            ));
        }
        // In slices, so Ctrl-C is noticed.
        match standby.wait_for(left.min(Duration::from_millis(200)))? {
            TakeOver::Ticker(ticker) => {
                let frame = ticker.last_frame().map_or(0, |(frame, _)| frame);
                eprintln!("tick: standby took over world '{world}' at frame {frame}");
                return Ok(Some(ticker));
            }
            TakeOver::Waiting(waiting) => standby = waiting,
        }
    }
}

/// Ticks until a bound, Ctrl-C or an error; returns the number of ticks.
/// With `restarts`, a server that exits is waited for and, once resumed
/// from its journal, claimed again; ticking goes on from the frame it
/// resumed at, and every frame is printed once.
fn tick_loop(
    ticker: &mut Ticker,
    timeout: Duration,
    args: &TickArgs,
    restarts: &mut Option<(Restarts, &mut Client)>,
    interrupted: &std::sync::atomic::AtomicBool,
) -> Result<u64, TickLoopError> {
    // --rate was checked to give a period a clock can wait for.
    let period = args.rate.map(|hz| Duration::from_secs_f64(1.0 / hz));
    let until_ns = args.until_sim_time.map(shared_types::seconds_to_nanos);
    let mut next_at = Instant::now();
    let mut ticks = 0;
    // The last frame printed: a resumed world's first frame is printed
    // only when it is past it.
    let mut printed = ticker.last_frame().map(|(frame, _)| frame);
    // After a resume behind the last frame printed (a journal that made
    // only every Nth frame durable, or stopped on a full disk): the frames
    // up to it are computed again, and neither printed nor counted twice.
    let mut catching_up: Option<u64> = None;
    loop {
        if interrupted.load(Ordering::Relaxed) || args.count.is_some_and(|n| ticks >= n) {
            return Ok(ticks);
        }
        if let (Some(until), Some((_, elapsed))) = (until_ns, ticker.last_frame()) {
            if elapsed >= until {
                return Ok(ticks);
            }
        }
        if let Some(period) = period {
            // Sleep in slices so Ctrl-C is noticed.
            while Instant::now() < next_at && !interrupted.load(Ordering::Relaxed) {
                std::thread::sleep((next_at - Instant::now()).min(Duration::from_millis(100)));
            }
            next_at = next_at.max(Instant::now() - period) + period;
            if interrupted.load(Ordering::Relaxed) {
                return Ok(ticks);
            }
        }
        let frame = match (ticker.tick(timeout), restarts.as_mut()) {
            (Ok(frame), _) => frame,
            (Err(e), Some((follow, client))) if e.is_server_gone() => {
                // The frame the world resumed at: the interrupted tick's,
                // when the journal made it durable.
                let resumed_at = ride_through(ticker, *follow, client, interrupted)?;
                catching_up = printed;
                resumed_at
            }
            (Err(e), _) => return Err(e.into()),
        };
        if catching_up.is_some_and(|last| frame <= last) {
            continue;
        }
        catching_up = None;
        ticks += 1;
        printed = Some(frame);
        let elapsed = ticker.last_frame().map_or(0, |(_, ns)| ns) as f64 / 1e9;
        if args.json {
            println!(
                "{}",
                serde_json::json!({ "frame": frame, "elapsed_seconds": elapsed })
            );
        } else {
            println!("tick  frame {frame:>8}  t = {elapsed:>12.6} s");
        }
    }
}
