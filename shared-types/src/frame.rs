//! The frame snapshot: a [`FrameHeader`] user header and a slice of
//! [`ActorState`]: the actors, then the same actors' [`ActorPose`]s packed
//! (see [`frame_slice_len`]).

use std::mem::MaybeUninit;

use bytemuck::{Pod, Zeroable};
use iceoryx2::prelude::ZeroCopySend;

use crate::settings::NANOS_PER_SECOND;
use crate::settings_wire::WireSettings;
use crate::wire::wire_enum;

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
    /// [`PROTOCOL_VERSION`](crate::wire::PROTOCOL_VERSION) of the server that wrote the frame.
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
        let s = crate::settings::WorldSettings::from(self.settings);
        crate::substep_rule::SubstepRule::Clamp.physics_ns(
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
        /// A pedestrian: a kinematic capsule along Y that stands on the
        /// ground, walks as its [`WalkerControl`](crate::CommandKind::WalkerControl)
        /// says and pushes nothing; `extent` is (radius, half height,
        /// radius), the half height counting the round ends.
        Walker = 6,
        /// A traffic light's head: a fixed box (`extent` its half
        /// extents) over the kerb of the approach it controls, cycling
        /// with its junction's group in simulation time; its state and
        /// how long it has held it are in the state's `flags` and
        /// `detail` ([`ActorState::light`]).
        TrafficLight = 7,
        /// A traffic sign's plate: a fixed box facing the traffic it
        /// speaks to; what it says is in the state's `flags` and `detail`
        /// ([`ActorState::sign`]).
        TrafficSign = 8,
    }
}

impl ActorKind {
    /// The kind named `name` (as printed by [`ActorKind::name`]).
    pub fn from_name(name: &str) -> Option<Self> {
        Self::ALL.into_iter().find(|k| k.name() == name)
    }

    /// Whether actors of this kind move: vehicles, walkers and dynamic
    /// bodies (not fixed geometry, lights or signs).
    pub fn moves(&self) -> bool {
        matches!(
            self,
            Self::Vehicle | Self::Walker | Self::Box | Self::Sphere | Self::Capsule
        )
    }

    /// The lower-case name used in CLI output.
    pub fn name(&self) -> &'static str {
        match self {
            Self::Static => "static",
            Self::Box => "box",
            Self::Sphere => "sphere",
            Self::Capsule => "capsule",
            Self::Vehicle => "vehicle",
            Self::Walker => "walker",
            Self::TrafficLight => "traffic_light",
            Self::TrafficSign => "traffic_sign",
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
    /// What the kind says beyond its body: a traffic light's milliseconds
    /// in its state, a speed-limit sign's km/h ([`ActorState::light`],
    /// [`ActorState::sign`]); zero for every other kind.
    pub detail: u32,
}

impl ActorState {
    /// Flag: the physics engine put the body to sleep (it is at rest).
    pub const SLEEPING: u32 = 1;
    /// Flag: the actor's physics is disabled (it does not move or collide).
    pub const PHYSICS_DISABLED: u32 = 2;
    /// Flag: a traffic light whose time is frozen (CARLA's
    /// `TrafficLight.freeze`): it keeps its state until unfrozen.
    pub const LIGHT_FROZEN: u32 = 4;
    /// Where the kind's code sits in `flags`: bits 8 to 15 (a traffic
    /// light's [`LightState`](crate::LightState), a sign's
    /// [`SignKind`](crate::SignKind)).
    pub const CODE_SHIFT: u32 = 8;

    /// The actor's kind, if this version knows it.
    pub fn actor_kind(&self) -> Option<ActorKind> {
        ActorKind::from_u32(self.kind)
    }
}

/// Who, what and where an actor is, packed: the first 44 bytes of its
/// [`ActorState`] (id, kind, flags, position, rotation), 48 bytes in all.
/// Every frame sample carries its actors' poses after the actors, in the
/// same order, so a reader that wants only where things are moves half the
/// bytes (see [`frame_slice_len`]).
#[repr(C)]
#[derive(Debug, Clone, Copy, PartialEq, Default, Pod, Zeroable, ZeroCopySend)]
#[type_name("simbus::ActorPose/1")]
pub struct ActorPose {
    /// [`ActorState::id`].
    pub id: u64,
    /// [`ActorState::kind`].
    pub kind: u32,
    /// [`ActorState::flags`].
    pub flags: u32,
    /// [`ActorState::position`].
    pub position: [f32; 3],
    /// [`ActorState::rotation`].
    pub rotation: [f32; 4],
    /// Zero.
    pub reserved: u32,
}

impl From<&ActorState> for ActorPose {
    fn from(a: &ActorState) -> Self {
        Self {
            id: a.id,
            kind: a.kind,
            flags: a.flags,
            position: a.position,
            rotation: a.rotation,
            reserved: 0,
        }
    }
}

impl ActorPose {
    /// The actor's kind, if this version knows it.
    pub fn actor_kind(&self) -> Option<ActorKind> {
        ActorKind::from_u32(self.kind)
    }
}

/// Poses packed into one [`ActorState`]-sized element of a frame's slice.
const POSES_PER_ELEMENT: usize =
    std::mem::size_of::<ActorState>() / std::mem::size_of::<ActorPose>();

/// The length of a frame sample's slice for `actor_count` actors: the
/// actors, then their poses, two [`ActorPose`]s to each further element
/// (the last one's second pose zero when the count is odd). Readers of the
/// actors take the first `actor_count` elements and never see the poses.
pub const fn frame_slice_len(actor_count: usize) -> usize {
    actor_count + actor_count.div_ceil(POSES_PER_ELEMENT)
}

/// Fills a frame sample's slice of [`frame_slice_len`]`(actor_count)`
/// elements with `actor(0..actor_count)`, then their poses, each actor
/// made once. Returns whether every element was written: false (and
/// nothing written) when `slice` has another length.
pub fn fill_frame_slice(
    slice: &mut [MaybeUninit<ActorState>],
    actor_count: usize,
    mut actor: impl FnMut(usize) -> ActorState,
) -> bool {
    if slice.len() != frame_slice_len(actor_count) {
        return false;
    }
    let (actors, poses) = slice.split_at_mut(actor_count);
    let mut pair = [ActorPose::default(); POSES_PER_ELEMENT];
    for (i, element) in actors.iter_mut().enumerate() {
        let state = element.write(actor(i));
        pair[i % POSES_PER_ELEMENT] = ActorPose::from(&*state);
        if i % POSES_PER_ELEMENT == POSES_PER_ELEMENT - 1 {
            poses[i / POSES_PER_ELEMENT].write(bytemuck::cast(pair));
        }
    }
    if !actor_count.is_multiple_of(POSES_PER_ELEMENT) {
        pair[actor_count % POSES_PER_ELEMENT..].fill(ActorPose::default());
        poses[actor_count / POSES_PER_ELEMENT].write(bytemuck::cast(pair));
    }
    true
}

/// A frame sample's slice read as its two parts: the first
/// `actor_count` elements are the actors; the poses after them, if the
/// slice holds them all (else none). Never reads past the slice.
pub fn frame_parts(slice: &[ActorState], actor_count: u32) -> (&[ActorState], &[ActorPose]) {
    let count = (actor_count as usize).min(slice.len());
    let (actors, rest) = slice.split_at(count);
    let pose_elements = frame_slice_len(count) - count;
    let poses = match rest.get(..pose_elements) {
        Some(elements) if count == actor_count as usize => {
            &bytemuck::cast_slice::<ActorState, ActorPose>(elements)[..count]
        }
        _ => &[],
    };
    (actors, poses)
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
        assert_eq!(std::mem::size_of::<ActorPose>(), 48);
    }

    fn actor(i: usize) -> ActorState {
        let f = i as f32;
        ActorState {
            id: 100 + i as u64,
            kind: ActorKind::Box as u32,
            flags: (i % 2) as u32,
            position: [f, f + 0.5, -f],
            rotation: [0.0, f, 0.0, 1.0],
            linear_velocity: [f; 3],
            angular_velocity: [2.0 * f; 3],
            acceleration: [3.0 * f; 3],
            extent: [0.5; 3],
            detail: 0,
        }
    }

    #[test]
    fn a_frame_slice_holds_the_actors_then_their_poses_in_order() {
        for n in [0usize, 1, 2, 3, 10, 11] {
            let mut slice = vec![MaybeUninit::<ActorState>::uninit(); frame_slice_len(n)];
            assert!(fill_frame_slice(&mut slice, n, actor));
            let slice = written(slice);
            let (actors, poses) = frame_parts(&slice, n as u32);
            let expected: Vec<ActorState> = (0..n).map(actor).collect();
            assert_eq!(actors, expected.as_slice(), "{n} actors");
            let expected: Vec<ActorPose> = expected.iter().map(ActorPose::from).collect();
            assert_eq!(poses, expected.as_slice(), "{n} poses");
            assert_eq!(slice.len() * 96, n * 96 + n.div_ceil(2) * 96);
        }
    }

    /// The slice `fill_frame_slice` filled, as values.
    #[allow(unsafe_code)]
    fn written(slice: Vec<MaybeUninit<ActorState>>) -> Vec<ActorState> {
        // SAFETY: `fill_frame_slice` returned true, so it wrote every element.
        slice
            .into_iter()
            .map(|e| unsafe { e.assume_init() })
            .collect()
    }

    #[test]
    fn a_slice_of_another_length_is_refused_and_left_alone() {
        let mut slice = vec![MaybeUninit::<ActorState>::uninit(); 3];
        assert!(!fill_frame_slice(&mut slice, 3, |_| unreachable!(
            "nothing is made"
        )));
    }

    #[test]
    fn a_slice_short_of_its_poses_reads_its_actors_and_no_poses() {
        let full: Vec<ActorState> = (0..4).map(actor).collect();
        let (actors, poses) = frame_parts(&full, 4);
        assert_eq!((actors.len(), poses.len()), (4, 0));
        let (actors, poses) = frame_parts(&full[..2], 4);
        assert_eq!((actors.len(), poses.len()), (2, 0));
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
