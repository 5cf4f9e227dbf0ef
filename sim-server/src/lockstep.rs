//! The lockstep domain: participants the server waits for, frame by frame,
//! in synchronous mode (CARLA's Traffic Manager, kept in step by the bus),
//! their service, and what happens to one that dies or hangs.

use iceoryx2::service::port_factory::PortFactory as _;
use simbus_transport::EarlierClients;
use std::time::{Duration, Instant};

use bytemuck::Zeroable;
use iceoryx2::identifiers::UniqueClientId;
use iceoryx2::port::server::Server as RequestServer;
use shared_types::limits::WorldLimits;
use shared_types::{
    FixedText, LockstepKind, LockstepRequest, LockstepResponse, ParticipantStatus, ResponseStatus,
    MAX_LOCKSTEP_WINDOW, PROTOCOL_VERSION, REPORTED_PARTICIPANTS,
};
use simbus_transport::Bus;
use tracing::{debug, info, warn};

use crate::clock::Clock;
use crate::error::PortError;
use crate::liveness::LiveProcesses;
use crate::ports::{sender_pid, Transport};

/// A tick held up by a participant this long is told which one, and how
/// long the server will wait for it, so the ticker's own timeout can wait
/// that long too.
const WAIT_NOTICE_AFTER: Duration = Duration::from_millis(200);

type LockstepServer = RequestServer<Bus, LockstepRequest, (), LockstepResponse, ()>;

/// The lockstep service and its participants.
#[derive(Debug)]
pub(crate) struct Lockstep {
    port: LockstepServer,
    /// The previous server's clients (their requests are dropped).
    earlier: EarlierClients,
    participants: Participants,
    /// Since when a tick waits for participants.
    waiting_since: Option<Instant>,
    /// Whether the waiting tick was told which participant it waits for.
    told: bool,
}

impl Lockstep {
    /// Opens the lockstep service.
    pub(crate) fn open(transport: &Transport, limits: &WorldLimits) -> Result<Self, PortError> {
        let service = transport
            .services
            .lockstep
            .open_or_create(&transport.node, limits)
            .map_err(|e| PortError::transport("lockstep service", e))?;
        let earlier = EarlierClients::of(service.dynamic_config());
        let port = service
            .server_builder()
            .create()
            .map_err(|e| PortError::transport("lockstep server", e))?;
        Ok(Self {
            port,
            earlier,
            participants: Participants::default(),
            waiting_since: None,
            told: false,
        })
    }

    /// How many participants there are.
    pub(crate) fn len(&self) -> usize {
        self.participants.len()
    }

    /// Whether there are none.
    pub(crate) fn is_empty(&self) -> bool {
        self.participants.is_empty()
    }

    /// Whether every participant is done far enough for the world to step
    /// past `frame`: with frame `frame − window` (each its own window).
    pub(crate) fn all_done(&self, frame: u64) -> bool {
        self.participants.all_done(frame)
    }

    /// A new episode starts at frame 0: everyone must report it anew.
    pub(crate) fn new_episode(&mut self) {
        self.participants.new_episode();
    }

    /// Joins, leaves and "done with frame N" of participants. A "done"
    /// from a client that is not (or no longer) a participant is answered
    /// `NotParticipant`, so a dropped one learns it.
    pub(crate) fn handle(&mut self, episode: u64, clock: &Clock) -> Result<(), PortError> {
        while let Some(request) = self
            .port
            .receive()
            .map_err(|e| PortError::transport("lockstep receive", e))?
        {
            if self.earlier.sent(request.header()) {
                debug!("dropped a request from a client of the previous server");
                continue;
            }
            let payload: LockstepRequest = *request.payload();
            let origin = request.origin();
            // Watched for liveness: the port's process, not the payload's word.
            let pid = sender_pid(request.header());
            let status = if payload.protocol_version != PROTOCOL_VERSION {
                ResponseStatus::ProtocolMismatch
            } else {
                match LockstepKind::from_u32(payload.kind) {
                    Some(LockstepKind::Join) if payload.window > MAX_LOCKSTEP_WINDOW => {
                        info!(
                            pid,
                            window = payload.window,
                            "lockstep join refused: window too large"
                        );
                        ResponseStatus::Refused
                    }
                    Some(LockstepKind::Join) => {
                        let name = payload.name.to_string_lossy();
                        let (window, frame) = (payload.window, clock.frame());
                        info!(pid, %name, frame, window, "lockstep participant joined");
                        self.participants.join(origin, pid, name, window, frame);
                        ResponseStatus::Ok
                    }
                    Some(LockstepKind::Leave) => {
                        if self.participants.leave(origin) {
                            info!(pid, "lockstep participant left");
                        }
                        ResponseStatus::Ok
                    }
                    Some(LockstepKind::Done) if !self.participants.contains(origin) => {
                        // Dropped (hung past the timeout) or never joined.
                        ResponseStatus::NotParticipant
                    }
                    Some(LockstepKind::Done) => {
                        // A "done" for an earlier episode means nothing now.
                        if payload.episode == episode {
                            // Timed only for the frame now current (whose
                            // publication time the clock holds).
                            let after = (payload.frame == clock.frame())
                                .then(|| clock.last_frame_at().elapsed());
                            self.participants.done(origin, payload.frame, after);
                        }
                        ResponseStatus::Ok
                    }
                    None => ResponseStatus::UnknownRequest,
                }
            };
            let response = LockstepResponse {
                protocol_version: PROTOCOL_VERSION,
                status: status as u32,
                frame: clock.frame(),
                episode,
            };
            if let Err(e) = request.send_copy(response) {
                debug!("lockstep response not delivered: {e:?}");
            }
        }
        Ok(())
    }

    /// A tick waits for participants at `now`: after [`WAIT_NOTICE_AFTER`]
    /// returns (once) the participant it waits for, whom the ticker is to
    /// be told of; after `timeout` the late ones are dropped (a hung reader
    /// must not stop the world).
    pub(crate) fn held_up(
        &mut self,
        now: Instant,
        timeout: Duration,
        frame: u64,
    ) -> Option<Participant> {
        let since = *self.waiting_since.get_or_insert(now);
        let waited = now.duration_since(since);
        if waited >= timeout {
            self.waiting_since = None;
            self.told = false;
            for late in self.participants.drop_not_done(frame) {
                warn!(
                    pid = late.pid,
                    name = %late.name,
                    frame,
                    ?timeout,
                    "lockstep participant did not report done in time; no longer waiting for it"
                );
            }
            return None;
        }
        if self.told || waited < WAIT_NOTICE_AFTER {
            return None;
        }
        self.told = true;
        let late = self.participants.first_not_done(frame)?;
        info!(
            pid = late.pid,
            name = %late.name,
            frame,
            "a tick waits for a lockstep participant"
        );
        Some(late.clone())
    }

    /// The world stepped: no tick waits any more.
    pub(crate) fn stepped(&mut self) {
        self.waiting_since = None;
        self.told = false;
    }

    /// The first participants as the status report describes them, at
    /// `frame` (the latest published).
    pub(crate) fn statuses(&self, frame: u64) -> [ParticipantStatus; REPORTED_PARTICIPANTS] {
        let mut statuses = [ParticipantStatus::zeroed(); REPORTED_PARTICIPANTS];
        for (status, p) in statuses.iter_mut().zip(&self.participants.list) {
            *status = ParticipantStatus {
                pid: p.pid,
                window: p.window as u32,
                done_frame: p.done.unwrap_or(0),
                lag: p
                    .done
                    .map_or(ParticipantStatus::NOT_YET, |d| frame.saturating_sub(d)),
                done_after_ns: p.done_after.map_or(ParticipantStatus::NOT_YET, |d| {
                    u64::try_from(d.as_nanos()).unwrap_or(u64::MAX - 1)
                }),
                name: FixedText::new(&p.name),
            };
        }
        statuses
    }

    /// The participants' processes.
    pub(crate) fn pids(&self) -> impl Iterator<Item = u32> + Clone + '_ {
        self.participants.list.iter().map(|p| p.pid)
    }

    /// Drops the participants whose process died (by `sweep`).
    pub(crate) fn drop_dead(&mut self, sweep: &LiveProcesses, frame: u64) {
        for dead in self.participants.drop_dead(|pid| sweep.alive(pid)) {
            warn!(
                pid = dead.pid,
                name = %dead.name,
                frame,
                "lockstep participant died; no longer waiting for it"
            );
        }
    }
}

/// One participant and the last frame it reported done in this episode.
#[derive(Debug, Clone, PartialEq)]
pub(crate) struct Participant {
    /// Its port on the lockstep service.
    pub client: UniqueClientId,
    /// Its process.
    pub pid: u32,
    /// Its name, for logs.
    pub name: String,
    /// How many frames the world may run ahead of its last "done".
    pub window: u64,
    /// The frame current when it joined (0 from a new episode on): it is
    /// done with every frame before it.
    pub joined_at: u64,
    /// The last frame of the current episode it is done with.
    pub done: Option<u64>,
    /// How long after its frame's publication that "done" came, when it
    /// was for the frame then current.
    pub done_after: Option<Duration>,
}

impl Participant {
    /// Whether the world may step past `frame` as far as this participant
    /// goes (see [`lets_step_past`]).
    fn lets_step_past(&self, frame: u64) -> bool {
        lets_step_past(self.window, self.joined_at, self.done, frame)
    }
}

/// Whether a participant with `window` that joined at frame `joined_at`
/// and is `done` with that frame lets the world step past `frame`: it is
/// done with frame `frame − window` (every frame before the one it joined
/// at counts as done; with no such frame to be done with, it lets it).
fn lets_step_past(window: u64, joined_at: u64, done: Option<u64>, frame: u64) -> bool {
    let Some(needed) = frame.checked_sub(window) else {
        return true;
    };
    let finished = done.or(joined_at.checked_sub(1));
    finished.is_some_and(|f| f >= needed)
}

#[cfg(test)]
mod tests {
    use super::lets_step_past;

    #[test]
    fn without_a_window_every_frame_waits_for_its_done() {
        // Joined at 7: the step past 7 waits for done(7), and so on.
        assert!(!lets_step_past(0, 7, None, 7));
        assert!(lets_step_past(0, 7, Some(7), 7));
        assert!(!lets_step_past(0, 7, Some(7), 8));
        // A new episode: joined at 0, nothing done yet.
        assert!(!lets_step_past(0, 0, None, 0));
        assert!(lets_step_past(0, 0, Some(0), 0));
    }

    #[test]
    fn a_window_of_three_lets_the_world_run_three_frames_past_its_last_done() {
        // Done with 10: steps past 10, 11, 12 and 13 need nothing more; the
        // step past 14 needs done(11).
        for frame in 10..=13 {
            assert!(lets_step_past(3, 5, Some(10), frame), "{frame}");
        }
        assert!(!lets_step_past(3, 5, Some(10), 14));
        assert!(lets_step_past(3, 5, Some(11), 14));
        // Joined at 20 with nothing done: done with 19 by joining.
        assert!(lets_step_past(3, 20, None, 22));
        assert!(!lets_step_past(3, 20, None, 23));
        // From a new episode's frame 0: frames 0..=2 need nothing.
        assert!(lets_step_past(3, 0, None, 2));
        assert!(!lets_step_past(3, 0, None, 3));
    }
}

/// Every participant of a world.
#[derive(Debug, Default)]
struct Participants {
    list: Vec<Participant>,
}

impl Participants {
    /// How many participants there are.
    pub(crate) fn len(&self) -> usize {
        self.list.len()
    }

    /// Whether there are none.
    pub(crate) fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// Adds `client` at `frame` with `window`: it must report done for
    /// frame N − window before the world steps past N. Joining twice
    /// changes nothing.
    pub(crate) fn join(
        &mut self,
        client: UniqueClientId,
        pid: u32,
        name: String,
        window: u32,
        frame: u64,
    ) {
        if !self.list.iter().any(|p| p.client == client) {
            self.list.push(Participant {
                client,
                pid,
                name,
                window: u64::from(window),
                joined_at: frame,
                done: None,
                done_after: None,
            });
        }
    }

    /// Whether `client` is a participant.
    pub(crate) fn contains(&self, client: UniqueClientId) -> bool {
        self.list.iter().any(|p| p.client == client)
    }

    /// Removes `client`; `false` if it was not a participant.
    pub(crate) fn leave(&mut self, client: UniqueClientId) -> bool {
        let before = self.list.len();
        self.list.retain(|p| p.client != client);
        self.list.len() != before
    }

    /// Records that `client` is done with `frame`; `false` if unknown.
    pub(crate) fn done(
        &mut self,
        client: UniqueClientId,
        frame: u64,
        after: Option<Duration>,
    ) -> bool {
        match self.list.iter_mut().find(|p| p.client == client) {
            Some(p) => {
                p.done = Some(p.done.map_or(frame, |done| done.max(frame)));
                p.done_after = after;
                true
            }
            None => false,
        }
    }

    /// Whether every participant lets the world step past `frame`.
    pub(crate) fn all_done(&self, frame: u64) -> bool {
        self.list.iter().all(|p| p.lets_step_past(frame))
    }

    /// The first participant that holds the world at `frame`.
    pub(crate) fn first_not_done(&self, frame: u64) -> Option<&Participant> {
        self.list.iter().find(|p| !p.lets_step_past(frame))
    }

    /// A new episode starts at frame 0: everyone must report it anew.
    pub(crate) fn new_episode(&mut self) {
        for p in &mut self.list {
            p.done = None;
            p.joined_at = 0;
        }
    }

    /// Removes and returns the participants that hold the world at `frame`.
    pub(crate) fn drop_not_done(&mut self, frame: u64) -> Vec<Participant> {
        let (late, done) = self.list.drain(..).partition(|p| !p.lets_step_past(frame));
        self.list = done;
        late
    }

    /// Removes and returns the participants whose process died.
    pub(crate) fn drop_dead(&mut self, alive: impl Fn(u32) -> bool) -> Vec<Participant> {
        let (dead, living) = self.list.drain(..).partition(|p| !alive(p.pid));
        self.list = living;
        dead
    }
}
