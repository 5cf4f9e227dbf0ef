//! A command from another process is bytes: whatever they hold, applying
//! them never panics, and a command the world refuses changes nothing.
//!
//! proptest builds commands field by field from the whole range of each
//! field: every `kind` (known and out of range), every flag, actor ids that
//! exist, do not, or are static, and floats that are NaN, infinite, huge,
//! tiny or ordinary. Each command is applied to the default scene; when its
//! result is not `Ok`, every actor's state must be bit-identical to before.
//! The world is then stepped, which must not panic either.

use proptest::prelude::*;
use shared_types::{Command, CommandStatus, WorldSettings};
use sim_server::clock::SubstepPlan;
use sim_server::world::World;
use sim_server::Scene;

fn any_float() -> impl Strategy<Value = f32> {
    prop_oneof![
        Just(f32::NAN),
        Just(f32::INFINITY),
        Just(f32::NEG_INFINITY),
        Just(f32::MAX),
        Just(f32::MIN_POSITIVE),
        Just(0.0),
        Just(-0.0),
        -1e6f32..1e6,
        any::<f32>(),
    ]
}

fn any_command() -> impl Strategy<Value = Command> {
    (
        prop_oneof![0u32..40, any::<u32>()],
        any::<u32>(),
        prop_oneof![0u64..40, any::<u64>()],
        proptest::array::uniform3(any_float()),
        any::<u32>(),
        proptest::array::uniform4(any_float()),
        proptest::array::uniform4(any_float()),
    )
        .prop_map(
            |(kind, flags, actor, vector, reserved, rotation, params)| Command {
                kind,
                flags,
                actor,
                vector,
                reserved,
                rotation,
                params,
            },
        )
}

fn state_bits(world: &World) -> Vec<u8> {
    bytemuck::cast_slice(&world.states()).to_vec()
}

proptest! {
    #![proptest_config(ProptestConfig { cases: 512, ..ProptestConfig::default() })]

    #[test]
    fn a_refused_command_changes_nothing_and_nothing_panics(
        commands in proptest::collection::vec(any_command(), 1..8)
    ) {
        let mut world = World::new(&Scene::Default.placements(0), 1);
        let plan = SubstepPlan::new(20_000_000, &WorldSettings::default());
        for command in &commands {
            let before = state_bits(&world);
            let actors = world.states().len();
            let result = world.apply(command);
            if result.status != CommandStatus::Ok as u32 {
                prop_assert_eq!(world.states().len(), actors);
                prop_assert!(
                    state_bits(&world) == before,
                    "refused command {:?} ({:?}) changed the world",
                    command,
                    result
                );
            }
            world.step(&plan);
        }
    }
}
