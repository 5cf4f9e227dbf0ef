"""The Python examples of `sim-client/python/examples/` (the CARLA page's
snippets written against `simbus`) run against a real server and print
what their snippets promise."""

import itertools
import os
import re
import subprocess
import sys

import pytest

BIN = os.environ["SIMBUS_BIN_DIR"]
EXAMPLES = os.path.join(os.path.dirname(__file__), "..", "..", "sim-client", "python", "examples")
_counter = itertools.count()


@pytest.fixture
def world():
    name = f"py-example-{os.getpid()}-{next(_counter)}"
    server = subprocess.Popen(
        [os.path.join(BIN, "sim-server"), "--world", name],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    )
    try:
        yield name
    finally:
        server.kill()
        server.wait()


def run(example, world, *args):
    done = subprocess.run(
        [sys.executable, os.path.join(EXAMPLES, example), "--world", world, *args],
        capture_output=True, text=True, timeout=120,
    )
    assert done.returncode == 0, done.stderr
    return done.stdout.splitlines()


def test_variable_step(world):
    lines = run("variable_step.py", world, "--frames", "5")
    assert lines[0] == "fixed_delta_seconds = None"
    steps = [float(re.search(r"dt = ([0-9.]+) s", line).group(1)) for line in lines[1:]]
    # The first is the frame already published when it connected (the
    # episode's first has no step); every later one stepped.
    assert len(steps) == 5 and all(dt > 0 for dt in steps[1:])


def test_fixed_step(world):
    lines = run("fixed_step.py", world, "--frames", "5", "--delta-seconds", "0.05")
    assert lines[0] == "fixed_delta_seconds = 0.05"
    rows = [re.search(r"frame (\d+) t = (\d+) ns dt = 0.05 s missed (\d+)", line).groups()
            for line in lines[1:]]
    assert len(rows) == 5
    for (f0, t0, _), (f1, t1, missed) in zip(rows, rows[1:]):
        # Every frame, seen or skipped, advanced exactly 0.05 s.
        assert int(f1) - int(f0) == 1 + int(missed)
        assert int(t1) - int(t0) == (int(f1) - int(f0)) * 50_000_000


def test_substepping(world):
    lines = run("substepping.py", world)
    assert lines[0] == "substepping = True, max_substep_delta_time = 0.01, max_substeps = 10"
    assert lines[1] == "fixed_delta_seconds = 0.1: accepted"
    assert lines[2].startswith("fixed_delta_seconds = 0.2: refused (")
    assert lines[3] == "still 0.1"


def test_synchronous_mode_with_a_camera_queue(world):
    lines = run("synchronous_mode.py", world, "--frames", "5")
    assert len(lines) == 5
    for line in lines:
        frame, image = re.match(r"frame (\d+): image of frame (\d+), 320x240", line).groups()
        assert frame == image


def test_wait_for_tick(world):
    lines = run("wait_for_tick.py", world, "--frames", "3")
    assert re.match(r"frame \d+ at [0-9.]+ s, \d+ actors", lines[0])
    frames = [int(re.match(r"frame (\d+): \d+ actors moving", line).group(1)) for line in lines[1:]]
    assert len(frames) == 3 and frames == sorted(set(frames))
