//! The simulation clock: integer-nanosecond time, fixed and variable steps,
//! and the physics substep plan of a frame.
//!
//! Time is kept as `u64` nanoseconds so that a million frames of 0.1 s land
//! exactly on 100 000 s; seconds are only computed for display and physics.

use std::time::{Duration, Instant, SystemTime, UNIX_EPOCH};

use shared_types::{seconds_to_nanos, WorldSettings, LONG_SUBSTEP_NS, NANOS_PER_SECOND};
use tracing::warn;

/// Wall-clock seconds since the Unix epoch, as frames and captures carry it.
pub(crate) fn platform_timestamp() -> f64 {
    SystemTime::now()
        .duration_since(UNIX_EPOCH)
        .map_or(0.0, |d| d.as_secs_f64())
}

/// How one frame's delta is split into physics steps.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct SubstepPlan {
    /// Physics steps to run, 1 to `max_substeps`.
    pub count: u32,
    /// Length of each physics step, in seconds (rapier runs in `f32`).
    pub substep_seconds: f32,
    /// The frame was longer than `max_substeps * max_substep_delta_time`, so
    /// its substeps are longer than `max_substep_delta_time` (the substep
    /// rules `refuse`, for a variable step, and `stretch`).
    pub capped: bool,
    /// The frame was longer than `max_substeps * max_substep_delta_time`
    /// and the substep rule `clamp` (CARLA's) ran only that much physics:
    /// `count * substep_seconds` is less than the frame's delta.
    pub clamped: bool,
    /// The frame's whole delta, nanoseconds: what the traffic lights
    /// count (physics may advance less, `clamped`).
    pub frame_ns: u64,
}

impl SubstepPlan {
    /// The plan for a frame of `delta_ns` under `settings`.
    ///
    /// With substepping: the physics time `t` is `dt`, or under the substep
    /// rule `clamp` at most `max_substeps * max_substep_delta_time` (then
    /// `clamped` is set); `n = ceil(t / max_substep_delta_time)` steps of
    /// `t / n`, with `n` capped at `max_substeps` (then `capped` is set).
    /// Without substepping: one step of `dt`.
    ///
    /// The substep length is computed from integer nanoseconds only, so a
    /// clamped 0.2 s frame steps bit for bit as a 0.1 s frame does.
    pub fn new(delta_ns: u64, settings: &WorldSettings) -> Self {
        let max_substep_ns = settings.max_substep_nanos().max(1);
        let physics_ns = settings.substep_rule.physics_ns(
            delta_ns,
            settings.substepping,
            max_substep_ns,
            settings.max_substeps,
        );
        let (count, capped) = if settings.substepping {
            let needed = physics_ns.div_ceil(max_substep_ns).max(1);
            let max = u64::from(settings.max_substeps.max(1));
            (needed.min(max) as u32, needed > max)
        } else {
            (1, false)
        };
        Self {
            count,
            substep_seconds: (physics_ns as f64 / f64::from(count) / NANOS_PER_SECOND as f64)
                as f32,
            capped,
            clamped: physics_ns < delta_ns,
            frame_ns: delta_ns,
        }
    }
}

/// Frame id and simulation time of the world.
#[derive(Debug, Clone)]
pub struct Clock {
    frame: u64,
    elapsed_ns: u64,
    delta_ns: u64,
    last_frame_at: Instant,
}

impl Clock {
    /// A clock at frame 0, time 0, whose variable steps count from `now`.
    pub fn new(now: Instant) -> Self {
        Self {
            frame: 0,
            elapsed_ns: 0,
            delta_ns: 0,
            last_frame_at: now,
        }
    }

    /// A clock at `frame`, `elapsed_ns`, last stepped by `delta_ns` (a
    /// restored keyframe, a replayed frame).
    pub fn at(frame: u64, elapsed_ns: u64, delta_ns: u64, now: Instant) -> Self {
        Self {
            frame,
            elapsed_ns,
            delta_ns,
            last_frame_at: now,
        }
    }

    /// A clock at the frame `timestamp` describes, computed at `now`.
    pub fn at_timestamp(timestamp: &shared_types::Timestamp, now: Instant) -> Self {
        Self::at(
            timestamp.frame,
            timestamp.elapsed_ns,
            timestamp.delta_ns,
            now,
        )
    }

    /// The current frame id.
    pub fn frame(&self) -> u64 {
        self.frame
    }

    /// Simulation time of the current frame, in nanoseconds.
    pub fn elapsed_ns(&self) -> u64 {
        self.elapsed_ns
    }

    /// Simulation time between the previous frame and the current one, in
    /// nanoseconds (0 for frame 0).
    pub fn delta_ns(&self) -> u64 {
        self.delta_ns
    }

    /// When the current frame was computed (wall clock).
    pub fn last_frame_at(&self) -> Instant {
        self.last_frame_at
    }

    /// The delta of the next frame if it were computed at `now`: the fixed
    /// step, or the wall time since the previous frame (at least 1 ns).
    pub fn next_delta_ns(&self, settings: &WorldSettings, now: Instant) -> u64 {
        settings.fixed_delta_nanos().unwrap_or_else(|| {
            let wall = now.saturating_duration_since(self.last_frame_at);
            u64::try_from(wall.as_nanos()).unwrap_or(u64::MAX).max(1)
        })
    }

    /// Moves to the next frame, `delta_ns` later, computed at `now`.
    pub fn advance(&mut self, delta_ns: u64, now: Instant) {
        self.frame += 1;
        // Saturates after 584 years of simulation time instead of wrapping.
        self.elapsed_ns = self.elapsed_ns.saturating_add(delta_ns);
        self.delta_ns = delta_ns;
        self.last_frame_at = now;
    }
}

/// A realtime server that falls this far behind stops trying to catch up.
const MAX_REALTIME_LAG: Duration = Duration::from_millis(250);

/// When the next frame is due in asynchronous mode: at once (fixed step,
/// unpaced), on the wall clock (fixed step, `--realtime`), or at most
/// `max_fps` frames a second (variable step).
#[derive(Debug, Clone)]
pub struct Pacer {
    realtime: bool,
    max_fps: f64,
    /// Wall instant and simulation time that correspond (realtime).
    anchor: Option<(Instant, u64)>,
}

impl Pacer {
    /// A pacer for `--realtime` and `--max-fps` (0: no limit).
    pub fn new(realtime: bool, max_fps: f64) -> Self {
        Self {
            realtime,
            max_fps,
            anchor: None,
        }
    }

    /// Forgets the wall/simulation correspondence (settings changed, new
    /// episode, sync mode left): pacing starts again from the next frame.
    pub fn reset(&mut self) {
        self.anchor = None;
    }

    /// Whether frames under `settings` wait for their time
    /// ([`Pacer::next_frame_at`] gives one), so the loop sleeps between
    /// them.
    pub fn paces(&self, settings: &WorldSettings) -> bool {
        match settings.fixed_delta_nanos() {
            Some(_) => self.realtime,
            None => self.max_fps > 0.0,
        }
    }

    /// When the next frame of `clock` is due under `settings`; `None` for now.
    pub fn next_frame_at(
        &mut self,
        clock: &Clock,
        settings: &WorldSettings,
        now: Instant,
    ) -> Option<Instant> {
        match settings.fixed_delta_nanos() {
            Some(dt) if self.realtime => {
                let (wall, sim) = *self.anchor.get_or_insert((now, clock.elapsed_ns()));
                let ahead = clock.elapsed_ns().saturating_add(dt).saturating_sub(sim);
                let due = wall + Duration::from_nanos(ahead);
                if now.saturating_duration_since(due) > MAX_REALTIME_LAG {
                    warn!("realtime pacing fell behind by more than {MAX_REALTIME_LAG:?}; resynchronising");
                    self.anchor = None;
                }
                Some(due)
            }
            Some(_) => None,
            // --max-fps was checked to give a period a clock can wait for.
            None if self.max_fps > 0.0 => {
                Some(clock.last_frame_at() + Duration::from_secs_f64(1.0 / self.max_fps))
            }
            None => None,
        }
    }
}

/// Whether `plan`'s substeps are longer than 1/60 s, the threshold
/// [`WorldSettings::warnings`] uses too ([`LONG_SUBSTEP_NS`]).
pub fn long_substep(plan: &SubstepPlan) -> bool {
    seconds_to_nanos(f64::from(plan.substep_seconds)) > LONG_SUBSTEP_NS
}

#[cfg(test)]
mod tests {
    use super::*;
    use std::time::Duration;

    fn settings(substepping: bool, max_dt: f64, max_substeps: u32) -> WorldSettings {
        WorldSettings {
            substepping,
            max_substep_delta_time: max_dt,
            max_substeps,
            ..Default::default()
        }
    }

    #[test]
    fn substep_count_is_ceil_of_delta_over_max_substep() {
        let s = settings(true, 0.01, 10);
        for (delta_ms, expected) in [
            (1, 1),
            (10, 1),
            (11, 2),
            (25, 3),
            (50, 5),
            (99, 10),
            (100, 10),
        ] {
            let plan = SubstepPlan::new(delta_ms * 1_000_000, &s);
            assert_eq!(plan.count, expected, "dt = {delta_ms} ms");
            assert!(!plan.capped);
            let expected_dt = delta_ms as f64 / 1000.0 / expected as f64;
            assert!((f64::from(plan.substep_seconds) - expected_dt).abs() < 1e-9);
        }
    }

    #[test]
    fn substeps_are_capped_at_max_substeps_and_flagged() {
        let plan = SubstepPlan::new(250_000_000, &settings(true, 0.01, 10));
        assert_eq!(plan.count, 10);
        assert!(plan.capped);
        assert!((plan.substep_seconds - 0.025).abs() < 1e-7);
        assert!(long_substep(&plan));
    }

    #[test]
    fn each_substep_rule_splits_a_long_frame_its_own_way() {
        use shared_types::SubstepRule;
        let rule = |substep_rule| WorldSettings {
            substep_rule,
            ..settings(true, 0.01, 10)
        };
        // CARLA's example, 0.2 s frames: clamp runs exactly the plan of a
        // 0.1 s frame, bit for bit.
        let clamp = SubstepPlan::new(200_000_000, &rule(SubstepRule::Clamp));
        let tenth = SubstepPlan::new(100_000_000, &rule(SubstepRule::Refuse));
        assert_eq!(clamp.count, 10);
        assert_eq!(
            clamp.substep_seconds.to_bits(),
            tenth.substep_seconds.to_bits()
        );
        assert!(clamp.clamped && !clamp.capped && !tenth.clamped);
        // Stretch: 10 substeps of 0.02 s, as 0.02 s x 10 would plan them.
        let stretch = SubstepPlan::new(200_000_000, &rule(SubstepRule::Stretch));
        let coarse = SubstepPlan::new(200_000_000, &settings(true, 0.02, 10));
        assert_eq!(
            (stretch.count, stretch.capped, stretch.clamped),
            (10, true, false)
        );
        assert_eq!(
            stretch.substep_seconds.to_bits(),
            coarse.substep_seconds.to_bits()
        );
        // Within the limit the rules agree.
        for r in SubstepRule::ALL {
            assert_eq!(
                SubstepPlan::new(50_000_000, &rule(r)),
                SubstepPlan::new(50_000_000, &settings(true, 0.01, 10))
            );
        }
    }

    #[test]
    fn without_substepping_one_step_covers_the_frame() {
        let plan = SubstepPlan::new(50_000_000, &settings(false, 0.01, 10));
        assert_eq!(plan.count, 1);
        assert!(!plan.capped);
        assert!((plan.substep_seconds - 0.05).abs() < 1e-9);
    }

    #[test]
    fn max_substeps_bounds_follow_settings() {
        let plan = SubstepPlan::new(40_000_000, &settings(true, 0.001, 16));
        assert_eq!(plan.count, 16);
        assert!(plan.capped);
        let plan = SubstepPlan::new(16_000_000, &settings(true, 0.001, 16));
        assert_eq!((plan.count, plan.capped), (16, false));
        let plan = SubstepPlan::new(3_000_000, &settings(true, 0.001, 1));
        assert_eq!((plan.count, plan.capped), (1, true));
    }

    #[test]
    fn a_pacer_paces_exactly_when_it_gives_the_next_frame_a_time() {
        let now = Instant::now();
        let clock = Clock::new(now);
        let fixed = WorldSettings {
            fixed_delta_seconds: Some(0.01),
            ..Default::default()
        };
        let variable = WorldSettings::default();
        for (realtime, max_fps) in [(false, 0.0), (true, 0.0), (false, 60.0), (true, 60.0)] {
            for settings in [&fixed, &variable] {
                let mut pacer = Pacer::new(realtime, max_fps);
                assert_eq!(
                    pacer.paces(settings),
                    pacer.next_frame_at(&clock, settings, now).is_some(),
                    "realtime {realtime}, max fps {max_fps}, {settings:?}"
                );
            }
        }
        assert!(Pacer::new(true, 0.0).paces(&fixed));
        assert!(Pacer::new(false, 60.0).paces(&variable));
    }

    #[test]
    fn fixed_steps_accumulate_exactly() {
        let start = Instant::now();
        let mut clock = Clock::new(start);
        let s = WorldSettings {
            fixed_delta_seconds: Some(0.1),
            ..Default::default()
        };
        for _ in 0..1_000_000 {
            let dt = clock.next_delta_ns(&s, start);
            clock.advance(dt, start);
        }
        assert_eq!(clock.frame(), 1_000_000);
        assert_eq!(clock.elapsed_ns(), 100_000 * NANOS_PER_SECOND);
    }

    #[test]
    fn variable_steps_follow_wall_time() {
        let start = Instant::now();
        let mut clock = Clock::new(start);
        let s = WorldSettings::default();
        let later = start + Duration::from_millis(16);
        assert_eq!(clock.next_delta_ns(&s, later), 16_000_000);
        clock.advance(16_000_000, later);
        assert_eq!(clock.next_delta_ns(&s, later), 1, "never a zero step");
    }
}
