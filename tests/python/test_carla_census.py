"""The census runner (`carla_census.py`) on a PythonAPI folder of three
scripts of the test's own, mirroring the three outcomes of CARLA's: one
that connects through the gateway and exits, one that loops until Ctrl-C,
one that fails; each on a fresh server + gateway, each process reaped, the
table and the JSON written."""

import json
import socket
import subprocess
import sys
import textwrap

import carla_census
from conftest import BIN

CONNECTS = """
import argparse, carla
p = argparse.ArgumentParser(); p.add_argument('--port', type=int, default=2000)
a = p.parse_args()
client = carla.Client('127.0.0.1', a.port); client.set_timeout(10.0)
print(client.get_world().get_map().name)
"""

LOOPS = """
import argparse, carla
p = argparse.ArgumentParser(); p.add_argument('--port', type=int, default=2000)
a = p.parse_args()
world = carla.Client('127.0.0.1', a.port).get_world()
try:
    while True:
        world.wait_for_tick(10.0)
except KeyboardInterrupt:
    print('Cancelled by user. Bye!')
"""

FAILS = """
raise RuntimeError('simbus: a call that is refused')
"""


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def test_the_census_runs_every_script_and_writes_its_table(tmp_path):
    api = tmp_path / "PythonAPI"
    for folder, name, source in [("examples", "connects.py", CONNECTS),
                                 ("examples", "loops.py", LOOPS),
                                 ("util", "fails.py", FAILS)]:
        (api / folder).mkdir(parents=True, exist_ok=True)
        (api / folder / name).write_text(textwrap.dedent(source))
    out, rows = tmp_path / "census.md", tmp_path / "census.json"
    done = subprocess.run(
        [sys.executable, carla_census.__file__, "--python-api", str(api), "--bin-dir", BIN,
         "--port", str(free_port()), "--seconds", "5", "--out", str(out), "--json", str(rows)],
        capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    results = {r["script"]: (r["result"], r["why"]) for r in json.loads(rows.read_text())}
    assert results == {
        "examples/connects.py": ("runs", "exited 0"),
        "examples/loops.py": ("runs", "looped until Ctrl-C after 5.0 s"),
        "util/fails.py": ("fails", "RuntimeError: simbus: a call that is refused"),
    }
    text = out.read_text()
    assert text.startswith("| script | result | why |\n|---|---|---|\n")
    assert "| util/fails.py | fails | RuntimeError: simbus: a call that is refused |" in text
