//! The world's own contracts: ids, stepping, determinism, commands.

use super::*;
use crate::scene::Scene;
use shared_types::WorldSettings;
use shared_types::{Command, CommandStatus};

fn fixed_plan(dt: f64) -> SubstepPlan {
    let settings = WorldSettings {
        fixed_delta_seconds: Some(dt),
        ..Default::default()
    };
    SubstepPlan::new(settings.fixed_delta_nanos().unwrap(), &settings)
}

fn state_of(world: &World, id: u64) -> ActorState {
    world.actor_state(world.index_of(id).expect("actor exists"))
}

#[test]
fn ids_follow_scene_order_from_one() {
    let world = World::new(&Scene::Default.placements(0), 1);
    let ids: Vec<u64> = (0..world.actor_count())
        .map(|i| world.actor_state(i).id)
        .collect();
    assert_eq!(ids, (1..=world.actor_count() as u64).collect::<Vec<_>>());
}

#[test]
fn things_fall_under_gravity() {
    let mut world = World::new(&Scene::Default.placements(0), 1);
    let capsule = (0..world.actor_count())
        .find(|&i| world.actor_state(i).kind == ActorKind::Capsule as u32)
        .unwrap();
    let y0 = world.actor_state(capsule).position[1];
    let plan = fixed_plan(0.05);
    for _ in 0..5 {
        world.step(&plan);
    }
    let state = world.actor_state(capsule);
    assert!(state.position[1] < y0 - 0.2, "the capsule fell");
    // Free fall: acceleration is gravity.
    assert!((state.acceleration[1] + 9.81).abs() < 0.05, "{state:?}");
}

#[test]
fn same_steps_give_identical_states() {
    let run = || {
        let mut world = World::new(&Scene::Boxes(50).placements(0), 1);
        let plan = fixed_plan(0.02);
        for _ in 0..100 {
            world.step(&plan);
        }
        (0..world.actor_count())
            .map(|i| world.actor_state(i))
            .collect::<Vec<_>>()
    };
    let (a, b) = (run(), run());
    assert_eq!(
        bytemuck::cast_slice::<ActorState, u8>(&a),
        bytemuck::cast_slice::<ActorState, u8>(&b)
    );
}

#[test]
fn spawned_ids_are_new_and_never_reused() {
    let mut world = World::new(&Scene::Empty.placements(0), 1);
    let a = world.apply(&Command::spawn_box([0.0, 1.0, 0.0], [0.5; 3]));
    let b = world.apply(&Command::spawn_sphere([2.0, 1.0, 0.0], 0.5));
    assert_eq!((a.actor, b.actor), (1, 2));
    assert_eq!(
        world.apply(&Command::destroy(2)).status,
        CommandStatus::Ok as u32
    );
    let c = world.apply(&Command::spawn_capsule([0.0, 3.0, 0.0], 0.3, 0.5));
    assert_eq!(c.actor, 3, "id 2 is not reused");
    let again = world.apply(&Command::destroy(2));
    assert_eq!(again.status, CommandStatus::UnknownActor as u32);
    assert_eq!(world.actor_count(), 2);
}

#[test]
fn bad_commands_are_refused_and_change_nothing() {
    let mut world = World::new(&Scene::Default.placements(0), 1);
    let before: Vec<_> = (0..world.actor_count())
        .map(|i| world.actor_state(i))
        .collect();
    let cases = [
        (
            Command::apply_force(999, [1.0, 0.0, 0.0]),
            CommandStatus::UnknownActor,
        ),
        (
            Command::apply_force(3, [f32::NAN, 0.0, 0.0]),
            CommandStatus::InvalidArgument,
        ),
        (
            Command::spawn_box([0.0; 3], [-1.0, 1.0, 1.0]),
            CommandStatus::InvalidArgument,
        ),
        (
            Command::spawn_sphere([0.0; 3], f32::INFINITY),
            CommandStatus::InvalidArgument,
        ),
        (
            Command::vehicle_control(3, 0.5, 0.0, 0.0, false),
            CommandStatus::NotAVehicle,
        ),
        (
            Command::apply_impulse(1, [0.0, 1.0, 0.0]),
            CommandStatus::StaticActor,
        ),
        (
            Command::set_transform(3, [0.0; 3], [f32::NAN, 0.0, 0.0, 1.0]),
            CommandStatus::InvalidArgument,
        ),
        (
            Command {
                kind: 99,
                ..Command::destroy(3)
            },
            CommandStatus::UnknownCommand,
        ),
    ];
    for (command, status) in cases {
        assert_eq!(world.apply(&command).status, status as u32, "{command:?}");
    }
    let after: Vec<_> = (0..world.actor_count())
        .map(|i| world.actor_state(i))
        .collect();
    assert_eq!(before, after);
}

#[test]
fn forces_last_one_frame_and_impulses_act_at_once() {
    let mut world = World::new(&Scene::Empty.placements(0), 1);
    let id = world
        .apply(&Command::spawn_box([0.0, 10.0, 0.0], [0.5; 3]))
        .actor;
    world.apply(&Command::set_gravity(id, false));
    world.apply(&Command::apply_force(id, [8.0, 0.0, 0.0])); // 1 kg box: 8 m/s²
    let plan = fixed_plan(0.1);
    world.step(&plan);
    let v1 = state_of(&world, id).linear_velocity[0];
    assert!((v1 - 0.8).abs() < 1e-3, "{v1}");
    world.step(&plan);
    let v2 = state_of(&world, id).linear_velocity[0];
    assert!((v2 - v1).abs() < 1e-4, "the force lasted one frame: {v2}");
    world.apply(&Command::apply_impulse(id, [0.0, 2.0, 0.0]));
    assert!((state_of(&world, id).linear_velocity[1] - 2.0).abs() < 1e-4);
}

#[test]
fn a_vehicle_drives_forward_with_throttle_and_turns_with_steer() {
    let mut world = crate::commands::tests::world_on_ground();
    let id = world.apply(&Command::spawn_vehicle([0.0, 1.0, 0.0])).actor;
    let plan = fixed_plan(0.02);
    for _ in 0..50 {
        world.step(&plan); // settle on the suspension
    }
    let start = state_of(&world, id).position;
    world.apply(&Command::vehicle_control(id, 1.0, 0.0, 0.0, false));
    for _ in 0..100 {
        world.step(&plan);
    }
    let moved = state_of(&world, id).position;
    assert!(
        moved[0] - start[0] > 2.0,
        "drove forward: {start:?} -> {moved:?}"
    );
    world.apply(&Command::vehicle_control(id, 1.0, 1.0, 0.0, false));
    for _ in 0..100 {
        world.step(&plan);
    }
    let turned = state_of(&world, id).position;
    assert!(
        (turned[2] - moved[2]).abs() > 0.5,
        "steered: {moved:?} -> {turned:?}"
    );
}

#[test]
fn a_contact_starts_when_it_first_pushes_not_when_shapes_come_near() {
    let mut world = World::new(&Scene::Flat.placements(0), 1);
    world.watch_contacts = true;
    let ground = state_of(&world, 1);
    let top = ground.position[1] + world.actors[0].extent[1];
    // A box 1 cm above the ground, floating: within rapier's 2 cm
    // prediction distance, so rapier starts the pair's contact, but
    // nothing touches.
    let spawned = world.apply(&Command::spawn_box([0.0, top + 0.51, 0.0], [0.5, 0.5, 0.5]));
    let id = spawned.actor;
    assert_eq!(
        world.apply(&Command::set_gravity(id, false)).status,
        CommandStatus::Ok as u32
    );
    let plan = fixed_plan(0.01);
    for _ in 0..20 {
        world.step(&plan);
        assert!(
            world.contact_starts.is_empty(),
            "{:?}",
            world.contact_starts
        );
    }
    // Pushed down, it lands: one start, the ground's push up on it.
    world.apply(&Command::apply_impulse(id, [0.0, -5.0, 0.0]));
    let mut starts = Vec::new();
    for _ in 0..20 {
        world.step(&plan);
        starts.extend(world.contact_starts.iter().filter_map(|c| c.seen_by(id)));
    }
    assert_eq!(starts.len(), 1, "{starts:?}");
    assert_eq!(starts[0].0, 1);
    assert!(starts[0].1.y > 0.0, "{starts:?}");
}

/// Issue 44, item 2: a spawn whose body would overlap another's is refused
/// (CARLA's "Spawn failed because of collision at spawn position"), its
/// result naming the actor that is there, and changes nothing; one that
/// rests on the ground, or on another body, touches but is spawned.
#[test]
fn a_spawn_inside_another_body_is_refused_naming_it_and_changes_nothing() {
    let mut world = World::new(&Scene::Default.placements(0), 1);
    let stack_bottom = (0..world.actor_count())
        .map(|i| world.actor_state(i))
        .find(|s| s.kind == ActorKind::Box as u32 && s.position == [5.0, 0.5, 0.0])
        .expect("the default scene's stack of boxes")
        .id;
    let before = world.states();
    for spawn in [
        // Into the stack of boxes, as the CLI spawn did.
        Command::spawn_vehicle([5.0, 1.0, 0.0]),
        Command::spawn_box([5.0, 0.5, 0.0], [0.5; 3]),
        Command::spawn_sphere([5.0, 0.5, 0.4], 0.3),
        Command::spawn_capsule([5.3, 1.3, 0.0], 0.3, 0.5),
    ] {
        let r = world.apply(&spawn);
        assert_eq!(r.status, CommandStatus::SpawnCollision as u32, "{spawn:?}");
        assert_eq!(
            r.actor, stack_bottom,
            "{spawn:?} names the box that is there"
        );
    }
    // Into the ground (its top is y = 0).
    let r = world.apply(&Command::spawn_box([30.0, 0.2, 30.0], [0.5; 3]));
    assert_eq!(r.status, CommandStatus::SpawnCollision as u32);
    assert_eq!(r.actor, 1, "the ground is actor 1");
    assert_eq!(world.states(), before, "nothing changed");

    // Resting on the ground, and on top of the stack: spawned.
    let on_ground = world.apply(&Command::spawn_box([30.0, 0.5, 30.0], [0.5; 3]));
    assert_eq!(on_ground.status, CommandStatus::Ok as u32);
    let on_stack = world.apply(&Command::spawn_box([5.0, 5.5, 0.0], [0.5; 3]));
    assert_eq!(on_stack.status, CommandStatus::Ok as u32);
}

/// A batch's spawns see the ones before them in the same batch (which the
/// query pipeline only learns of at the next step).
#[test]
fn a_second_spawn_at_the_same_place_in_one_batch_is_refused() {
    let mut world = World::new(&Scene::Empty.placements(0), 1);
    let first = world.apply(&Command::spawn_box([0.0, 10.0, 0.0], [0.5; 3]));
    assert_eq!(first.status, CommandStatus::Ok as u32);
    let second = world.apply(&Command::spawn_sphere([0.2, 10.0, 0.0], 0.5));
    assert_eq!(second.status, CommandStatus::SpawnCollision as u32);
    assert_eq!(second.actor, first.actor);
    // A body moved this frame is tested where it is now.
    let moved = world.apply(&Command::set_transform(
        first.actor,
        [20.0, 10.0, 0.0],
        [0.0; 4],
    ));
    assert_eq!(moved.status, CommandStatus::Ok as u32);
    let there = world.apply(&Command::spawn_box([20.0, 10.0, 0.0], [0.5; 3]));
    assert_eq!(there.status, CommandStatus::SpawnCollision as u32);
    let freed = world.apply(&Command::spawn_box([0.0, 10.0, 0.0], [0.5; 3]));
    assert_eq!(freed.status, CommandStatus::Ok as u32);
    assert_eq!(world.actor_count(), 2);
}
