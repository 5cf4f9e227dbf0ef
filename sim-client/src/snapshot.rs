//! One frame of the world as a client holds it: [`FrameView`] reads it in
//! place in shared memory (nothing copied); [`WorldSnapshot`] is an owned
//! copy (CARLA's `WorldSnapshot`, what `wait_for_tick` returns).

use iceoryx2::sample::Sample;
use shared_types::{frame_parts, ActorPose, ActorState, FrameHeader, Timestamp, WorldSettings};
use simbus_transport::Bus;

/// One frame read in place in shared memory: the header and the actors are
/// borrowed from the sample, not copied. The sample returns to the server's
/// pool when the view is dropped (a subscriber holds at most 4 at once).
pub struct FrameView {
    sample: Sample<Bus, [ActorState], FrameHeader>,
    missed: u64,
}

impl std::fmt::Debug for FrameView {
    fn fmt(&self, f: &mut std::fmt::Formatter<'_>) -> std::fmt::Result {
        f.debug_struct("FrameView")
            .field("header", self.header())
            .field("actors", &self.actors().len())
            .field("missed", &self.missed)
            .finish()
    }
}

impl FrameView {
    pub(crate) fn new(sample: Sample<Bus, [ActorState], FrameHeader>, missed: u64) -> Self {
        Self { sample, missed }
    }

    /// The frame header as the server wrote it.
    pub fn header(&self) -> &FrameHeader {
        self.sample.user_header()
    }

    /// Every actor, in id order, in place.
    pub fn actors(&self) -> &[ActorState] {
        frame_parts(self.sample.payload(), self.header().actor_count).0
    }

    /// Every actor's pose (id, kind, flags, position, rotation), in the
    /// order of [`FrameView::actors`], packed in place: half the bytes of
    /// the actors, so a reader that needs only where things are reads a
    /// large world twice as fast.
    pub fn poses(&self) -> &[ActorPose] {
        frame_parts(self.sample.payload(), self.header().actor_count).1
    }

    /// The frame's payload as it lies in shared memory: the actors, then
    /// their poses (`shared_types::frame_slice_len`).
    pub fn payload_bytes(&self) -> &[u8] {
        bytemuck::cast_slice(self.sample.payload())
    }

    /// Frames this client never saw before this one (see [`WorldSnapshot::missed`]).
    pub fn missed(&self) -> u64 {
        self.missed
    }

    /// The frame id.
    pub fn frame(&self) -> u64 {
        self.header().timestamp.frame
    }

    /// When the frame happened.
    pub fn timestamp(&self) -> &Timestamp {
        &self.header().timestamp
    }

    /// The episode (changes when the world is loaded or reloaded).
    pub fn episode(&self) -> u64 {
        self.header().episode
    }

    /// The settings the frame was computed with.
    pub fn settings(&self) -> WorldSettings {
        self.header().settings.into()
    }

    /// Whether physics advanced less than the frame's delta: the substep
    /// rule `clamp` (CARLA's) with a frame longer than `max_substeps *
    /// max_substep_delta_time` ([`FrameHeader::PHYSICS_CLAMPED`]).
    pub fn is_physics_clamped(&self) -> bool {
        self.header().is_physics_clamped()
    }

    /// The simulation seconds physics advanced in this frame: its delta,
    /// or less for a clamped frame ([`FrameView::is_physics_clamped`]).
    pub fn physics_seconds(&self) -> f64 {
        self.header().physics_seconds()
    }

    /// A replayed frame's id in the recording (see [`WorldSnapshot::recorded_frame`]).
    pub fn recorded_frame(&self) -> Option<u64> {
        self.header()
            .is_replay()
            .then_some(self.header().recorded_frame)
    }

    /// The frame's digest (see [`WorldSnapshot::digest`]).
    pub fn digest(&self) -> u64 {
        digest(self.header(), self.actors())
    }

    /// An owned copy.
    pub fn to_snapshot(&self) -> WorldSnapshot {
        WorldSnapshot {
            header: *self.header(),
            actors: self.actors().to_vec(),
            missed: self.missed,
        }
    }
}

/// The digest of a frame: its id, simulation time and every actor's state,
/// bit for bit (xxh3), with actor ids counted from the episode's first one,
/// so a reloaded world (whose actors get new ids) digests like a fresh server.
/// A replayed frame digests with the id and time it had in the recording
/// ([`FrameHeader::source_timestamp`]), so a replay digests like the run it
/// replays.
fn digest(header: &FrameHeader, actors: &[ActorState]) -> u64 {
    let t = &header.source_timestamp();
    let mut hasher = xxhash_rust::xxh3::Xxh3::new();
    hasher.update(&t.frame.to_le_bytes());
    hasher.update(&t.elapsed_ns.to_le_bytes());
    hasher.update(&t.delta_ns.to_le_bytes());
    let first = header.first_actor_id;
    for actor in actors {
        let relative = ActorState {
            id: actor.id.wrapping_sub(first),
            ..*actor
        };
        hasher.update(bytemuck::bytes_of(&relative));
    }
    hasher.digest()
}

/// The state of every actor at one frame, copied out of shared memory.
#[derive(Debug, Clone, PartialEq)]
pub struct WorldSnapshot {
    /// The frame header as the server wrote it.
    pub header: FrameHeader,
    /// Every actor, in id order.
    pub actors: Vec<ActorState>,
    /// Frames published between the previous snapshot this client received
    /// and this one that it never saw (always 0 for a reader that keeps up).
    /// From a client's first snapshot on, each next one is the frame after
    /// it or says how many frames lay between; a new episode's ids start
    /// again, so its first snapshot counts from there.
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

    /// Whether physics advanced less than the frame's delta (see
    /// [`FrameView::is_physics_clamped`]).
    pub fn is_physics_clamped(&self) -> bool {
        self.header.is_physics_clamped()
    }

    /// The simulation seconds physics advanced in this frame (see
    /// [`FrameView::physics_seconds`]).
    pub fn physics_seconds(&self) -> f64 {
        self.header.physics_seconds()
    }

    /// For a replayed frame, the id it had in the recording (its own
    /// [`WorldSnapshot::frame`] is the server's next id, as in CARLA: frame
    /// ids never go back); `None` for a live frame.
    pub fn recorded_frame(&self) -> Option<u64> {
        self.header
            .is_replay()
            .then_some(self.header.recorded_frame)
    }

    /// A 64-bit digest of the frame: its id, simulation time and every
    /// actor's state, bit for bit (xxh3), with actor ids counted from the
    /// episode's first actor id. Two runs that print the same
    /// digests frame after frame computed identical worlds. A replayed
    /// frame digests with its recorded id and time, like the frame it replays.
    pub fn digest(&self) -> u64 {
        digest(&self.header, &self.actors)
    }

    /// The actor with `id`, if it exists in this frame.
    pub fn find(&self, id: u64) -> Option<&ActorState> {
        self.actors
            .binary_search_by_key(&id, |a| a.id)
            .ok()
            .map(|i| &self.actors[i])
    }
}
