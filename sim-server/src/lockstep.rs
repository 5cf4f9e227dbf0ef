//! Lockstep participants: clients the server waits for, frame by frame, in
//! synchronous mode (CARLA's Traffic Manager, kept in step by the bus).

use iceoryx2::identifiers::UniqueClientId;

/// One participant and the last frame it reported done in this episode.
#[derive(Debug, Clone, PartialEq)]
pub struct Participant {
    /// Its port on the lockstep service.
    pub client: UniqueClientId,
    /// Its process.
    pub pid: u32,
    /// Its name, for logs.
    pub name: String,
    /// The last frame of the current episode it is done with.
    pub done: Option<u64>,
}

/// Every participant of a world.
#[derive(Debug, Default)]
pub struct Participants {
    list: Vec<Participant>,
}

impl Participants {
    /// How many participants there are.
    pub fn len(&self) -> usize {
        self.list.len()
    }

    /// Whether there are none.
    pub fn is_empty(&self) -> bool {
        self.list.is_empty()
    }

    /// Adds `client`; it must report done for the current frame before the
    /// next step. Joining twice changes nothing.
    pub fn join(&mut self, client: UniqueClientId, pid: u32, name: String) {
        if !self.list.iter().any(|p| p.client == client) {
            self.list.push(Participant {
                client,
                pid,
                name,
                done: None,
            });
        }
    }

    /// Whether `client` is a participant.
    pub fn contains(&self, client: UniqueClientId) -> bool {
        self.list.iter().any(|p| p.client == client)
    }

    /// Removes `client`; `false` if it was not a participant.
    pub fn leave(&mut self, client: UniqueClientId) -> bool {
        let before = self.list.len();
        self.list.retain(|p| p.client != client);
        self.list.len() != before
    }

    /// Records that `client` is done with `frame`; `false` if unknown.
    pub fn done(&mut self, client: UniqueClientId, frame: u64) -> bool {
        match self.list.iter_mut().find(|p| p.client == client) {
            Some(p) => {
                p.done = Some(p.done.map_or(frame, |done| done.max(frame)));
                true
            }
            None => false,
        }
    }

    /// Whether every participant is done with `frame`.
    pub fn all_done(&self, frame: u64) -> bool {
        self.list.iter().all(|p| p.done.is_some_and(|d| d >= frame))
    }

    /// The first participant not yet done with `frame`.
    pub fn first_not_done(&self, frame: u64) -> Option<&Participant> {
        self.list.iter().find(|p| p.done.is_none_or(|d| d < frame))
    }

    /// A new episode starts at frame 0: everyone must report it anew.
    pub fn new_episode(&mut self) {
        for p in &mut self.list {
            p.done = None;
        }
    }

    /// Removes and returns the participants not yet done with `frame`.
    pub fn drop_not_done(&mut self, frame: u64) -> Vec<Participant> {
        let (late, done) = self
            .list
            .drain(..)
            .partition(|p| p.done.is_none_or(|d| d < frame));
        self.list = done;
        late
    }

    /// Removes and returns the participants whose process died.
    pub fn drop_dead(&mut self, alive: impl Fn(u32) -> bool) -> Vec<Participant> {
        let (dead, living) = self.list.drain(..).partition(|p| !alive(p.pid));
        self.list = living;
        dead
    }
}
