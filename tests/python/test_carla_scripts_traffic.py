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
import json, math, sys, time
import carla
from numpy import random

port, tm_port, vehicles, asynch = int(sys.argv[1]), int(sys.argv[2]), int(sys.argv[3]), sys.argv[4] == "asynch"
walkers, frames = int(sys.argv[5]), int(sys.argv[6])


def blueprints_of(world, pattern, generation):
    found = world.get_blueprint_library().filter(pattern)
    if generation.lower() == "all" or len(found) == 1:
        return found
    return [bp for bp in found if int(bp.get_attribute("generation")) == int(generation)]


vehicles_list, walkers_list, all_id, walked = [], [], [], []
crossed, floating, inside = set(), 0, 0
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

    # Walkers: random locations from the navigation, one batch of walkers,
    # one of their AI controllers.
    spawn_points = []
    for i in range(walkers):
        spawn_point = carla.Transform()
        loc = world.get_random_location_from_navigation()
        if loc != None:
            spawn_point.location = loc
            spawn_points.append(spawn_point)
    batch, walker_speed = [], []
    for spawn_point in spawn_points:
        walker_bp = random.choice(walker_blueprints)
        probability = random.randint(0, 100 + 1)
        if walker_bp.has_attribute("is_invincible"):
            walker_bp.set_attribute("is_invincible", "false")
        if walker_bp.has_attribute("can_use_wheelchair") and probability < 11:
            walker_bp.set_attribute("use_wheelchair", "true")
        if walker_bp.has_attribute("speed"):
            walker_speed.append(walker_bp.get_attribute("speed").recommended_values[1])
        else:
            print("Walker has no speed")
            walker_speed.append(0.0)
        batch.append(carla.command.SpawnActor(walker_bp, spawn_point))
    results = client.apply_batch_sync(batch, True)
    walker_speed2 = []
    for i in range(len(results)):
        if results[i].error:
            print("ERROR: " + results[i].error)
        else:
            walkers_list.append({"id": results[i].actor_id})
            walker_speed2.append(walker_speed[i])
    walker_speed = walker_speed2
    batch = []
    controller_bp = world.get_blueprint_library().find("controller.ai.walker")
    for i in range(len(walkers_list)):
        batch.append(carla.command.SpawnActor(controller_bp, carla.Transform(), walkers_list[i]["id"]))
    results = client.apply_batch_sync(batch, True)
    for i in range(len(results)):
        if results[i].error:
            print("ERROR: " + results[i].error)
        else:
            walkers_list[i]["con"] = results[i].actor_id
    for i in range(len(walkers_list)):
        all_id.append(walkers_list[i]["con"])
        all_id.append(walkers_list[i]["id"])
    all_actors = world.get_actors(all_id)
    if asynch:
        world.wait_for_tick()
    else:
        world.tick()
    world.set_pedestrians_cross_factor(0.0)
    for i in range(0, len(all_id), 2):
        all_actors[i].start()
        all_actors[i].go_to_location(world.get_random_location_from_navigation())
        all_actors[i].set_max_speed(float(walker_speed[int(i / 2)]))
    walker_ids = [w["id"] for w in walkers_list]
    walker_actors = list(world.get_actors(walker_ids))
    walker_start = {w.id: [w.get_location().x, w.get_location().y] for w in walker_actors}
    town = world.get_map()
    buildings = [b for b in world.get_actors().filter("static.prop.fixed")
                 if b.bounding_box.extent.z < 50 and b.get_location().z > 0.5]
    crossed, floating, inside = set(), 0, 0
    by_id = {a.id: a for a in world.get_actors(vehicles_list)}
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
                t = state.get_transform()
                at, v = t.location, state.get_velocity()
                seen = track.setdefault(actor_id, {"first": [at.x, at.y, at.z], "frames": 0,
                                                   "red_stops": 0, "upright": True,
                                                   "type": by_id[actor_id].type_id})
                seen["last"] = [at.x, at.y, at.z]
                seen["frames"] += 1
                seen["upright"] = max(abs(t.rotation.roll), abs(t.rotation.pitch)) < 60
                vehicle = by_id[actor_id]
                if (vehicle.is_at_traffic_light() and math.hypot(v.x, v.y) < 0.3
                        and vehicle.get_traffic_light_state() == carla.TrafficLightState.Red):
                    seen["red_stops"] += 1
        if ticks % 10 == 0:
            for w in walker_actors:
                at = w.get_location()
                # On a driving lane: crossing the road (at a crosswalk).
                if town.get_waypoint(at, project_to_road=False, lane_type=carla.LaneType.Driving):
                    crossed.add(w.id)
                floating += abs(at.z - w.bounding_box.extent.z) > 0.3
                inside += any(b.bounding_box.contains(at, b.get_transform()) for b in buildings)
    walked = [math.dist(walker_start[w.id], [w.get_location().x, w.get_location().y])
              for w in world.get_actors(walker_ids)]
finally:
    if not asynch:
        settings = original if original else world.get_settings()
        print("restore world_settings {}".format(settings))
        world.apply_settings(settings)
    print("\\ndestroying %d vehicles" % len(vehicles_list))
    client.apply_batch([carla.command.DestroyActor(x) for x in vehicles_list])
    for i in range(0, len(all_id), 2):
        all_actors[i].stop()
    print("\\ndestroying %d walkers" % len(walkers_list))
    client.apply_batch([carla.command.DestroyActor(x) for x in all_id])
    print("\\ndone.")
    print(json.dumps({"track": track, "ticks": ticks, "walked": walked,
                      "crossed": len(crossed), "floating": floating, "inside": inside}))
"""


def generate_traffic(request, mode, walkers=0, frames=200, gateway_args=()):
    """Runs the mirror with `-n 30 -w WALKERS` (and `--asynch` when `mode`
    is "asynch") for `frames` frames against a fresh pair on the town (with
    `gateway_args`; again on another should CARLA's own traffic manager
    deadlock: `carla_tm_deadlock.py`); returns (its lines, each vehicle's
    track, how far each walker walked)."""
    def attempt(gateway):
        status, out, err = run_script([
            sys.executable, "-c", GENERATE_TRAFFIC,
            str(gateway.port), str(free_port()), "30", mode, str(walkers), str(frames),
        ])
        assert status == 0, f"exit {status}\n{err[-3000:]}"
        assert "terminate called" not in err, err[-3000:]
        return out
    [out] = on_fresh_pairs(request, [attempt], server_args=["--scene", "town"],
                           gateway_args=gateway_args)
    lines = out.splitlines()
    result = json.loads(lines[-1])
    generate_traffic.walkers = result
    return lines[:-1], result["track"], result["walked"]


def assert_traffic_drove(lines, track, walkers=0):
    """What generate_traffic.py shows of a good run: its 30 vehicles, and
    its walkers but any whose random navigation point another walker took
    (CARLA logs such a spawn's error and goes on, as the mirror does)."""
    spawned = [l for l in lines if l.startswith("spawned 30 vehicles and ")]
    assert len(spawned) == 1, lines
    placed = int(spawned[0].split()[4])
    assert walkers - 1 <= placed <= walkers, spawned
    errors = [l for l in lines if l.startswith(("ERROR", "WARNING"))]
    assert len(errors) == walkers - placed, lines
    assert all("collision at spawn position" in l for l in errors), errors
    assert len(track) == 30
    moved = [math.dist(p["first"][:2], p["last"][:2]) for p in track.values()]
    assert all(math.isfinite(m) for m in moved), moved
    # The town's roads: most vehicles got somewhere, none left the ground.
    assert sum(m > 5.0 for m in moved) >= 20, moved
    assert all(-1.0 < p["last"][2] < 3.0 for p in track.values()), track
    assert [l for l in lines if l.strip()][-3:] == [
        "destroying 30 vehicles", f"destroying {placed} walkers", "done."], lines


def test_generate_traffic_30_vehicles_synchronous_200_frames(request):
    """Mirrors PythonAPI/examples/generate_traffic.py -n 30 -w 0 (CARLA
    0.9.16, synchronous by default): the traffic manager synchronous, the
    world at 0.05 s frames, 30 autopilot vehicles spawned in one
    `SpawnActor.then(SetAutopilot)` batch, 200 ticks, the settings put
    back (0.9.16 puts back the object it changed: synchronous stays on)."""
    lines, track, _ = generate_traffic(request, "sync", gateway_args=["--client-traffic-manager"])
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
    lines, track, _ = generate_traffic(request, "asynch")
    assert "synchronous_mode=False" in lines[0], lines
    assert lines[1] == "You are currently in asynchronous mode.", lines
    assert lines[2].startswith("apply_world_settings WorldSettings(synchronous_mode=False"), lines
    assert not [l for l in lines if l.startswith("restore world_settings")], lines
    assert_traffic_drove(lines, track)


def test_generate_traffic_defaults_2000_synchronous_frames_on_the_native_traffic_manager(request):
    """Mirrors PythonAPI/examples/generate_traffic.py with its defaults
    (CARLA 0.9.16: 30 vehicles, 10 walkers, synchronous) for 2 000 frames
    against the gateway's own traffic manager: no thread of CARLA's runs
    in the script, so nothing can deadlock; the vehicles drive the town,
    stop at red lights and go on, none rolls over; the walkers walk."""
    lines, track, walked = generate_traffic(request, "sync", walkers=10, frames=2000)
    assert_traffic_drove(lines, track, walkers=10)
    assert all(p["frames"] == 2000 for p in track.values()), "every vehicle in every tick"
    # Every vehicle on its wheels at the end (a knock between two may tilt
    # one for a moment).
    assert all(p["upright"] for p in track.values()), "no vehicle rolled over"
    stopped = [p for p in track.values() if p["red_stops"] > 0]
    assert len(stopped) >= 5, "vehicles wait at red lights"
    # A vehicle stopped at a red light went on: it waited less than the
    # whole run there.
    assert any(0 < p["red_stops"] < 1500 and math.dist(p["first"][:2], p["last"][:2]) > 50
               for p in stopped), stopped
    assert len(walked) >= 9 and sum(w > 5.0 for w in walked) >= len(walked) - 2, walked
    # Every controller walked its walker on the ground, never through a
    # building; some crossed a road (at its crosswalks: the cross factor
    # is 0).
    result = generate_traffic.walkers
    assert result["floating"] == 0 and result["inside"] == 0, result
    assert result["crossed"] >= 1, result


def test_the_native_traffic_managers_soak_runs_twice_short_with_no_hang():
    """The fault suite's soak (carla_tm_soak.py, 100 runs of 2 000 ticks
    there), twice with 300 ticks here: each run on a fresh pair, none
    hangs or fails."""
    import carla_tm_soak
    result = carla_tm_soak.soak(runs=2, ticks=300, walkers=10, limit=120, prefix="soak-test")
    assert (result["runs"], result["hangs"], result["failures"]) == (2, 0, 0), result
