//! Walkers stand, walk, jump, stop at walls and are refused bad values.

use rapier3d::prelude::{Rotation, Vector};
use shared_types::{ActorKind, Command, CommandStatus};

use crate::commands::tests::{state, step, world_on_ground};
use crate::world::World;

fn spawned(world: &mut World, command: Command) -> u64 {
    let r = world.apply(&command);
    assert_eq!(r.status, CommandStatus::Ok as u32, "{command:?}");
    r.actor
}

#[test]
fn a_walker_stands_on_the_ground_walks_where_told_and_faces_that_way() {
    let mut world = world_on_ground();
    let id = spawned(
        &mut world,
        Command::spawn_walker([0.0, 0.95, 0.0], 0.25, 0.9),
    );
    step(&mut world, 10);
    let standing = state(&world, id);
    assert_eq!(standing.actor_kind(), Some(ActorKind::Walker));
    assert_eq!(standing.extent, [0.25, 0.9, 0.25]);
    assert!((standing.position[1] - 0.9).abs() < 0.06, "{standing:?}");
    assert!(
        standing.position[0].abs() < 1e-4,
        "a walker without control stands"
    );
    // 1.4 m/s along -Z for 2 s.
    world.apply(&Command::walker_control(id, [0.0, 0.0, -3.0], 1.4, false));
    step(&mut world, 40);
    let walked = state(&world, id);
    assert!((walked.position[2] + 2.8).abs() < 0.1, "{walked:?}");
    assert!(
        (walked.position[1] - 0.9).abs() < 0.06,
        "on the ground: {walked:?}"
    );
    assert!((walked.linear_velocity[2] + 1.4).abs() < 0.05, "{walked:?}");
    // Facing -Z: +X turned a quarter turn about Y.
    let [x, y, z, w] = walked.rotation;
    let facing = Rotation::from_xyzw(x, y, z, w) * Vector::X;
    assert!((facing + Vector::Z).length() < 1e-3, "{facing}");
    // Speed zero: it stops where it is.
    world.apply(&Command::walker_control(id, [0.0, 0.0, -1.0], 0.0, false));
    step(&mut world, 10);
    let stopped = state(&world, id);
    assert!((stopped.position[2] - walked.position[2]).abs() < 0.08);
    assert!(stopped.linear_velocity[2].abs() < 1e-3);
}

#[test]
fn a_walker_asked_for_with_its_feet_in_the_ground_stands_on_it() {
    let mut world = world_on_ground();
    // Its centre on the ground's surface, as CARLA's navigation points are.
    let id = spawned(
        &mut world,
        Command::spawn_walker([3.0, 0.0, 1.0], 0.3, 0.85),
    );
    let lifted = state(&world, id);
    assert!(
        (lifted.position[1] - 0.87).abs() < 1e-3,
        "2 cm above: {lifted:?}"
    );
    step(&mut world, 10);
    let settled = state(&world, id).position[1];
    assert!((0.85..0.87).contains(&settled), "{settled}");
    // Its head below the surface: refused.
    let r = world.apply(&Command::spawn_walker([6.0, -0.9, 1.0], 0.3, 0.85));
    assert_eq!(r.status, CommandStatus::SpawnCollision as u32);
}

#[test]
fn a_walker_jumps_once_and_lands_and_stops_at_a_wall() {
    let mut world = world_on_ground();
    let id = spawned(
        &mut world,
        Command::spawn_walker([0.0, 0.9, 0.0], 0.25, 0.9),
    );
    step(&mut world, 5);
    world.apply(&Command::walker_control(id, [1.0, 0.0, 0.0], 0.0, true));
    step(&mut world, 4);
    let up = state(&world, id).position[1];
    assert!(up > 1.1, "in the air: {up}");
    step(&mut world, 30);
    let down = state(&world, id).position[1];
    assert!((down - 0.9).abs() < 0.06, "landed: {down}");
    // A wall 2 m ahead (+X): the walker stops at it.
    world.insert(&crate::scene::Placement {
        kind: ActorKind::Static,
        extent: Vector::new(0.5, 2.0, 5.0),
        position: Vector::new(2.5, 2.0, 0.0),
        rotation: Vector::ZERO,
        linear_velocity: Vector::ZERO,
        density: 1.0,
        signal: None,
    });
    world.apply(&Command::walker_control(id, [1.0, 0.0, 0.0], 2.0, false));
    step(&mut world, 60);
    let x = state(&world, id).position[0];
    assert!(
        (1.6..2.0).contains(&x),
        "stopped at the wall's face (x = 2): {x}"
    );
}

#[test]
fn walker_commands_with_bad_values_or_on_other_actors_change_nothing() {
    let mut world = world_on_ground();
    let car = spawned(&mut world, Command::spawn_vehicle([10.0, 1.0, 0.0]));
    let id = spawned(
        &mut world,
        Command::spawn_walker([0.0, 0.9, 0.0], 0.25, 0.9),
    );
    for (command, status) in [
        (
            Command::walker_control(car, [1.0, 0.0, 0.0], 1.0, false),
            CommandStatus::NotAWalker,
        ),
        (
            Command::walker_control(id, [1.0, 0.0, 0.0], -1.0, false),
            CommandStatus::InvalidArgument,
        ),
        (
            Command::walker_control(id, [1.0, 0.0, 0.0], 21.0, false),
            CommandStatus::InvalidArgument,
        ),
        (
            Command::walker_control(id, [f32::NAN, 0.0, 0.0], 1.0, false),
            CommandStatus::InvalidArgument,
        ),
        (
            Command::vehicle_control(id, 1.0, 0.0, 0.0, false),
            CommandStatus::NotAVehicle,
        ),
        (
            Command::spawn_walker([5.0, 0.9, 0.0], 0.25, 0.2),
            CommandStatus::InvalidArgument,
        ),
        (
            Command::spawn_walker([5.0, 0.9, 0.0], 0.01, 0.9),
            CommandStatus::InvalidArgument,
        ),
        (
            Command::spawn_walker([5.0, 0.9, 0.0], 0.25, 6.0),
            CommandStatus::InvalidArgument,
        ),
    ] {
        assert_eq!(world.apply(&command).status, status as u32, "{command:?}");
    }
    step(&mut world, 10);
    assert!(
        state(&world, id).position[0].abs() < 1e-4,
        "nothing moved it"
    );
    assert_eq!(
        world.apply(&Command::destroy(id)).status,
        CommandStatus::Ok as u32
    );
    assert!(!world.walkers.contains(id));
}

#[test]
fn a_car_driven_into_a_walker_touches_it_and_the_walker_is_not_pushed_into_the_ground() {
    let mut world = world_on_ground();
    world.watch_contacts = true;
    let car = spawned(
        &mut world,
        Command::spawn_sized_vehicle([0.0, 1.0, 0.0], [2.4, 0.74, 1.08], 1850.0),
    );
    let walker = spawned(
        &mut world,
        Command::spawn_walker([8.0, 0.9, 0.0], 0.25, 0.9),
    );
    step(&mut world, 20);
    world.apply(&Command::vehicle_control(car, 1.0, 0.0, 0.0, false));
    let mut touched = false;
    for _ in 0..80 {
        step(&mut world, 1);
        touched |= world
            .contact_starts
            .iter()
            .any(|c| c.seen_by(car).is_some_and(|(other, _)| other == walker));
    }
    assert!(touched, "the car met the walker");
    assert!(state(&world, walker).position[1] > 0.8);
}

/// The flat scene's ground is 4 km wide: a capsule's casts touching it
/// lose precision by position (walkers sank up to 11 cm); rays do not.
#[test]
fn a_walker_stands_at_one_height_anywhere_on_a_wide_ground_and_steps_up_a_kerb() {
    let mut world = World::new(&crate::scene::Scene::Flat.placements(0), 1);
    let mut ids = Vec::new();
    for x in [-4.0f32, -2.0, 0.0, 2.0, 3.0, 4.0] {
        for z in [-4.0f32, -2.0, 0.0, 2.0, 3.0, 4.0] {
            ids.push(spawned(
                &mut world,
                Command::spawn_walker([x * 3.0, 0.0, z * 3.0], 0.1875, 0.9375),
            ));
        }
    }
    step(&mut world, 10);
    for id in ids {
        let y = state(&world, id).position[1];
        assert!((y - 0.9475).abs() < 1e-3, "actor {id}: {y}");
    }
    // A kerb 0.15 m high ahead: the walker steps up onto it and on.
    world.insert(&crate::scene::Placement {
        kind: ActorKind::Static,
        extent: Vector::new(5.0, 0.075, 5.0),
        position: Vector::new(40.0, 0.075, 0.0),
        rotation: Vector::ZERO,
        linear_velocity: Vector::ZERO,
        density: 1.0,
        signal: None,
    });
    let id = spawned(
        &mut world,
        Command::spawn_walker([33.0, 0.0, 0.0], 0.1875, 0.9375),
    );
    world.apply(&Command::walker_control(id, [1.0, 0.0, 0.0], 1.5, false));
    step(&mut world, 80);
    let on = state(&world, id).position;
    assert!(on[0] > 37.5, "walked on: {on:?}");
    assert!(
        (on[1] - (0.15 + 0.9475)).abs() < 1e-3,
        "on the kerb: {on:?}"
    );
}
