"""CARLA's traffic manager against the gateway, with the real `carla`
wheel: the traffic manager runs inside the script's process (CARLA 0.9.16's
client) and drives vehicles through ordinary RPCs; the gateway keeps the
registry of running traffic managers and the streamed vehicle state it
reads (speed limit, traffic-light state, elapsed time).

Scripts run as their own processes (`carla_tm_run.py`): a traffic manager
binds its port and keeps threads until its process ends. CARLA 0.9.16's
traffic manager can deadlock in synchronous mode on its own
(`carla_tm_deadlock.py`): such a run is made again on a fresh pair."""

import json
import math
import os
import socket
import subprocess
import sys
import time

from test_carla_actors_sensors import Raw

from carla_tm_deadlock import on_fresh_pairs, run_script

HERE = os.path.dirname(os.path.abspath(__file__))


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


def test_autopilot_vehicles_drive_along_the_town_roads(request):
    [out] = on_fresh_pairs(request, [tm_run("--vehicles", "10", "--ticks", "200")])
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


def test_the_seeds_determinism_example_repeats_exactly(request):
    """Two fresh server + gateway pairs, the same seed: every vehicle's
    transform identical at every tick; a third with another seed differs."""
    runs = on_fresh_pairs(request, [
        tm_run("--seed", str(seed), "--vehicles", "30", "--ticks", "500") for seed in (7, 7, 8)
    ])
    a, b, c = runs
    assert len(a["ticks"]) == 500 and len(a["ids"]) == 30
    assert a["ticks"] == b["ticks"], "the same seed gives the same run, tick by tick"
    assert a["ticks"] != c["ticks"], "another seed gives another run"
    moved = [math.dist(p[1:3], q[1:3]) for p, q in zip(a["ticks"][0], a["ticks"][-1])]
    assert sum(m > 5.0 for m in moved) >= 20, moved


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
