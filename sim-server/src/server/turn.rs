//! One turn of the server's loop: every domain answers what arrived, then
//! a frame is stepped when it is due (or ticked), or the loop polls or
//! sleeps as the wait mode says.

use std::time::Instant;

use shared_types::{Doorbell, FixedText, WaitMode};

use super::error::ServerError;
use super::{Domains, Server, FULL_PASS_PERIOD, MAX_IDLE_WAIT};
use crate::batches::BatchEffect;
use crate::control::Rung;
use crate::ticker::Ticker;

impl Domains {
    /// The batch domain answers what arrived: applied now, queued for the
    /// next tick, or refused while a replay runs.
    fn answer_batches(&mut self) -> Result<(), ServerError> {
        if self.replayer.is_running() {
            return Ok(self.batches.refuse_while_replaying(&self.clock)?);
        }
        let (frame, episode) = (self.clock.frame(), self.runtime.episode);
        let ticker_pid = self.ticker.owner_pid();
        let (recorder, ticker) = (&mut self.recorder, &mut self.ticker);
        let journal = &mut self.journal;
        let applied =
            self.batches.handle(
                &mut self.world,
                ticker_pid,
                &self.clock,
                |effect| match effect {
                    BatchEffect::Applied(command, result) => {
                        recorder.command(frame + 1, episode, command, result);
                        if let Some(journal) = journal {
                            journal
                                .recorder()
                                .command(frame + 1, episode, command, result);
                        }
                    }
                    BatchEffect::Tick(request, results) => ticker.queue_batch(request, results),
                },
            )?;
        if applied {
            self.sensors.end_orphans(&self.world, frame, episode);
        }
        Ok(())
    }
}

impl Server {
    /// Every domain whose doorbell rang answers what arrived, in this
    /// order. Returns whether a client announced a request or an answer
    /// went out late: the frame-ready event then rings before the loop
    /// waits (a frame stepped now rings it anyway), so clients waiting on
    /// it for an answer (the Zenoh exporter) wake, and a tick's round trip
    /// costs one ring.
    ///
    /// A client rings its service's doorbell on the wake-up event after each
    /// request: while nothing rang, a polling server looks at one word
    /// instead of every domain's ports, a tick is taken without looking at
    /// the other services, and every [`FULL_PASS_PERIOD`] all of them are
    /// looked at anyway.
    pub(super) fn answer_requests(&mut self) -> Result<bool, ServerError> {
        let d = &mut self.domains;
        let mut rung = self.control.take_rung()?;
        let mut answered = rung.any();
        if d.timers.full_pass.elapsed() >= FULL_PASS_PERIOD {
            d.timers.full_pass = Instant::now();
            rung = Rung::ALL;
        } else if !answered {
            return Ok(false);
        }
        if rung.has(Doorbell::Control) {
            self.control.handle(|call| d.answer_control(call))?;
        }
        if let Some(response) = d.replay_prepared() {
            self.recorder.answer_replay(response);
            answered = true;
        }
        if rung.has(Doorbell::Recorder) {
            self.recorder
                .handle(|call, client_pid| d.answer_recorder(call, client_pid))?;
        }
        if rung.has(Doorbell::Batch) {
            d.answer_batches()?;
        }
        if rung.has(Doorbell::Lockstep) {
            d.lockstep.handle(d.runtime.episode, &d.clock)?;
        }
        if rung.has(Doorbell::Sensors) {
            let follow = d.replayer.follow_id();
            d.sensors
                .handle(&d.transport, &d.world, &d.clock, d.runtime.episode, follow)?;
        }
        d.note_sensors();
        if rung.has(Doorbell::Debug) {
            d.debug.handle(&d.clock)?;
        }
        if rung.has(Doorbell::Tick) {
            d.ticker.handle(&mut d.runtime, &d.clock)?;
        }
        Ok(answered | d.housekeeping())
    }

    /// Synchronous: one frame per tick, nothing without one, and not before
    /// every lockstep participant is done; otherwise poll or sleep as the
    /// wait mode says.
    pub(super) fn synchronous_turn(
        &mut self,
        now: Instant,
        mut answered: bool,
    ) -> Result<(), ServerError> {
        let d = &mut self.domains;
        let ticked = d.ticker.has_pending();
        if ticked && d.lockstep.all_done(d.clock.frame()) {
            d.ticker.drop_abandoned();
            if d.ticker.has_pending() {
                // A batch its client sent before this tick is in its queue
                // now, but a full pass may have looked at the batches just
                // before it came and at the ticks just after: take it now,
                // so it applies to this frame as sent, whatever the timing.
                d.answer_batches()?;
                d.lockstep.stepped();
                return d.step_frame(now, 1);
            }
            // The ticks were abandoned (their ticker is gone).
            return if answered {
                Ok(d.publication.notify()?)
            } else {
                Ok(())
            };
        }
        if ticked {
            let timeout = d.config.lockstep_timeout;
            if let Some(late) = d.lockstep.held_up(now, timeout, d.clock.frame()) {
                let frame = d.clock.frame();
                let name = FixedText::new(&late.name);
                let participant = Ticker::named(late.pid, name, frame);
                d.ticker.tell_held_up(participant, timeout, &d.clock);
                answered = true;
            }
        }
        if answered {
            d.publication.notify()?;
        }
        let polling = match d.config.wait_mode {
            WaitMode::Spin => true,
            WaitMode::Hybrid => d.clock.last_frame_at().elapsed() < d.config.hybrid_window,
            WaitMode::Block => false,
        };
        if polling && d.config.wait_mode == WaitMode::Hybrid {
            // Polls without keeping the ticker from running: on a CPU it
            // shares with the ticker, a spin would hold the tick back for
            // the whole window.
            std::thread::yield_now();
        } else if polling {
            std::hint::spin_loop();
        } else {
            self.control.wait_for_request(d.idle_limit(MAX_IDLE_WAIT))?;
        }
        Ok(())
    }

    /// Asynchronous: a frame when one is due (a tick just waits for it);
    /// until then, sleep, woken by requests.
    pub(super) fn asynchronous_turn(
        &mut self,
        now: Instant,
        answered: bool,
    ) -> Result<(), ServerError> {
        let d = &mut self.domains;
        let due = match d.replayer.next_frame_at(now) {
            Some(at) => Some(at),
            None => d
                .runtime
                .pacer
                .next_frame_at(&d.clock, &d.runtime.settings, now),
        };
        match due {
            Some(at) if at > now => {
                if answered {
                    d.publication.notify()?;
                }
                let until = at - now;
                let limit = d.idle_limit(until);
                if limit < until {
                    // Woken by requests; probes its watch on the way.
                    Ok(self.control.wait_for_request(limit)?)
                } else {
                    Ok(self.control.idle(until)?)
                }
            }
            _ => {
                if d.ticker.has_pending() {
                    d.ticker.drop_abandoned();
                }
                let ticks = d.ticker.pending_count();
                d.step_frame(now, ticks)
            }
        }
    }
}
