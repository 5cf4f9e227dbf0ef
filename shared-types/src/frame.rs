//! The frame snapshot: a [`FrameHeader`] user header and a slice of [`ActorState`].

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

use crate::wire::wire_enum;
use crate::{WireSettings, NANOS_PER_SECOND};

/// When a frame happened, in simulation time (integer nanoseconds) and wall time.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::Timestamp/1")]
pub struct Timestamp {
    /// Frame id: 0 is the initial state, each step adds one.
    pub frame: u64,
    /// Simulation time since the episode started, in nanoseconds.
    pub elapsed_ns: u64,
    /// Simulation time since the previous frame, in nanoseconds.
    pub delta_ns: u64,
    /// Wall-clock seconds since the Unix epoch when the frame was published.
    pub platform_timestamp: f64,
}

impl Timestamp {
    /// Simulation time since the episode started, in seconds.
    pub fn elapsed_seconds(&self) -> f64 {
        nanos_to_seconds(self.elapsed_ns)
    }

    /// Simulation time since the previous frame, in seconds.
    pub fn delta_seconds(&self) -> f64 {
        nanos_to_seconds(self.delta_ns)
    }
}

/// Nanoseconds as seconds, as every simbus timestamp reads them.
pub fn nanos_to_seconds(nanos: u64) -> f64 {
    // One correctly rounded division: exact to the nanosecond below 2^53 ns
    // (104 days), and 1_503_000_000 ns prints as 1.503, not 1.5030000000000001.
    nanos as f64 / NANOS_PER_SECOND as f64
}

/// The user header of every frame sample.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::FrameHeader/3")]
pub struct FrameHeader {
    /// [`crate::PROTOCOL_VERSION`] of the server that wrote the frame.
    pub protocol_version: u32,
    /// Number of [`ActorState`]s in the sample.
    pub actor_count: u32,
    /// Episode id: changes when the world is loaded or reloaded.
    pub episode: u64,
    /// When the frame happened.
    pub timestamp: Timestamp,
    /// The settings this frame was computed with.
    pub settings: WireSettings,
    /// How many physics steps computed this frame (0 for the initial frame).
    pub physics_substeps: u32,
    /// [`FrameHeader::SUBSTEPS_CAPPED`] and future flags.
    pub flags: u32,
    /// The first actor id of this episode. Ids are never reused within one
    /// server's life, so a reloaded scene's actors get new ids; the frame
    /// digest counts ids from this one, so a reload digests like a fresh
    /// server.
    pub first_actor_id: u64,
    /// The server's process id: a client that only reads frames watches it
    /// to notice the server's death.
    pub server_pid: u32,
    /// The rays the sensors cast for this frame (cameras of one parent,
    /// pose, size and field of view share one cast; saturates).
    pub sensor_rays: u32,
    /// A replayed frame ([`FrameHeader::REPLAY`]): the id the frame had in
    /// the recording (`timestamp.frame` is the server's own, next id: frame
    /// ids on the bus never go back). Zero for a live frame.
    pub recorded_frame: u64,
    /// A replayed frame: its simulation time in the recording, nanoseconds
    /// (`timestamp.elapsed_ns` is the server's own time, which goes on).
    /// Zero for a live frame.
    pub recorded_elapsed_ns: u64,
}

impl FrameHeader {
    /// Flag: the frame was longer than `max_substeps * max_substep_delta_time`,
    /// so its substeps were longer than `max_substep_delta_time`.
    pub const SUBSTEPS_CAPPED: u32 = 1;
    /// Flag: the frame is a replay of a recording (not computed live).
    pub const REPLAY: u32 = 2;
    /// Flag: under the substep rule `clamp` (CARLA's), physics advanced
    /// only `max_substeps * max_substep_delta_time`, less than the frame's
    /// delta ([`FrameHeader::physics_ns`] says how much).
    pub const PHYSICS_CLAMPED: u32 = 4;
    /// Flag: the frame was stepped — computed or replayed, in synchronous
    /// mode one per tick. A frame that a load, a reload or the end of a
    /// replay publishes at once has none (a tick answered by its frame
    /// takes only a stepped one).
    pub const STEPPED: u32 = 8;
    /// Flag: the frame goes on from a restored snapshot, whose line of
    /// frames it continues: `recorded_frame` is its id in that line (the
    /// frame after the snapshot's is the snapshot's frame plus one),
    /// `recorded_elapsed_ns` its time. It digests like the frame of the
    /// same id after the save.
    pub const RESTORED: u32 = 16;

    /// Whether physics advanced less than the frame's delta (the substep
    /// rule `clamp`, CARLA's).
    pub fn is_physics_clamped(&self) -> bool {
        self.flags & Self::PHYSICS_CLAMPED != 0
    }

    /// The simulation time physics advanced in this frame, in nanoseconds:
    /// the frame's delta, or for a [`FrameHeader::PHYSICS_CLAMPED`] frame
    /// `max_substeps * max_substep_delta_time` of its settings. Zero for the
    /// initial frame.
    pub fn physics_ns(&self) -> u64 {
        let delta_ns = self.timestamp.delta_ns;
        if !self.is_physics_clamped() {
            return delta_ns;
        }
        let s = crate::WorldSettings::from(self.settings);
        crate::SubstepRule::Clamp.physics_ns(
            delta_ns,
            s.substepping,
            s.max_substep_nanos(),
            s.max_substeps,
        )
    }

    /// [`FrameHeader::physics_ns`] in seconds.
    pub fn physics_seconds(&self) -> f64 {
        nanos_to_seconds(self.physics_ns())
    }

    /// Whether the frame is a replay of a recording.
    pub fn is_replay(&self) -> bool {
        self.flags & Self::REPLAY != 0
    }

    /// The frame's own identity: for a replayed frame the frame id and
    /// simulation time it had in the recording, for one that goes on from
    /// a restored snapshot its id in the snapshot's line, for a live one
    /// its timestamp's. A replay digests like the frames it replays, a
    /// restored world like the one saved.
    pub fn source_timestamp(&self) -> Timestamp {
        if self.is_replay() || self.flags & Self::RESTORED != 0 {
            Timestamp {
                frame: self.recorded_frame,
                elapsed_ns: self.recorded_elapsed_ns,
                ..self.timestamp
            }
        } else {
            self.timestamp
        }
    }
}

wire_enum! {
    /// What an actor is.
    #[derive(Debug, Clone, Copy, PartialEq, Eq, Hash, serde::Serialize, serde::Deserialize)]
    pub enum ActorKind {
        /// Fixed geometry: ground, ramps, walls.
        Static = 1,
        /// A dynamic box; `extent` holds its half extents.
        Box = 2,
        /// A dynamic sphere; `extent[0]` is its radius.
        Sphere = 3,
        /// A dynamic capsule along Y; `extent` is (radius, half height, radius).
        Capsule = 4,
        /// A four-wheeled ray-cast vehicle; `extent` holds the chassis half extents.
        Vehicle = 5,
    }
}

impl ActorKind {
    /// The kind named `name` (as printed by [`ActorKind::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// The lower-case name used in CLI output.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Static => "static",
            Self::Box => "box",
            Self::Sphere => "sphere",
            Self::Capsule => "capsule",
            Self::Vehicle => "vehicle",
        }
    }
}

/// The state of one actor in one frame. World frame: Y up, metres, radians.
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::ActorState/1")]
pub struct ActorState {
    /// Actor id: stable for the actor's life, never reused in a world.
    pub id: u64,
    /// [`ActorKind`] as `u32`.
    pub kind: u32,
    /// [`ActorState::SLEEPING`] and future flags.
    pub flags: u32,
    /// Position of the body origin.
    pub position: [f32; 3],
    /// Orientation as a unit quaternion (x, y, z, w).
    pub rotation: [f32; 4],
    /// Linear velocity, m/s.
    pub linear_velocity: [f32; 3],
    /// Angular velocity, rad/s.
    pub angular_velocity: [f32; 3],
    /// Linear acceleration over the last frame, m/s².
    pub acceleration: [f32; 3],
    /// Shape size: half extents for boxes, radius for spheres (see [`ActorKind`]).
    pub extent: [f32; 3],
    /// Zero.
    pub reserved: u32,
}

impl ActorState {
    /// Flag: the physics engine put the body to sleep (it is at rest).
    pub const SLEEPING: u32 = 1;
    /// Flag: the actor's physics is disabled (it does not move or collide).
    pub const PHYSICS_DISABLED: u32 = 2;

    /// The actor's kind, if this version knows it.
    pub fn actor_kind(&self) -> Option<ActorKind> {
        ActorKind::from_u32(self.kind)
    }
}

#[cfg(test)]
mod tests {
    use super::*;

    #[test]
    fn layouts_have_no_padding_and_fixed_sizes() {
        // Pod derives already refuse padding; the sizes are part of the protocol.
        assert_eq!(std::mem::size_of::<Timestamp>(), 32);
        assert_eq!(std::mem::size_of::<FrameHeader>(), 112);
        assert_eq!(std::mem::size_of::<ActorState>(), 96);
    }

    #[test]
    fn seconds_are_exact_for_long_runs() {
        let t = Timestamp {
            elapsed_ns: 100_000 * NANOS_PER_SECOND,
            delta_ns: 100_000_000,
            ..Default::default()
        };
        assert_eq!(t.elapsed_seconds(), 100_000.0);
        assert_eq!(t.delta_seconds(), 0.1);
        let t = Timestamp {
            elapsed_ns: 1_503_000_000,
            ..Default::default()
        };
        assert_eq!(t.elapsed_seconds().to_string(), "1.503");
    }

    #[test]
    fn kinds_round_trip_through_their_names() {
        for kind in ActorKind::ALL {
            assert_eq!(ActorKind::from_name(kind.name()), Some(kind));
        }
        assert_eq!(ActorKind::from_name("Box"), None);
    }
}
