"""CARLA 0.9.16's `generate_traffic.py`, mirrored: our own script makes its
calls in its order with its arguments (`-n 30 -w 0`, synchronous by
default, and `--asynch`) against a gateway on simbus's town, and the test
asserts what the script shows a user: its lines, vehicles that drive, its
clean-up and its exit.

The script runs until Ctrl-C; the mirror stops after 200 frames (ticks it
gives, or ticks it waits for; asynchronous frames run on to the 10
simulated seconds 200 of CARLA's frames last, since simbus steps them
faster) and then runs the script's `finally`. It
runs as its own process (the traffic manager lives in the script's
process, on a free port instead of CARLA's 8000)."""

import json
import math
import sys

from carla_tm_deadlock import on_fresh_pairs, run_script
from test_carla_traffic_manager import free_port

GENERATE_TRAFFIC = """
import json, sys, time
import carla
from numpy import random

port, tm_port, vehicles, asynch = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4] == "asynch"
walkers, frames = 0, 200


def blueprints_of(world, pattern, generation):
    found = world.get_blueprint_library().filter(pattern)
    if generation.lower() == "all" or len(found) == 1:
        return found
    return [bp for bp in found if int(bp.get_attribute("generation")) == int(generation)]


vehicles_list, walkers_list, all_id = [], [], []
client = carla.Client("127.0.0.1", port)
client.set_timeout(10.0)
random.seed(int(time.time()))
original = None
track = {}
try:
    world = client.get_world()
    tm = client.get_trafficmanager(tm_port)
    tm.set_global_distance_to_leading_vehicle(2.5)
    original = world.get_settings()
    print("current_world_settings {}".format(original))
    settings = original
    if not asynch:
        tm.set_synchronous_mode(True)
        if not settings.synchronous_mode:
            settings.synchronous_mode = True
            settings.fixed_delta_seconds = 0.05
    else:
        print("You are currently in asynchronous mode.")
    print("apply_world_settings {}".format(settings))
    world.apply_settings(settings)
    print("settings applied")

    blueprints = blueprints_of(world, "vehicle.*", "All")
    if not blueprints:
        raise ValueError("Couldn't find any vehicles with the specified filters")
    walker_blueprints = blueprints_of(world, "walker.pedestrian.*", "2")
    if not walker_blueprints:
        raise ValueError("Couldn't find any walkers with the specified filters")
    blueprints = sorted(blueprints, key=lambda bp: bp.id)

    spawn_points = world.get_map().get_spawn_points()
    if vehicles < len(spawn_points):
        random.shuffle(spawn_points)
    elif vehicles > len(spawn_points):
        print("WARNING: requested %d vehicles, but could only find %d spawn points" % (vehicles, len(spawn_points)))
        vehicles = len(spawn_points)

    batch = []
    for transform in spawn_points[:vehicles]:
        bp = random.choice(blueprints)
        if bp.has_attribute("color"):
            bp.set_attribute("color", random.choice(bp.get_attribute("color").recommended_values))
        if bp.has_attribute("driver_id"):
            bp.set_attribute("driver_id", random.choice(bp.get_attribute("driver_id").recommended_values))
        bp.set_attribute("role_name", "autopilot")
        batch.append(carla.command.SpawnActor(bp, transform).then(
            carla.command.SetAutopilot(carla.command.FutureActor, True, tm.get_port())))
    for response in client.apply_batch_sync(batch, do_tick=True):
        if response.error:
            print("ERROR: " + response.error)
        else:
            vehicles_list.append(response.actor_id)

    # Zero walkers: no locations, empty spawn batches, no controllers.
    results = client.apply_batch_sync([], do_tick=True)
    controller_bp = world.get_blueprint_library().find("controller.ai.walker")
    results = client.apply_batch_sync([], do_tick=True)
    all_actors = world.get_actors(all_id)
    if asynch:
        world.wait_for_tick()
    else:
        world.tick()
    world.set_pedestrians_cross_factor(0.0)
    print("spawned %d vehicles and %d walkers, press Ctrl+C to exit." % (len(vehicles_list), len(walkers_list)))
    tm.global_percentage_speed_difference(30.0)

    start, ticks = world.get_snapshot().timestamp.elapsed_seconds, 0
    # 200 frames; asynchronous frames come as fast as simbus steps them,
    # so those run on to the 10 simulated seconds of 200 CARLA frames.
    while ticks < frames or (asynch and world.get_snapshot().timestamp.elapsed_seconds - start < 10.0):
        if not asynch:
            world.tick()
        else:
            world.wait_for_tick()
        ticks += 1
        snapshot = world.get_snapshot()
        for actor_id in vehicles_list:
            state = snapshot.find(actor_id)
            if state is not None:
                at = state.get_transform().location
                seen = track.setdefault(actor_id, {"first": [at.x, at.y, at.z], "frames": 0})
                seen["last"] = [at.x, at.y, at.z]
                seen["frames"] += 1
finally:
    if not asynch:
        settings = original if original else world.get_settings()
        print("restore world_settings {}".format(settings))
        world.apply_settings(settings)
    print("\\ndestroying %d vehicles" % len(vehicles_list))
    client.apply_batch([carla.command.DestroyActor(x) for x in vehicles_list])
    print("\\ndestroying %d walkers" % len(walkers_list))
    client.apply_batch([carla.command.DestroyActor(x) for x in all_id])
    print("\\ndone.")
    print(json.dumps({"track": track, "ticks": ticks}))
"""


def generate_traffic(request, mode):
    """Runs the mirror with `-n 30 -w 0` (and `--asynch` when `mode` is
    "asynch") against a fresh pair on the town (again on another should
    CARLA's traffic manager deadlock: `carla_tm_deadlock.py`); returns
    (its lines, each vehicle's positions per frame)."""
    def attempt(gateway):
        status, out, err = run_script([
            sys.executable, "-c", GENERATE_TRAFFIC,
            str(gateway.port), str(free_port()), "30", mode,
        ])
        assert status == 0, f"exit {status}\n{err[-3000:]}"
        assert "terminate called" not in err, err[-3000:]
        return out
    [out] = on_fresh_pairs(request, [attempt], server_args=["--scene", "town"])
    lines = out.splitlines()
    return lines[:-1], json.loads(lines[-1])["track"]


def assert_traffic_drove(lines, track):
    assert "spawned 30 vehicles and 0 walkers, press Ctrl+C to exit." in lines, lines
    assert not [l for l in lines if l.startswith(("ERROR", "WARNING"))], lines
    assert len(track) == 30
    moved = [math.dist(p["first"][:2], p["last"][:2]) for p in track.values()]
    assert all(math.isfinite(m) for m in moved), moved
    # The town's roads: most vehicles got somewhere, none left the ground.
    assert sum(m > 5.0 for m in moved) >= 20, moved
    assert all(-1.0 < p["last"][2] < 3.0 for p in track.values()), track
    assert [l for l in lines if l.strip()][-3:] == [
        "destroying 30 vehicles", "destroying 0 walkers", "done."], lines


def test_generate_traffic_30_vehicles_synchronous_200_frames(request):
    """Mirrors PythonAPI/examples/generate_traffic.py -n 30 -w 0 (CARLA
    0.9.16, synchronous by default): the traffic manager synchronous, the
    world at 0.05 s frames, 30 autopilot vehicles spawned in one
    `SpawnActor.then(SetAutopilot)` batch, 200 ticks, the settings put
    back (0.9.16 puts back the object it changed: synchronous stays on)."""
    lines, track = generate_traffic(request, "sync")
    assert "synchronous_mode=False" in lines[0], lines
    assert lines[1].startswith("apply_world_settings WorldSettings(synchronous_mode=True"), lines
    assert "fixed_delta_seconds=0.05" in lines[1], lines
    assert lines[2] == "settings applied", lines
    assert_traffic_drove(lines, track)
    assert all(p["frames"] == 200 for p in track.values()), "every vehicle in every tick"
    assert [l for l in lines if l.startswith("restore world_settings")] == [
        lines[1].replace("apply_world_settings", "restore world_settings")], lines


def test_generate_traffic_30_vehicles_asynchronous_200_frames(request):
    """Mirrors PythonAPI/examples/generate_traffic.py -n 30 -w 0 --asynch
    (CARLA 0.9.16): the world left asynchronous (the script says so), 30
    autopilot vehicles, 200 frames (and 10 simulated seconds) waited for,
    nothing put back."""
    lines, track = generate_traffic(request, "asynch")
    assert "synchronous_mode=False" in lines[0], lines
    assert lines[1] == "You are currently in asynchronous mode.", lines
    assert lines[2].startswith("apply_world_settings WorldSettings(synchronous_mode=False"), lines
    assert not [l for l in lines if l.startswith("restore world_settings")], lines
    assert_traffic_drove(lines, track)
