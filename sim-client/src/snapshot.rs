//! [`WorldSnapshot`]: one frame of the world, as a client holds it.

use shared_types::{ActorState, FrameHeader, Timestamp, WorldSettings};

/// The state of every actor at one frame, copied out of shared memory.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldSnapshot {
    /// The frame header as the server wrote it.
    pub header: FrameHeader,
    /// Every actor, in id order.
    pub actors: Vec<ActorState>,
    /// Frames published between the previous snapshot this client received
    /// and this one that it never saw (always 0 for a reader that keeps up).
    pub missed: u64,
}

impl WorldSnapshot {
    /// The frame id.
    pub fn frame(&self) -> u64 {
        self.header.timestamp.frame
    }

    /// When the frame happened.
    pub fn timestamp(&self) -> &Timestamp {
        &self.header.timestamp
    }

    /// The episode (changes when the world is loaded or reloaded).
    pub fn episode(&self) -> u64 {
        self.header.episode
    }

    /// The settings the frame was computed with.
    pub fn settings(&self) -> WorldSettings {
        self.header.settings.into()
    }

    /// A 64-bit digest of the frame: its id, simulation time and every
    /// actor's state, bit for bit (xxh3), with actor ids counted from the
    /// episode's first actor id. Two runs that print the same
    /// digests frame after frame computed identical worlds.
    pub fn digest(&self) -> u64 {
        let t = self.timestamp();
        let mut hasher = xxhash_rust::xxh3::Xxh3::new();
        hasher.update(&t.frame.to_le_bytes());
        hasher.update(&t.elapsed_ns.to_le_bytes());
        hasher.update(&t.delta_ns.to_le_bytes());
        // Ids count from the episode's first one: a reloaded world (whose
        // actors get new ids) digests like a fresh server.
        let first = self.header.first_actor_id;
        for actor in &self.actors {
            let relative = ActorState {
                id: actor.id.wrapping_sub(first),
                ..*actor
            };
            hasher.update(bytemuck::bytes_of(&relative));
        }
        hasher.digest()
    }

    /// The actor with `id`, if it exists in this frame.
    pub fn find(&self, id: u64) -> Option<&ActorState> {
        self.actors
            .binary_search_by_key(&id, |a| a.id)
            .ok()
            .map(|i| &self.actors[i])
    }
}
