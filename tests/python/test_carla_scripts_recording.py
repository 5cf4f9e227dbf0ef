"""CARLA 0.9.16's recorder examples, mirrored in the order a user runs
them: `start_recording.py` (10 autopilot vehicles recorded), then
`show_recorder_file_info.py`, `show_recorder_collisions.py` and
`start_replaying.py` on the file it wrote, each with its default
arguments but the file (`-f`, here a file in the test's own folder).

The recording script starts a traffic manager (`SetAutopilot`), so it runs
as its own process (on a free traffic-manager port instead of CARLA's
8000); the others run in the test. CARLA's scripts are not copied here:
these are our own calls, in their order with their arguments."""

import json
import re

import carla
import pytest

from conftest import kill_all, start, world_name
from test_carla_scripts_examples import run_mirror, vehicle_ids
from test_carla_traffic_manager import free_port

START_RECORDING = """
import json, random, sys
import carla

port, tm_port, name = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
actor_list = []
try:
    client = carla.Client("127.0.0.1", port)
    client.set_timeout(2.0)
    world = client.get_world()
    blueprints = world.get_blueprint_library().filter("vehicle.*")
    spawn_points = world.get_map().get_spawn_points()
    random.shuffle(spawn_points)
    print("found %d spawn points." % len(spawn_points))
    count = 10
    print("Recording on file: %s" % client.start_recorder(name=name))
    spawn_points = world.get_map().get_spawn_points()
    if count < len(spawn_points):
        random.shuffle(spawn_points)
    elif count > len(spawn_points):
        count = len(spawn_points)
    batch = []
    for transform in spawn_points[:count]:
        blueprint = random.choice(blueprints)
        if blueprint.has_attribute("color"):
            blueprint.set_attribute("color", random.choice(blueprint.get_attribute("color").recommended_values))
        blueprint.set_attribute("role_name", "autopilot")
        batch.append(carla.command.SpawnActor(blueprint, transform).then(
            carla.command.SetAutopilot(carla.command.FutureActor, True, tm_port)))
    for response in client.apply_batch_sync(batch):
        if response.error:
            print("ERROR: " + response.error)
        else:
            actor_list.append(response.actor_id)
    print("spawned %d vehicles, press Ctrl+C to exit." % len(actor_list))
    types = {a.id: a.type_id for a in world.get_actors(actor_list)}
    # The script waits for ticks until Ctrl-C: the mirror, 5 simulated s.
    start = world.wait_for_tick().timestamp.elapsed_seconds
    while world.wait_for_tick().timestamp.elapsed_seconds - start < 5.0:
        pass
finally:
    print("\\ndestroying %d actors" % len(actor_list))
    client.apply_batch_sync([carla.command.DestroyActor(x) for x in actor_list])
    print("Stop recording")
    client.stop_recorder()
    print("\\ndone.")
    print(json.dumps({str(k): v for k, v in types.items()}))
"""


def record(gateway, path):
    """Runs the `start_recording.py` mirror into `path`; returns its lines
    and the type id of each vehicle it spawned, by CARLA id."""
    done = run_mirror(START_RECORDING, gateway.port, free_port(), path, timeout=300)
    assert done.returncode == 0, f"exit {done.returncode}\n{done.stderr[-3000:]}"
    assert "terminate called" not in done.stderr, done.stderr[-3000:]
    lines = done.stdout.splitlines()
    return lines[:-1], {int(k): v for k, v in json.loads(lines[-1]).items()}


def test_start_recording_then_file_info_collisions_and_replay(gateway, tmp_path, request):
    """Mirrors PythonAPI/examples/start_recording.py (10 vehicles on
    autopilot, recorded), then show_recorder_file_info.py,
    show_recorder_collisions.py (`-t aa`) and start_replaying.py (time
    factor 1, heroes and spectator as by default, offset behind and
    above) on `-f <that file>` (CARLA 0.9.16)."""
    path = str(tmp_path / "test1.log")
    lines, spawned = record(gateway, path)
    assert re.fullmatch(r"found \d+ spawn points\.", lines[0]), lines
    assert lines[1] == f"Recording on file: {path}", lines
    assert "spawned 10 vehicles, press Ctrl+C to exit." in lines, lines
    assert [l for l in lines if l.strip()][-3:] == ["destroying 10 actors", "Stop recording", "done."]
    assert len(spawned) == 10

    client = gateway.client(timeout=60.0)
    info = client.show_recorder_file_info(path, False)
    head = info.splitlines()[:5]
    assert head[0] == "Version: 1", info[:400]
    assert head[1].startswith("Map: ") and head[2].startswith("Date: "), info[:400]
    assert head[3] == "" and re.fullmatch(r"Frame \d+ at [0-9.e-]+ seconds", head[4]), info[:400]
    created = dict(re.findall(r"^ Create (\d+): (\S+) \(", info, re.M))
    for actor_id, type_id in spawned.items():
        assert created.get(str(actor_id)) == type_id, (actor_id, type_id, created)
    # The script destroys its vehicles in one batch and stops the recorder
    # at once: each vehicle's Destroy is in the file (from the batch's
    # commands, before the frame that shows them gone).
    destroyed = set(re.findall(r"^ Destroy (\d+)$", info, re.M))
    assert {str(i) for i in spawned} <= destroyed, (spawned, destroyed)
    assert re.search(r"^Frames: \d+$", info, re.M) and re.search(r"^Duration: [0-9.]+ seconds$", info, re.M)
    # Read through another server + gateway (as the census runs each
    # script on a fresh pair): the blueprints' type ids, kept beside the
    # file when the recording stopped, name the vehicles all the same.
    procs = []
    try:
        reader = start(world_name(request, "-reader"), [], procs)
        again = reader.client(timeout=60.0).show_recorder_file_info(path, True)
    finally:
        kill_all(procs)
    assert dict(re.findall(r"^ Create (\d+): (\S+) \(", again, re.M)) == created
    # With show_all, the frames' positions (the default scene has no lights).
    assert re.search(r"^ Positions: \d+$", again, re.M), again[:600]

    collisions = client.show_recorder_collisions(path, "a", "a")
    assert collisions.splitlines()[0] == "Version: 1", collisions[:400]
    assert re.search(r"^ +Time +Types +Id Actor 1 +Id Actor 2", collisions, re.M), collisions[:600]
    for row in re.findall(r"^ +\d+ +[a-z] [a-z] +(\d+) \S+ +(\d+) \S+", collisions, re.M):
        assert set(row) <= set(created), (row, created)
    assert re.search(r"^Frames: \d+$", collisions, re.M), collisions[-200:]

    world = client.get_world()
    world.wait_for_tick()
    before = vehicle_ids(world)
    client.set_replayer_time_factor(1.0)
    client.set_replayer_ignore_hero(False)
    client.set_replayer_ignore_spectator(True)
    offset = carla.Transform(carla.Location(-10, 0, 5), carla.Rotation(-25, 0, 0))
    answer = client.replay_file(path, 0.0, 0.0, 0, False, offset)
    assert answer.startswith("Replaying") and "test1.log" in answer, answer
    # The replay brings the 10 recorded vehicles back into the world.
    replayed = before
    for _ in range(500):
        world.wait_for_tick()
        replayed = vehicle_ids(world)
        if len(replayed) >= len(before) + 10:
            break
    assert len(replayed) >= len(before) + 10, (before, replayed)
