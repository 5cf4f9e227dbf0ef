//! A tick sent and answered later: [`Ticker::send_tick`], then
//! [`Ticker::poll_tick`] or [`Ticker::finish_tick`]. A client that ticks
//! many worlds sends every world's tick first and collects the answers
//! after, so the servers step at once instead of one after another.

use std::time::{Duration, Instant};

use shared_types::{ResponseStatus, TickRequest, TickResponse, TickerInfo};
use simbus_transport::stamps::{self, Stage};

use super::Ticker;
use crate::rpc::{Pending, Wait};
use crate::{RequestError, TickError};

/// A tick sent to the server and not yet answered (see [`Ticker::send_tick`]).
///
/// Dropping it forgets the answer; the frame is computed all the same.
#[derive(Debug)]
pub struct TickInFlight {
    pending: Pending<TickRequest, TickResponse>,
    started: Instant,
    sent: u64,
    deadline: Instant,
    waiting_for: Option<TickerInfo>,
}

impl TickInFlight {
    /// When the tick gives up waiting for its answer.
    pub fn deadline(&self) -> Instant {
        self.deadline
    }
}

impl Ticker {
    /// Asks for the next frame without waiting for it; its answer is
    /// collected by [`Ticker::poll_tick`] or [`Ticker::finish_tick`]
    /// within `timeout` of now.
    ///
    /// # Errors
    ///
    /// Returns [`TickError::Request`] if the request cannot be sent (the
    /// server's port is gone or full).
    pub fn send_tick(&mut self, timeout: Duration) -> Result<TickInFlight, TickError> {
        let started = Instant::now();
        let sent = stamps::began();
        let pending = self.port.send(self.tick_request)?;
        Ok(TickInFlight {
            pending,
            started,
            sent,
            deadline: started + timeout,
            waiting_for: None,
        })
    }

    /// The frame of `tick` if its answer has come (no waiting), or `None`.
    ///
    /// # Errors
    ///
    /// As [`Ticker::finish_tick`], once the answer says so or its deadline
    /// has passed.
    pub fn poll_tick(&mut self, tick: &mut TickInFlight) -> Result<Option<u64>, TickError> {
        loop {
            match self.port.try_answer(&tick.pending) {
                Ok(Some(response)) => match self.tick_answered(tick, response)? {
                    Some(frame) => return Ok(Some(frame)),
                    None => continue,
                },
                Ok(None) if Instant::now() < tick.deadline => {
                    if crate::process_alive(self.server_pid) {
                        return Ok(None);
                    }
                    let e = RequestError::ServerGone {
                        world: self.world.to_string(),
                        pid: self.server_pid,
                    };
                    return Err(self.ride_through(e.into()));
                }
                Ok(None) => return Err(self.tick_timed_out(tick)),
                Err(e) => return Err(self.ride_through(e.into())),
            }
        }
    }

    /// Waits for the answer to `tick` and returns its frame's id, as
    /// [`Ticker::tick`] does.
    ///
    /// # Errors
    ///
    /// The errors of [`Ticker::tick`]: [`TickError::Request`] with
    /// [`RequestError::Timeout`] past the tick's deadline or with
    /// [`RequestError::ServerGone`]; [`TickError::HeldUp`],
    /// [`TickError::NotTicker`], [`TickError::Revoked`] and
    /// [`TickError::Restarted`].
    pub fn finish_tick(&mut self, mut tick: TickInFlight) -> Result<u64, TickError> {
        loop {
            let remaining = tick.deadline.saturating_duration_since(Instant::now());
            let wait = Wait::for_mode(self.mode, &self.ready);
            match self.port.answer(&tick.pending, remaining, wait) {
                Ok(response) => {
                    if let Some(frame) = self.tick_answered(&mut tick, response)? {
                        return Ok(frame);
                    }
                }
                Err(RequestError::Timeout { .. }) => return Err(self.tick_timed_out(&tick)),
                Err(e) => return Err(self.ride_through(e.into())),
            }
        }
    }

    /// Takes an answer to `tick`: its frame, or `None` when the server said
    /// a lockstep participant holds it (the deadline then stretches).
    fn tick_answered(
        &mut self,
        tick: &mut TickInFlight,
        response: TickResponse,
    ) -> Result<Option<u64>, TickError> {
        if response.status == ResponseStatus::WaitingForParticipants as u32 {
            tick.deadline = tick.deadline.max(self.told_held_up(&response));
            tick.waiting_for = Some(response.waiting_for);
            return Ok(None);
        }
        let response = self.expect_ok(response).map_err(|e| self.ride_through(e))?;
        stamps::stamp_at(Stage::ClientSend, response.frame, tick.sent);
        stamps::stamp_wake(Stage::ClientWake, response.frame);
        self.last = Some((response.frame, response.elapsed_ns));
        Ok(Some(response.frame))
    }

    /// The error of `tick` past its deadline.
    fn tick_timed_out(&mut self, tick: &TickInFlight) -> TickError {
        match tick.waiting_for {
            Some(participant) => self.held_up(participant, tick.started),
            None => {
                let e = RequestError::Timeout {
                    world: self.world.to_string(),
                    timeout: tick.deadline.saturating_duration_since(tick.started),
                };
                self.ride_through(e.into())
            }
        }
    }
}
