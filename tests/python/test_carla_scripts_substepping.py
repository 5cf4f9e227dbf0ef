"""CARLA 0.9.16's `PythonAPI/util/check_collisions_substepping.py`,
mirrored: `load_world("Town03")` (simbus's town in its place), then per
collision scenario ten repetitions of: `reload_world()`, synchronous
settings at 20 frames/s with substepping at 100 physics steps/s (at most
16), the spectator placed, the scenario's vehicles spawned and launched
at each other, 100 ticks with every vehicle's location and velocities
recorded; then the repetitions compared. The script's normal outcome is
one line per scenario: `Deterministic Repetitions: [10] / 10`.

One test per scenario (the script runs them in one go, in this order);
each mirrors the script's calls for its scenario. Our own code, not the
script's."""

import numpy as np
import pytest

import carla

REPETITIONS = 10
TICKS = 100
FPS, FPS_PHYSICS = 20, 100
SPECTATOR = carla.Transform(carla.Location(120, -256, 10), carla.Rotation(yaw=180))

# Per scenario, per actor: blueprint filter, spawn (x, y, z, yaw), launch
# velocity (x, y, z).
SCENARIOS = {
    "TwoSpawnedCars": [
        ("tt", (100, -257, 0.02, 181.5), (-25, 0, 0)),
        ("lincoln", (110, -253, 0.04, 181.5), (-25, 0, 0)),
    ],
    "TwoCarsSlowSpeedCollision": [
        ("tt", (100, -256, 0.015, 178), (-12, 0, 0)),
        ("lincoln", (40, -255, 0.04, 0), (12, 0, 0)),
    ],
    "TwoCarsHighSpeedCollision": [
        ("tt", (140, -256, 0.015, 180), (-50, 0, 0)),
        ("lincoln", (40, -255, 0.04, 0), (50, 0, 0)),
    ],
    "CarBikeCollision": [
        ("*lincoln*", (50, -255, 0.04, 0), (30, 0, 0)),
        ("*gazelle*", (85, -245, 0.04, -90), (0, -12, 0)),
    ],
    "CarWalkerCollision": [
        ("*lincoln*", (50, -255, 0.04, 0), (20, 0, 0)),
        ("walker.pedestrian.0007", (85, -255, 1.00, -90), None),
    ],
    "ThreeCarsSlowSpeedCollision": [
        ("prius", (110, -255, 0.05, 180), (-15, 0, 0)),
        ("a2", (53, -257, 0.00, 0), (15, 0, 0)),
        ("lincoln", (85, -230, 0.04, -90), (0, -15, 0)),
    ],
    "ThreeCarsHighSpeedCollision": [
        ("prius", (110, -255, 0.05, 180), (-30, 0, 0)),
        ("a2", (53, -257, 0.00, 0), (30, 0, 0)),
        ("lincoln", (85, -230, 0.04, -90), (0, -30, 0)),
    ],
}


def transform(x, y, z, yaw):
    return carla.Transform(carla.Location(x, y, z), carla.Rotation(yaw=yaw))


def spawn_scene(world, actors):
    """The scenario's actors spawned, one tick, launched, one tick."""
    library = world.get_blueprint_library()
    spawned = []
    for pattern, (x, y, z, yaw), _ in actors:
        bp = library.filter(pattern)[0]
        if bp.has_attribute("is_invincible"):
            bp.set_attribute("is_invincible", "false")
        at = transform(x, y, z, yaw)
        spawned.append(world.spawn_actor(bp, at))
    world.tick()
    for actor, (_, _, velocity) in zip(spawned, actors):
        if velocity is None:
            actor.set_simulate_physics(True)
        else:
            actor.set_target_velocity(carla.Vector3D(*velocity))
    world.tick()
    return spawned


def run_once(client, world, settings, actors):
    """One repetition: per actor, a row per tick (frame and time since the
    start, location, velocity, angular velocity)."""
    original = world.get_settings()
    client.reload_world()
    world.apply_settings(settings)
    world.get_spectator().set_transform(SPECTATOR)
    start = world.get_snapshot()
    frame0, time0 = start.frame, start.timestamp.elapsed_seconds
    spawned = spawn_scene(world, actors)
    rows = [[] for _ in spawned]
    for _ in range(TICKS):
        world.tick()
        snapshot = world.get_snapshot()
        for row, actor in zip(rows, spawned):
            at, v, w = actor.get_location(), actor.get_velocity(), actor.get_angular_velocity()
            row.append([snapshot.frame - frame0, snapshot.timestamp.elapsed_seconds - time0,
                        at.x, at.y, at.z, v.x, v.y, v.z, w.x, w.y, w.z])
    world.apply_settings(original)
    for actor in spawned:
        actor.destroy()
    return [np.array(r) for r in rows]


def deterministic_repetitions(runs):
    """The script's verdict: for each repetition, how many repetitions
    match it (every actor within 0.01); the distinct counts, highest
    first."""
    same = [[all(np.amax(np.abs(a - b)) < 0.01 for a, b in zip(ri, rj)) for rj in runs] for ri in runs]
    return sorted({sum(row) for row in same}, reverse=True)


@pytest.mark.parametrize("scenario", list(SCENARIOS))
def test_check_collisions_substepping_scenario_is_deterministic(gateway, scenario):
    """Mirrors PythonAPI/util/check_collisions_substepping.py (CARLA
    0.9.16) for one of its scenarios: 10 repetitions at 20 frames/s with
    100 physics steps/s, all alike."""
    client = gateway.client(timeout=30.0)
    world = client.get_world()
    pre_settings = world.get_settings()
    world = client.load_world("Town03")
    assert world.get_map().name.startswith("simbus/town"), world.get_map().name
    spectator_at = carla.Transform(carla.Location(120, -256, 5), carla.Rotation(yaw=180))
    spectator_at.location.z += 5
    world.get_spectator().set_transform(spectator_at)
    try:
        settings = world.get_settings()
        settings.synchronous_mode = True
        settings.fixed_delta_seconds = 1.0 / FPS
        settings.substepping = True
        settings.max_substep_delta_time = 1.0 / FPS_PHYSICS
        settings.max_substeps = 16
        runs = [run_once(client, world, settings, SCENARIOS[scenario]) for _ in range(REPETITIONS)]
    finally:
        world.apply_settings(pre_settings)
    assert deterministic_repetitions(runs) == [REPETITIONS]
    first = runs[0]
    assert all(len(rows) == TICKS for rows in first)
    # The frames advance one by one, 0.05 s each, and the vehicles move.
    assert [r[0] for r in first[0]] == list(range(int(first[0][0][0]), int(first[0][0][0]) + TICKS))
    assert first[0][-1][1] - first[0][0][1] == pytest.approx((TICKS - 1) / FPS, abs=1e-6)
    launched = [rows for rows, (_, _, v) in zip(first, SCENARIOS[scenario]) if v is not None]
    assert all(np.linalg.norm(rows[-1][2:4] - rows[0][2:4]) > 1.0 for rows in launched)
    # On the ground all along: Town03's coordinates are on simbus's ground.
    assert all(-1.0 < z < 3.0 for rows in first for z in rows[:, 4]), [rows[-1][4] for rows in first]
