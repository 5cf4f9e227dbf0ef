"""CARLA's traffic manager against the gateway, with the real `carla`
wheel, both ways a script can get one:

- the gateway's own (the default): CARLA's client finds a traffic manager
  running on the port it asks for and drives it remotely over CARLA's
  traffic-manager RPC protocol; the gateway steps it in lockstep with the
  world, so nothing of CARLA's traffic manager runs in the script;
- CARLA's (`--client-traffic-manager`): it runs inside the script's
  process and drives vehicles through ordinary RPCs; the gateway keeps the
  registry of running traffic managers and the streamed vehicle state it
  reads (speed limit, traffic-light state, elapsed time). CARLA 0.9.16's
  can deadlock in synchronous mode on its own (`carla_tm_deadlock.py`):
  such a run is made again on a fresh pair.

Scripts run as their own processes (`carla_tm_run.py`): a traffic manager
in a script binds its port and keeps threads until its process ends."""

import json
import math
import os
import socket
import subprocess
import sys
import time

import msgpack
import pytest

from conftest import Raw, synced

from carla_tm_deadlock import on_fresh_pairs, run_script

HERE = os.path.dirname(os.path.abspath(__file__))

# The gateway flags of each traffic manager.
MANAGERS = {"native": [], "client": ["--client-traffic-manager"]}


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def tm_run(*args):
    """An attempt (carla_tm_deadlock.on_fresh_pairs) at carla_tm_run.py
    with `args`: its JSON."""
    def attempt(gateway):
        status, out, err = run_script([
            sys.executable, os.path.join(HERE, "carla_tm_run.py"),
            "--port", str(gateway.port), "--tm-port", str(free_port()), *args,
        ])
        assert status == 0, f"exit {status}\n{err[-3000:]}"
        return json.loads(out.strip().splitlines()[-1])
    return attempt


@pytest.mark.parametrize("manager", MANAGERS)
def test_autopilot_vehicles_drive_along_the_town_roads(request, manager):
    [out] = on_fresh_pairs(request, [tm_run("--vehicles", "10", "--ticks", "200")],
                           gateway_args=MANAGERS[manager])
    assert out["map"].startswith("simbus/town"), out["map"]
    assert out["spawn_points"] >= 100
    first, last = out["ticks"][0], out["ticks"][-1]
    moved = [math.dist(a[1:3], b[1:3]) for a, b in zip(first, last)]
    # 10 s of driving at up to 36 km/h: nothing went flying (NaN
    # controls, a fall off the world), and most vehicles got somewhere. A
    # vehicle spawned a few metres before a junction stops at its light,
    # red three quarters of a 60 s cycle, and may wait the whole 10 s.
    assert all(math.isfinite(m) for m in moved), moved
    assert sum(m > 5.0 for m in moved) >= 6, moved
    assert all(-1.0 < row[3] < 3.0 for row in last), last


@pytest.mark.parametrize("manager", MANAGERS)
def test_the_seeds_determinism_example_repeats_exactly(request, manager):
    """Two fresh server + gateway pairs, the same seed: every vehicle's
    and (with the gateway's traffic manager) every AI walker's transform
    identical at every tick, on the town with its lights cycling; a third
    with another seed differs."""
    walkers = ["--walkers", "10"] if manager == "native" else []
    runs = on_fresh_pairs(request, [
        tm_run("--seed", str(seed), "--vehicles", "30", "--ticks", "500", *walkers)
        for seed in (7, 7, 8)
    ], gateway_args=MANAGERS[manager])
    a, b, c = runs
    assert len(a["ticks"]) == 500 and len(a["ids"]) == 30
    assert len(a["walkers"]) == (10 if walkers else 0)
    assert a["ticks"] == b["ticks"], "the same seed gives the same run, tick by tick"
    assert a["ticks"] != c["ticks"], "another seed gives another run"
    moved = [math.dist(p[1:3], q[1:3]) for p, q in zip(a["ticks"][0], a["ticks"][-1])]
    assert sum(m > 5.0 for m in moved) >= 20, moved


CLIENT_SIDE = [{"gateway": MANAGERS["client"]}]


@pytest.mark.parametrize("gateway", CLIENT_SIDE, indirect=True)
def test_the_registry_forgets_a_traffic_manager_whose_client_left(gateway):
    """A script that started a traffic manager and exited leaves no entry:
    the next one starts its own at once instead of waiting for a dead one."""
    tm_port = free_port()
    script = f"""
import carla, json, sys
client = carla.Client("127.0.0.1", {gateway.port})
client.set_timeout(10.0)
tm = client.get_trafficmanager({tm_port})
print(json.dumps({{"port": tm.get_port()}}))
"""
    for _ in range(2):
        done = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
        assert done.returncode == 0, done.stderr[-2000:]
        assert json.loads(done.stdout.splitlines()[-1]) == {"port": tm_port}
        assert "not responding" not in done.stderr, done.stderr


@pytest.mark.parametrize("gateway", CLIENT_SIDE, indirect=True)
def test_the_registry_answers_as_carlas_and_drops_a_closed_connections_entry(gateway):
    owner, other = Raw(gateway.port), Raw(gateway.port)
    port = free_port()
    assert owner.call("is_traffic_manager_running", port) == [[1, False]]
    assert owner.call("get_traffic_manager_running", port) == [[1, ["", 0]]]
    assert owner.call("add_traffic_manager_running", ["127.0.0.1", port]) == [[1, True]]
    # A second registration of the port is refused, as CARLA's.
    assert other.call("add_traffic_manager_running", ["10.0.0.9", port]) == [[1, False]]
    assert other.call("get_traffic_manager_running", port) == [[1, ["127.0.0.1", port]]]
    # Garbage is an error, and changes nothing.
    assert other.call("add_traffic_manager_running", "nonsense")[0][0] == 0
    assert other.call("is_traffic_manager_running", 70000)[0][0] == 0
    assert other.call("is_traffic_manager_running", port) == [[1, True]]
    # The owner's connection closes: its entry goes with it.
    owner.sock.close()
    deadline = time.monotonic() + 10
    while other.call("is_traffic_manager_running", port) == [[1, True]]:
        assert time.monotonic() < deadline, "the entry outlived its connection"
    assert other.call("add_traffic_manager_running", ["127.0.0.1", port]) == [[1, True]]
    assert other.call("destroy_traffic_manager", port) == [[1, True]]
    assert other.call("destroy_traffic_manager", port) == [[1, False]]


class TrafficManagerRpc:
    """A plain rpclib connection, as CARLA's `TrafficManagerClient` makes
    one (no CARLA metadata element)."""

    def __init__(self, port):
        self.sock = socket.create_connection(("127.0.0.1", port))
        self.sock.settimeout(10)
        self.unpacker = msgpack.Unpacker(raw=False)
        self.msgid = 0

    def send(self, data):
        self.sock.sendall(data)

    def call(self, method, *args):
        """(error, result) of `method`."""
        self.msgid += 1
        self.send(msgpack.packb([0, self.msgid, method, list(args)]))
        while True:
            for message in self.unpacker:
                assert message[0] == 1 and message[1] == self.msgid, message
                return message[2], message[3]
            data = self.sock.recv(65536)
            assert data, "the traffic manager closed the connection"
            self.unpacker.feed(data)


def test_the_native_traffic_manager_answers_carlas_calls_and_refuses_garbage(gateway):
    """The gateway says a traffic manager runs on any port a client asks
    about (CARLA's client then drives it remotely), at the address the
    client reached; a script cannot register one of its own there; its
    protocol answers every call CARLA's `TrafficManagerClient` makes and
    refuses bad arguments, unknown calls and garbage without harm."""
    raw = Raw(gateway.port)
    port = free_port()
    assert raw.call("is_traffic_manager_running", port) == [[1, True]]
    assert raw.call("get_traffic_manager_running", port) == [[1, ["127.0.0.1", port]]]
    assert raw.call("add_traffic_manager_running", ["127.0.0.1", port]) == [[1, False]]
    tm = TrafficManagerRpc(port)
    assert tm.call("health_check_remote_TM") == (None, None)
    assert tm.call("synchronous_tick") == (None, True)
    for method, args in [
        ("set_synchronous_mode", [True]),
        ("set_random_device_seed", [42]),
        ("set_global_distance_to_leading_vehicle", [2.5]),
        ("set_global_percentage_speed_difference", [30.0]),
        ("set_hybrid_physics_mode", [True]),
        ("set_hybrid_physics_radius", [70.0]),
        ("set_respawn_dormant_vehicles", [True]),
        ("set_boundaries_respawn_dormant_vehicles", [25.0, 50.0]),
        ("set_percentage_running_light", [[7, 0, [0, "vehicle.x", []]], 50.0]),
        ("set_desired_speed", [[7, 0, [0, "vehicle.x", []]], 40.0]),
        ("set_path", [[7, 0, [0, "vehicle.x", []]], [[1.0, 2.0, 0.0]], True]),
        ("set_imported_route", [[7, 0, [0, "vehicle.x", []]], b"\x01\x02\x03", True]),
        ("keep_slow_lane_rule_percentage", [[7, 0, [0, "vehicle.x", []]], 10.0]),
        ("get_next_action", [7]),
    ]:
        assert tm.call(method, *args) == (None, None), method
    error, _ = tm.call("set_percentage_running_light", [7, 0, []], 150.0)
    assert "percentage" in error, error
    error, _ = tm.call("set_desired_speed", "seven", 40.0)
    assert "actor" in error, error
    error, _ = tm.call("set_global_distance_to_leading_vehicle")
    assert "arguments" in error, error
    error, _ = tm.call("no_such_call", 1)
    assert "no_such_call" in error, error
    # Garbage closes that connection only.
    bad = TrafficManagerRpc(port)
    bad.send(b"\xc1\xc1\xc1 not msgpack")
    assert bad.sock.recv(100) == b""
    assert tm.call("health_check_remote_TM") == (None, None)
    assert raw.call("is_traffic_manager_running", port) == [[1, True]]


SYNC_TOWN = [["--scene", "town"]]


@pytest.mark.parametrize("gateway", SYNC_TOWN, indirect=True)
def test_the_native_traffic_manager_obeys_its_settings_per_vehicle(gateway):
    """Two autopilot vehicles far apart, one told to go 50 % under the
    limit and one at 18 km/h: each holds its own speed, and reports the
    controls it was given. Nothing of CARLA's traffic manager runs here:
    the script's calls go to the gateway's (lights, walkers and the
    percentages that ignore them: the planner's unit tests)."""
    client, world = synced(gateway)
    tm = client.get_trafficmanager(free_port())
    tm.set_synchronous_mode(True)
    tm.set_random_device_seed(3)
    library = world.get_blueprint_library()
    bp = library.find("vehicle.tesla.model3")
    town = world.get_map()
    # Two spawn points on long straights, far apart.
    points = sorted(town.get_spawn_points(), key=lambda t: (round(t.location.x), round(t.location.y)))
    slow = world.spawn_actor(bp, points[0])
    fixed = world.spawn_actor(bp, points[len(points) // 2])
    for v in (slow, fixed):
        v.set_autopilot(True, tm.get_port())
    tm.vehicle_percentage_speed_difference(slow, 50.0)
    tm.set_desired_speed(fixed, 18.0)
    speeds = {slow.id: [], fixed.id: []}
    for _ in range(300):
        world.tick()
        for v in (slow, fixed):
            vel = v.get_velocity()
            speeds[v.id].append(math.hypot(vel.x, vel.y))
    # Cruising speeds: the fastest each held over the last 10 s.
    assert 2.0 < max(speeds[slow.id][100:]) < 4.17 * 1.15, max(speeds[slow.id][100:])
    assert 3.0 < max(speeds[fixed.id][100:]) < 5.0 * 1.15, max(speeds[fixed.id][100:])
    # The controls it sends are what the vehicles report.
    control = slow.get_control()
    assert 0.0 <= control.throttle <= 1.0 and 0.0 <= control.brake <= 1.0
    for v in (slow, fixed):
        v.set_autopilot(False, tm.get_port())


def test_the_native_traffic_manager_drives_the_world_a_script_loads_after_it(gateway):
    """A traffic manager asked for on the default scene, then a load of
    CARLA's town (simbus's in its place): the vehicles spawned on autopilot
    there follow the town's roads (the manager reads each episode's
    scene)."""
    client = gateway.client(timeout=20.0)
    tm = client.get_trafficmanager(free_port())
    world = client.load_world("Town10HD_Opt")
    settings = world.get_settings()
    settings.synchronous_mode = True
    settings.fixed_delta_seconds = 0.05
    world.apply_settings(settings)
    tm.set_synchronous_mode(True)
    library = world.get_blueprint_library()
    points = world.get_map().get_spawn_points()[:6]
    cars = [world.spawn_actor(library.find("vehicle.tesla.model3"), p) for p in points]
    for car in cars:
        car.set_autopilot(True, tm.get_port())
    start = [c.get_location() for c in cars]
    for _ in range(200):
        world.tick()
    town = world.get_map()
    moved = [c.get_location().distance(s) for c, s in zip(cars, start)]
    assert sum(m > 10.0 for m in moved) >= 4, moved
    for car in cars:
        on = town.get_waypoint(car.get_location(), project_to_road=False)
        assert on is not None, car.get_location()
