//! The server loop: each turn it lets every domain answer what arrived, in
//! a fixed order, then steps a frame when it is due (asynchronous mode) or
//! ticked and every lockstep participant is done (synchronous mode), and
//! otherwise sleeps in one place, the control domain's wake-up event.
//! After answering what clients announced on that event, it rings the
//! frame-ready event, so a client may wait for an answer as for a frame.
//!
//! Within a frame boundary the order is: control (settings, status,
//! load/reload), recorder (record, replay), batches, lockstep, sensors,
//! ticks, housekeeping — so whatever arrived before a step applies before
//! it. While a replay runs, a replayed frame takes the place of a computed
//! one; while a recording runs, every published frame is recorded.
//!
//! # Where `Domains` is
//!
//! `Domains` holds every domain but the two request ports whose answers
//! concern all of them; its `impl` is split by what it does:
//!
//! | file | what it holds |
//! |---|---|
//! | `mod.rs` | `Server::run`; `step_frame` (one computed frame), `finish_frame` (the tail every frame shares: capture, publish, answer, wake), `publish`, the frame header, `load_world`, housekeeping |
//! | `open.rs` | `Server::start` / `Server::resume`: every domain opened, fresh, resumed or forked |
//! | `turn.rs` | one turn: `answer_requests` in the order above, `synchronous_turn`, `asynchronous_turn` (when to step, where to sleep) |
//! | `answers.rs` | control requests: status `report`, settings, load and reload |
//! | `recording.rs` | recorder requests; `replay_frame` and its header; the episodes the recording and the journal note |
//! | `snapshots.rs` | saving and restoring snapshots in memory |
//! | `error.rs` | `ServerError`: what starting or running can fail with |
//!
//! # What each domain may touch
//!
//! A domain (each module beside this folder) owns its ports and its state.
//! What it needs of another's state is handed to each call, read-only
//! unless the call is about changing it: `batches` and `commands` change
//! the world, the ticker and the lockstep read the clock, the sensors read
//! the world. A domain uses another's types only where it is built on it:
//! the journal on the recorder's writer, the recorder service on the
//! replayer's requests, the ticker on the batches' answer to a batch that
//! ticks. Imports go one way (lower modules never import higher ones), and
//! only this folder touches several domains in one place, so the order of
//! their effects within a frame is decided here.
//!

mod answers;
mod error;
mod open;
mod recording;
mod snapshots;
mod turn;

pub use error::ServerError;

use std::sync::atomic::{AtomicBool, Ordering};
use std::time::{Duration, Instant};

use shared_types::{FrameHeader, SensorEnd, Timestamp, WorldSettings, PROTOCOL_VERSION};
use simbus_transport::stamps::{self, Stage};
use tracing::{debug_span, info};

use crate::batches::Batches;
use crate::clock::{platform_timestamp, Clock, SubstepPlan};
use crate::config::ServerConfig;
use crate::control::Control;
use crate::error::PortError;
use crate::journal::Journal;
use crate::liveness::{LiveProcesses, PidWatch};
use crate::lockstep::Lockstep;
use crate::ports::Transport;
use crate::publication::Publication;
use crate::recorder::{Recorder, RecorderPort};
use crate::replayer::{ReplayFrame, Replayer};
use crate::scene::Scene;
use crate::sensors::Sensors;
use crate::state::Runtime;
use crate::ticker::Ticker;
use crate::timing::FrameTimings;
use crate::world::World;

/// What a finished run did.
#[derive(Debug, Clone, Copy, PartialEq)]
pub struct RunSummary {
    /// Frames computed (frame 0 is not computed, only published).
    pub frames: u64,
    /// Wall time from the first step to the last, in seconds.
    pub wall_seconds: f64,
    /// Simulation time at the end, in seconds.
    pub elapsed_seconds: f64,
}

impl RunSummary {
    /// Frames computed per wall-clock second.
    pub fn frames_per_second(&self) -> f64 {
        if self.wall_seconds > 0.0 {
            self.frames as f64 / self.wall_seconds
        } else {
            0.0
        }
    }
}

/// How often the server looks for dead clients and removes what they left.
const CLEANUP_PERIOD: Duration = Duration::from_secs(1);
/// The longest the server sleeps without looking at requests and signals.
const MAX_IDLE_WAIT: Duration = Duration::from_millis(50);
/// How often new subscribers are connected while no frame is sent.
const CONNECTION_PERIOD: Duration = Duration::from_millis(10);
/// How often the server checks that the ticker and the lockstep
/// participants still live (one node list for all of them) while one of
/// them has no pidfd to tell.
const LIVENESS_PERIOD: Duration = Duration::from_millis(100);
/// How soon after a ticker's death its port is cleaned up.
const SOON: Duration = Duration::from_millis(20);
/// The longest a polling server goes without every domain looking for
/// requests no client announced (a port that sends without ringing the
/// wake-up event, as raw iceoryx2 clients may).
const FULL_PASS_PERIOD: Duration = Duration::from_millis(1);
/// The least time between two pidfd probes of the watched processes.
const PROBE_SPACING: Duration = Duration::from_millis(1);

/// A running world: the control domain, which the loop sleeps on, and
/// every other domain.
#[derive(Debug)]
pub struct Server {
    control: Control,
    recorder: RecorderPort,
    domains: Domains,
}

/// Every domain but the two request ports whose answers concern all of
/// them (control, recorder): the loop hands their decoded calls here.
#[derive(Debug)]
struct Domains {
    config: ServerConfig,
    runtime: Runtime,
    transport: Transport,
    world: World,
    clock: Clock,
    publication: Publication,
    ticker: Ticker,
    batches: Batches,
    lockstep: Lockstep,
    sensors: Sensors,
    /// The shapes clients draw.
    debug: crate::debug_shapes::DebugShapes,
    recorder: Recorder,
    replayer: Replayer,
    timers: Timers,
    /// The journal, when the server keeps one.
    journal: Option<Journal>,
    /// The snapshots saved in memory.
    snapshots: crate::snapshots::Snapshots,
    /// Fast death notice of the ticker and the lockstep participants.
    pidwatch: PidWatch,
    /// Per-frame timings, only when a benchmark asked ([`Server::time_frames`]).
    timings: Option<FrameTimings>,
}

/// What a frame publishes: the world as computed, or a recorded frame.
#[derive(Debug, Clone, Copy)]
enum Outgoing<'a> {
    /// A computed frame, with its substeps and `FrameHeader` flags.
    Computed { substeps: u32, flags: u32 },
    /// A replayed frame, published as recorded.
    Replayed(&'a ReplayFrame),
}

/// When the periodic chores last ran.
#[derive(Debug)]
struct Timers {
    /// The last turn every domain looked for requests.
    full_pass: Instant,
    cleanup: Instant,
    liveness: Instant,
    connections: Instant,
    probe: Instant,
}

/// Refuses a keyframe interval a recording could not use (NaN, infinite,
/// zero or absurd): the library checks what the CLI's parser checks.
fn check_keyframe_seconds(seconds: Option<f64>) -> Result<(), ServerError> {
    use simbus_recording::{MAX_KEYFRAME_SECONDS, MIN_KEYFRAME_SECONDS};
    match seconds {
        Some(s) if !(MIN_KEYFRAME_SECONDS..=MAX_KEYFRAME_SECONDS).contains(&s) => {
            Err(ServerError::KeyframeSeconds {
                seconds: s,
                min: MIN_KEYFRAME_SECONDS,
                max: MAX_KEYFRAME_SECONDS,
            })
        }
        _ => Ok(()),
    }
}

impl Server {
    /// From now on, times each computed frame, up to `capacity` frames (the
    /// room is reserved now): rapier's own step and the whole frame. For
    /// benchmarks; a server never asked reads no clock for it.
    pub fn time_frames(&mut self, capacity: usize) {
        self.domains.timings = Some(FrameTimings::new(capacity));
    }

    /// The frames timed since [`Server::time_frames`], if it was called.
    pub fn frame_timings(&self) -> Option<&FrameTimings> {
        self.domains.timings.as_ref()
    }

    /// Runs until `shutdown` is set or `max_frames` frames were computed.
    ///
    /// # Errors
    ///
    /// Returns [`ServerError::Port`] if iceoryx2 fails while the server takes
    /// requests, steps or publishes a frame (a port it can no longer use). A
    /// client's bad request is answered with a refusal, not an error of the
    /// server.
    pub fn run(&mut self, shutdown: &AtomicBool) -> Result<RunSummary, ServerError> {
        let started = Instant::now();
        let first_frame = self.domains.runtime.frames_computed;
        while !shutdown.load(Ordering::Relaxed) {
            let d = &self.domains;
            if d.config
                .max_frames
                .is_some_and(|max| d.runtime.frames_computed - first_frame >= max)
            {
                break;
            }
            let answered = self.answer_requests()?;
            let d = &mut self.domains;
            let now = Instant::now();
            if !d.ticker.has_pending() {
                // No tick waits: nothing is held up (any more).
                d.lockstep.stepped();
            }
            if d.runtime.settings.synchronous_mode {
                self.synchronous_turn(now, answered)?;
            } else {
                self.asynchronous_turn(now, answered)?;
            }
        }
        let d = &mut self.domains;
        let reason = if shutdown.load(Ordering::Relaxed) {
            "server stopped by a signal"
        } else {
            "server stopped"
        };
        d.recorder.stop(reason, d.clock.frame());
        if let Some(journal) = &mut d.journal {
            journal.close(reason, d.clock.frame());
        }
        // Readers of the sensors learn why their stream ended.
        d.sensors
            .end_all(SensorEnd::ServerStopped, d.clock.frame(), d.runtime.episode);
        // What clients that died since the last sweep left behind goes now,
        // not at the next server's start.
        d.remove_dead_clients();
        let summary = RunSummary {
            frames: d.runtime.frames_computed - first_frame,
            wall_seconds: started.elapsed().as_secs_f64(),
            elapsed_seconds: Timestamp {
                elapsed_ns: d.clock.elapsed_ns(),
                ..Default::default()
            }
            .elapsed_seconds(),
        };
        info!(
            frames = summary.frames,
            fps = format_args!("{:.1}", summary.frames_per_second()),
            "server stopped"
        );
        Ok(summary)
    }
}

impl Domains {
    /// Computes and publishes the next frame, answers the first `ticks`
    /// waiting steps with it, then wakes waiting clients.
    fn step_frame(&mut self, now: Instant, ticks: usize) -> Result<(), ServerError> {
        if self.replayer.is_running() {
            return self.replay_frame(now, ticks);
        }
        let started = self.timings.as_ref().map(|_| Instant::now());
        let delta_ns = self.clock.next_delta_ns(&self.runtime.settings, now);
        let plan = SubstepPlan::new(delta_ns, &self.runtime.settings);
        let frame = self.clock.frame() + 1;
        let _span = debug_span!("frame", frame, delta_ns, substeps = plan.count).entered();
        self.runtime.warn_if_unreliable(frame, delta_ns, &plan, now);
        stamps::stamp(Stage::StepBegin, frame);
        let mut physics = Duration::ZERO;
        let timed = started.map(|_| &mut physics);
        self.world.watch_contacts = self.sensors.watch_contacts();
        self.world
            .step_timed(&plan, self.recorder.collisions(), timed);
        if let (Some(timings), Some(started)) = (&mut self.timings, started) {
            timings.record(started, physics);
        }
        stamps::stamp(Stage::StepEnd, frame);
        self.clock.advance(delta_ns, now);
        self.runtime.frames_computed += 1;
        let flags = FrameHeader::STEPPED
            | if plan.capped {
                FrameHeader::SUBSTEPS_CAPPED
            } else {
                0
            }
            | if plan.clamped {
                FrameHeader::PHYSICS_CLAMPED
            } else {
                0
            };
        self.finish_frame(
            Outgoing::Computed {
                substeps: plan.count,
                flags,
            },
            ticks,
        )?;
        if ticks == 0 && self.runtime.pacer.paces(&self.runtime.settings) {
            // A paced frame no tick asked for: the loop sleeps until the
            // next one anyway. On a CPU it shares with a client waiting for
            // this frame, the client runs now rather than after the rest of
            // this turn (a woken waiter does not preempt the server; a
            // ticker, woken by its answer, does).
            std::thread::yield_now();
        }
        Ok(())
    }

    /// The tail every frame shares, computed or replayed: the sensors
    /// capture it, it is published (a computed one recorded and journaled
    /// too), the first `ticks` waiting steps are answered with it, and
    /// waiting clients wake.
    fn finish_frame(&mut self, outgoing: Outgoing<'_>, ticks: usize) -> Result<(), PortError> {
        let frame = self.clock.frame();
        // Sensors first: whoever sees the frame's snapshot (or hears the
        // tick is done) finds its captures already queued. A replayed
        // frame's captures are not recorded again.
        self.debug.stepped(frame, self.clock.elapsed_ns());
        let captures = match outgoing {
            Outgoing::Computed { .. } => self.recorder.captures(),
            Outgoing::Replayed(_) => None,
        };
        self.sensors.capture(
            &self.world,
            self.runtime.scene.name(),
            (frame, self.clock.elapsed_ns(), self.runtime.episode),
            captures,
        );
        match outgoing {
            Outgoing::Computed { substeps, flags } => self.publish(substeps, flags)?,
            Outgoing::Replayed(replayed) => {
                let header = self.replayed_header(replayed);
                self.publication.publish_states(header, &replayed.actors)?;
                self.recorder.published(&header);
            }
        }
        stamps::stamp(Stage::Published, frame);
        self.ticker
            .answer_stepped(ticks, &self.clock, self.runtime.settings.synchronous_mode);
        stamps::stamp(Stage::Answered, frame);
        self.publication.notify()?;
        stamps::stamp(Stage::Notified, frame);
        Ok(())
    }

    /// Publishes the current frame (and records it while recording).
    fn publish(&mut self, physics_substeps: u32, flags: u32) -> Result<(), PortError> {
        let header = self.frame_header(physics_substeps, flags);
        self.publication.publish(header, &self.world)?;
        self.recorder.published(&header);
        if self.recorder.is_recording() {
            self.recorder.draw(self.debug.live());
            self.recorder
                .frame(&header, &self.world, &self.runtime.scene);
        }
        if let Some(journal) = &mut self.journal {
            // Durable (as the policy says) before any tick is answered.
            journal.frame(
                &header,
                &self.world,
                &self.runtime.scene,
                &self.runtime.settings,
            );
        }
        Ok(())
    }

    /// Hands the sensors' spawns and ends since last asked to the
    /// recording and the journal.
    fn note_sensors(&mut self) {
        let notes: Vec<_> = self.sensors.take_journal().collect();
        if notes.is_empty() {
            return;
        }
        if let Some(journal) = &mut self.journal {
            journal.recorder().sensor_notes(notes.iter().copied());
        }
        self.recorder.sensor_notes(notes);
    }

    /// The header of the current frame.
    fn frame_header(&self, physics_substeps: u32, flags: u32) -> FrameHeader {
        let mut header = FrameHeader {
            protocol_version: PROTOCOL_VERSION,
            actor_count: self.world.actor_count() as u32,
            episode: self.runtime.episode,
            timestamp: Timestamp {
                frame: self.clock.frame(),
                elapsed_ns: self.clock.elapsed_ns(),
                delta_ns: self.clock.delta_ns(),
                platform_timestamp: platform_timestamp(),
            },
            settings: self.runtime.settings.into(),
            physics_substeps,
            flags,
            first_actor_id: self.world.first_id(),
            server_pid: shared_types::this_process_id(),
            sensor_rays: self.sensors.rays(),
            recorded_frame: 0,
            recorded_elapsed_ns: 0,
        };
        self.restored_fields(&mut header);
        header
    }

    /// Replaces the world with `scene`'s initial state as a new episode,
    /// starting again at frame 0; settings are kept unless `reset`. The old
    /// episode's sensors end; actor ids go on from the old episode's.
    fn load_world(
        &mut self,
        scene: Scene,
        reset: bool,
        pid: u32,
        now: Instant,
    ) -> Result<(), ServerError> {
        if scene != self.runtime.scene {
            // A new map ends the recording, as in CARLA; a reload is recorded.
            self.recorder.stop("load", self.clock.frame());
        }
        if self.replayer.is_running() {
            self.replayer.end(
                shared_types::ReplayState::Stopped,
                "the world was loaded".to_string(),
            );
        }
        self.replayer.saved = None;
        self.sensors.end_all(
            SensorEnd::EpisodeEnded,
            self.clock.frame(),
            self.runtime.episode,
        );
        self.note_sensors();
        let first_id = self.world.next_id();
        self.world = World::new(&scene.placements(self.config.seed), first_id);
        self.runtime.scene = scene;
        self.clock = Clock::new(now);
        self.runtime.episode += 1;
        self.debug.new_episode();
        self.runtime.source_offset = None;
        self.runtime.pacer.reset();
        self.lockstep.new_episode();
        if reset {
            self.runtime.settings = WorldSettings::default();
        }
        info!(
            pid,
            %scene,
            episode = self.runtime.episode,
            actors = self.world.actor_count(),
            "world loaded: {}",
            self.runtime.settings
        );
        self.record_episode(reset);
        self.publish(0, 0)?;
        Ok(self.publication.notify()?)
    }

    /// How long the loop may sleep (at most `wanted`): while processes are
    /// watched, short enough to probe them every [`PidWatch::PROBE_PERIOD`].
    fn idle_limit(&self, wanted: Duration) -> Duration {
        let limit = if self.pidwatch.is_idle() {
            MAX_IDLE_WAIT
        } else if self.ticker.has_standby() {
            // A standby waits for the ticker's death: notice it sooner.
            PROBE_SPACING
        } else {
            PidWatch::PROBE_PERIOD
        };
        wanted.min(limit)
    }

    /// Every 10 ms: connect new subscribers. Every millisecond at most: has
    /// the ticker or a participant exited (their pidfds)? If so, and every
    /// 100 ms for one without a pidfd: do they live (one node list for
    /// all)? Once a second
    /// (sooner after a ticker died): remove what dead clients left in the
    /// services. Returns whether waiting ticks were answered (their ticker
    /// died).
    fn housekeeping(&mut self) -> bool {
        if self.timers.connections.elapsed() >= CONNECTION_PERIOD {
            self.timers.connections = Instant::now();
            self.publication.connect_new_subscribers();
        }
        // The processes the world waits on: a pidfd probe at most every
        // millisecond (the loop may spin), a node-list sweep when one
        // exited, and every 100 ms while one has no pidfd.
        let mut exited = false;
        let mut answered = false;
        if self.timers.probe.elapsed() >= PROBE_SPACING {
            self.timers.probe = Instant::now();
            let watched = self
                .ticker
                .owner_pid()
                .into_iter()
                .chain(self.lockstep.pids());
            self.pidwatch.watch(watched);
            exited = !self.pidwatch.exited().is_empty();
        }
        // The periodic sweep only covers what the pidfds do not: a
        // process without one, or one that exited but is still listed.
        let periodic =
            !self.pidwatch.covers_all() && self.timers.liveness.elapsed() >= LIVENESS_PERIOD;
        if (self.ticker.owner_pid().is_some() || !self.lockstep.is_empty()) && (exited || periodic)
        {
            self.timers.liveness = Instant::now();
            let sweep = LiveProcesses::now();
            let dropped = self.ticker.drop_if_dead(
                &sweep,
                &mut self.runtime,
                self.config.on_ticker_loss,
                &self.clock,
            );
            answered = dropped;
            if dropped {
                // Free the dead ticker's port soon, not before the requests
                // already waiting (a new ticker's claim) are answered.
                let now = Instant::now();
                self.timers.cleanup = now.checked_sub(CLEANUP_PERIOD - SOON).unwrap_or(now);
            }
            self.lockstep.drop_dead(&sweep, self.clock.frame());
        }
        if self.timers.cleanup.elapsed() >= CLEANUP_PERIOD {
            self.timers.cleanup = Instant::now();
            self.remove_dead_clients();
        }
        answered
    }

    /// Removes what dead client processes left in shared memory and in
    /// iceoryx2's directories.
    fn remove_dead_clients(&self) {
        let cleanup = self.transport.node.try_cleanup_dead_nodes();
        if cleanup.cleanups > 0 {
            info!(
                removed = cleanup.cleanups,
                "removed resources of dead clients"
            );
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn a_keyframe_interval_a_recording_cannot_use_is_refused_by_the_library() {
        for bad in [f64::NAN, f64::INFINITY, -1.0, 0.0, 1e300] {
            let error = check_keyframe_seconds(Some(bad)).unwrap_err();
            assert!(
                error.to_string().contains("--keyframe-seconds"),
                "{bad}: {error}"
            );
        }
        for good in [None, Some(0.001), Some(10.0), Some(1e9)] {
            check_keyframe_seconds(good).unwrap();
        }
    }
}
