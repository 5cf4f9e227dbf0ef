"""CARLA 0.9.16's own client gets CARLA's meaning of the recorder calls'
arguments through the gateway: `show_recorder_actors_blocked` reads its
`min_distance` in centimetres, `set_replayer_time_factor` before
`replay_file` applies to that replay, and `show_recorder_collisions` takes
every CARLA category letter ('a' any, 'v' vehicle, 'w' walker, 't' traffic
light, 'o' other, 'h' hero). Their answers are CARLA's text (see
test_carla_recorder_text.py); the tests read its rows as CARLA users do."""

import json
import re

import carla
import pytest

from conftest import synced

EMPTY = [["--scene", "empty"]]


def record(client, world, path, ticks):
    """Records `ticks` ticks of `world` to `path`."""
    assert client.start_recorder(path, False) == path
    for _ in range(ticks):
        world.tick()
    client.stop_recorder()


# A row of CARLA's blocked-actors table: time, id, type id, duration.
BLOCKED_ROW = re.compile(r"^\s*\d+\s+(\d+)\s+(\S+)\s+\d+\s*$")
# A row of CARLA's collisions table: time, the two categories, then id and
# type id of each actor.
COLLISION_ROW = re.compile(r"^\s*\d+\s+([a-z]) ([a-z])\s+(\d+) (\S+)\s+(\d+) (\S+)\s*$")


def blocked_ids(client, path, min_time, min_distance):
    answer = client.show_recorder_actors_blocked(path, min_time, min_distance)
    return {int(m.group(1)) for m in map(BLOCKED_ROW.match, answer.splitlines()) if m}


@pytest.mark.parametrize("gateway", EMPTY, indirect=True)
def test_actors_blocked_reads_min_distance_in_centimetres(gateway, tmp_path):
    client, world = synced(gateway)
    library = world.get_blueprint_library()
    # A box falling in an empty scene (no ground): over 1.2 m in any 0.5 s
    # of the recording, under 10 m in all of it.
    box = world.spawn_actor(library.find("static.prop.box"), carla.Transform(carla.Location(z=5)))
    world.tick()
    path = str(tmp_path / "falling.mcap")
    record(client, world, path, 20)
    # 30 cm in 0.5 s: it falls farther, so it is never blocked (read as
    # 30 m, it would be blocked all along).
    assert box.id not in blocked_ids(client, path, 0.5, 30.0)
    # 1000 cm (10 m) in 0.5 s: it falls less, so it is blocked.
    assert box.id in blocked_ids(client, path, 0.5, 1000.0)
    # CARLA's unit is named when min_distance is not positive.
    with pytest.raises(RuntimeError, match="centimetres"):
        client.show_recorder_actors_blocked(path, 0.5, 0.0)


def test_a_time_factor_set_before_replay_file_applies_to_that_replay(gateway, tmp_path):
    client, world = synced(gateway)
    path = str(tmp_path / "run.mcap")
    record(client, world, path, 10)
    client.set_replayer_time_factor(2.5)
    assert "frames" in client.replay_file(path, 0.0, 0.0, 0, False)
    status = gateway.sim_client("recorder", "status", "--json")
    assert status.returncode == 0, status.stderr
    replay = json.loads(status.stdout)["replay"]
    assert replay["state"] == "running"
    assert replay["time_factor"] == 2.5
    # A factor that is not positive is refused (CARLA's client sends this
    # call without reading its answer) and the kept one stays.
    client.set_replayer_time_factor(-1.0)
    client.stop_replayer(False)
    client.replay_file(path, 0.0, 0.0, 0, False)
    status = json.loads(gateway.sim_client("recorder", "status", "--json").stdout)
    assert status["replay"]["time_factor"] == 2.5
    client.stop_replayer(False)


def test_collisions_take_every_carla_category(gateway, tmp_path):
    client, world = synced(gateway)
    # The default scene: boxes fall onto the ground and onto each other,
    # in its first seconds: from the start (a loaded machine may have run
    # the young world past their fall before this test's first call).
    world = client.reload_world(False)
    path = str(tmp_path / "scene.mcap")
    record(client, world, path, 40)

    def pairs(category1, category2):
        answer = client.show_recorder_collisions(path, category1, category2)
        rows = [m for m in map(COLLISION_ROW.match, answer.splitlines()) if m]
        # Each actor's category letter goes with its type id.
        for m in rows:
            for letter, type_id in ((m.group(1), m.group(4)), (m.group(2), m.group(6))):
                assert letter == ("v" if type_id.startswith("vehicle.") else "o"), answer
        return {(int(m.group(3)), m.group(4), int(m.group(5)), m.group(6)) for m in rows}

    def vehicle(type_id):
        return type_id.startswith("vehicle.")

    everything = pairs("a", "a")
    # 'o' other: anything not a vehicle (simbus has no walkers or traffic lights).
    others = {p for p in everything if not vehicle(p[1]) and not vehicle(p[3])}
    # The ground (a fixed prop) and boxes.
    ground, box = "static.prop.fixed", "static.prop.box"
    assert any(p[1] == ground or p[3] == ground for p in others), everything
    assert any(p[1] == box and p[3] == box for p in others), everything
    assert pairs("o", "o") == others
    assert pairs("a", "o") == {p for p in everything if not vehicle(p[1]) or not vehicle(p[3])}
    assert pairs("o", "a") == pairs("a", "o")
    vehicles = {p for p in everything if vehicle(p[1]) or vehicle(p[3])}
    assert pairs("v", "a") == vehicles
    assert pairs("v", "o") == {p for p in vehicles if not vehicle(p[1]) or not vehicle(p[3])}
    # No walker, traffic light or hero took part.
    for category in "wth":
        assert pairs(category, "a") == set()
        assert pairs("o", category) == set()
