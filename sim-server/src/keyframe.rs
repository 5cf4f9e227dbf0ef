//! Keyframes: the whole server world (rapier's physics sets through their
//! serde support, simbus's actors and vehicles) with the clock, in
//! [postcard](https://docs.rs/postcard), so a replay or a re-simulation
//! starts from the nearest one instead of from the recording's first frame.
//!
//! Layout 1 was msgpack (recordings of simbus before it); a keyframe of it
//! is refused by its version, with what it is. Layout 2 had no walkers,
//! layout 3 no traffic lights and layout 4 no Ackermann targets: the
//! world's last fields, so an older keyframe reads as layout 5 with those
//! it lacks appended empty (walkers one zero byte, lights three,
//! Ackermann targets one).

use serde::{Deserialize, Serialize};

use crate::world::World;

/// Layout version of [`Keyframe`], checked on restore.
const KEYFRAME_VERSION: u32 = 5;

/// How a layout-1 keyframe begins: msgpack's array of its 7 fields, the
/// first its version, 1.
const MSGPACK_LAYOUT_1: [u8; 2] = [0x97, 0x01];

/// The state after a frame.
#[derive(Debug, Serialize, Deserialize)]
pub(crate) struct Keyframe<W> {
    version: u32,
    /// The frame it follows.
    pub(crate) frame: u64,
    /// Its simulation time.
    pub(crate) elapsed_ns: u64,
    /// Its delta.
    pub(crate) delta_ns: u64,
    /// Its episode in the recording.
    pub(crate) episode: u64,
    /// The episode's scene.
    pub(crate) scene: String,
    /// The world.
    pub(crate) world: W,
}

impl<'a> Keyframe<&'a World> {
    /// The keyframe of `world` after the frame `header` describes.
    pub(crate) fn of(world: &'a World, header: &shared_types::FrameHeader, scene: String) -> Self {
        Self {
            version: KEYFRAME_VERSION,
            frame: header.timestamp.frame,
            elapsed_ns: header.timestamp.elapsed_ns,
            delta_ns: header.timestamp.delta_ns,
            episode: header.episode,
            scene,
            world,
        }
    }

    /// As postcard, its layout version first.
    pub(crate) fn encode(&self) -> Vec<u8> {
        // Serializing plain data into a Vec cannot fail.
        postcard::to_allocvec(self).unwrap_or_default()
    }
}

/// Why a keyframe cannot be restored.
#[derive(Debug, thiserror::Error)]
pub(crate) enum KeyframeError {
    #[error("the keyframe is not readable")]
    Decode(#[from] postcard::Error),
    #[error("the keyframe has layout version {0}; this server reads 2 to {KEYFRAME_VERSION}")]
    Version(u32),
}

impl Keyframe<World> {
    /// Decodes a keyframe written by [`Keyframe::encode`].
    pub(crate) fn decode(bytes: &[u8]) -> Result<Self, KeyframeError> {
        if bytes.starts_with(&MSGPACK_LAYOUT_1) {
            return Err(KeyframeError::Version(1));
        }
        let (version, rest) = postcard::take_from_bytes::<u32>(bytes)?;
        match version {
            KEYFRAME_VERSION => Ok(postcard::from_bytes(bytes)?),
            2..=4 => {
                // Each layout is the one before and one more of the
                // world's last fields, empty: layout 3 the walkers (one
                // zero byte), 4 the lights (lights, groups, signs: three),
                // 5 the Ackermann targets (one).
                let mut current = postcard::to_allocvec(&KEYFRAME_VERSION)?;
                current.extend_from_slice(rest);
                if version == 2 {
                    current.push(0);
                }
                if version <= 3 {
                    current.extend_from_slice(&[0, 0, 0]);
                }
                current.push(0);
                Ok(postcard::from_bytes(&current)?)
            }
            _ => Err(KeyframeError::Version(version)),
        }
    }
}

#[cfg(test)]
mod tests {
    use super::*;
    use crate::clock::SubstepPlan;
    use crate::scene::Scene;
    use shared_types::{Command, FrameHeader, WorldSettings};

    /// Frames of 0.05 s (five physics steps).
    fn plan() -> SubstepPlan {
        let settings = WorldSettings {
            fixed_delta_seconds: Some(0.05),
            ..Default::default()
        };
        SubstepPlan::new(50_000_000, &settings)
    }

    /// A world restored from a keyframe steps bit for bit as the original:
    /// the property re-simulation from a keyframe rests on.
    #[test]
    fn a_restored_world_steps_exactly_as_the_original() {
        let plan = plan();
        let mut world = World::new(&Scene::Default.placements(7), 1);
        let vehicle = world.apply(&Command::spawn_vehicle([0.0, 1.0, -6.0])).actor;
        let walker = world
            .apply(&Command::spawn_walker([6.0, 0.9, 6.0], 0.25, 0.9))
            .actor;
        assert!(world.walkers.contains(walker));
        for _ in 0..40 {
            world.step(&plan);
        }
        world.apply(&Command::vehicle_control(vehicle, 0.8, 0.3, 0.0, false));
        world.apply(&Command::walker_control(walker, [1.0, 0.0, 1.0], 1.5, true));
        let bytes = Keyframe::of(&world, &FrameHeader::default(), "default".into()).encode();
        let mut restored = Keyframe::decode(&bytes).expect("decodes").world;
        for frame in 0..120 {
            world.step(&plan);
            restored.step(&plan);
            assert_eq!(world.states(), restored.states(), "frame {frame}");
        }
    }

    /// The town's lights go on from a keyframe and from a snapshot's copy
    /// exactly where they were: a script's held state, a frozen group's
    /// and a cycle's place in it (the states compared hold every light's
    /// state, time in its phase and freeze).
    #[test]
    fn the_towns_lights_go_on_from_a_keyframe_and_a_copy_exactly() {
        let plan = plan();
        let mut world = World::new(&Scene::Town.placements(0), 1);
        let lights: Vec<u64> = world
            .states()
            .iter()
            .filter(|a| a.light().is_some())
            .map(|a| a.id)
            .collect();
        assert_eq!(lights.len(), 16);
        for _ in 0..250 {
            world.step(&plan);
        }
        world.apply(&Command::traffic_light_state(
            lights[5],
            shared_types::LightState::Green,
        ));
        world.apply(&Command::freeze_traffic_lights(lights[8], true));
        world.apply(&Command::traffic_light_times(
            lights[0],
            [Some(4.0), None, None],
        ));
        let bytes = Keyframe::of(&world, &FrameHeader::default(), "town".into()).encode();
        let mut restored = Keyframe::decode(&bytes).expect("decodes").world;
        let mut copy = world.duplicate();
        let light_states =
            |w: &World| -> Vec<_> { w.states().iter().filter_map(|a| a.light()).collect() };
        let before = light_states(&world);
        for frame in 0..1300 {
            world.step(&plan);
            restored.step(&plan);
            copy.step(&plan);
            assert_eq!(world.states(), restored.states(), "frame {frame}");
            assert_eq!(world.states(), copy.states(), "frame {frame}");
        }
        // The lights did move on (but the frozen group's).
        assert_ne!(light_states(&world), before);
    }

    /// A snapshot's copy of a world steps bit for bit as the original:
    /// what a restore rests on.
    #[test]
    fn a_duplicated_world_steps_exactly_as_the_original() {
        let plan = plan();
        let mut world = World::new(&Scene::Default.placements(3), 1);
        let vehicle = world.apply(&Command::spawn_vehicle([0.0, 1.0, -6.0])).actor;
        let walker = world
            .apply(&Command::spawn_walker([6.0, 0.9, 6.0], 0.25, 0.9))
            .actor;
        assert!(world.walkers.contains(walker));
        for _ in 0..30 {
            world.step(&plan);
        }
        world.apply(&Command::vehicle_control(vehicle, 0.6, -0.2, 0.0, false));
        world.apply(&Command::walker_control(
            walker,
            [-1.0, 0.0, 0.5],
            1.2,
            false,
        ));
        let mut copy = world.duplicate();
        let mut again = copy.duplicate();
        for frame in 0..120 {
            world.step(&plan);
            copy.step(&plan);
            again.step(&plan);
            assert_eq!(world.states(), copy.states(), "frame {frame}");
            assert_eq!(world.states(), again.states(), "frame {frame}");
        }
    }

    #[test]
    fn garbage_is_an_error_not_a_panic() {
        assert!(Keyframe::decode(b"not a keyframe").is_err());
        assert!(Keyframe::decode(&[]).is_err());
        let world = World::new(&Scene::Default.placements(1), 1);
        let bytes = Keyframe::of(&world, &FrameHeader::default(), "default".into()).encode();
        for cut in [1, bytes.len() / 2, bytes.len() - 1] {
            assert!(Keyframe::decode(&bytes[..cut]).is_err(), "cut at {cut}");
        }
    }

    /// A keyframe of layout 1 (msgpack, before this layout) is refused by
    /// its version, not misread.
    #[test]
    fn a_msgpack_keyframe_of_layout_1_is_refused_by_its_version() {
        let old = [0x97, 0x01, 0x05, 0x00, 0x00, 0x00, 0xa7];
        let error = Keyframe::decode(&old).unwrap_err();
        assert!(matches!(error, KeyframeError::Version(1)), "{error:?}");
        assert_eq!(
            error.to_string(),
            "the keyframe has layout version 1; this server reads 2 to 5"
        );
    }

    /// Keyframes of layout 2 (before walkers, lights and Ackermann
    /// targets: layout 5 without its last three fields), 3 (before lights)
    /// and 4 (before Ackermann targets) read as the same world without
    /// them.
    #[test]
    fn keyframes_of_layouts_2_to_4_read_with_no_walkers_lights_or_targets() {
        let plan = plan();
        let mut world = World::new(&Scene::Default.placements(5), 1);
        for _ in 0..10 {
            world.step(&plan);
        }
        let bytes = Keyframe::of(&world, &FrameHeader::default(), "default".into()).encode();
        // The same fields; layout 4 without the Ackermann targets (one
        // empty list), 3 without the lights (three) too, 2 without the
        // walkers (one) too.
        assert_eq!(bytes[0], 5);
        assert_eq!(bytes[bytes.len() - 5..], [0; 5]);
        for (version, cut) in [(2, 5), (3, 4), (4, 1)] {
            let mut old = bytes[..bytes.len() - cut].to_vec();
            old[0] = version;
            let mut restored = Keyframe::decode(&old)
                .expect("an older layout decodes")
                .world;
            assert_eq!(restored.states(), world.states());
            let mut world = world.duplicate();
            world.step(&plan);
            restored.step(&plan);
            assert_eq!(restored.states(), world.states());
        }
        let error = Keyframe::decode(&[6, 0, 0]).unwrap_err();
        assert!(matches!(error, KeyframeError::Version(6)), "{error:?}");
    }
}
