"""The native traffic manager's soak: `generate_traffic.py`'s calls (the
mirror of test_carla_scripts_traffic.py: 30 vehicles, 10 walkers,
synchronous) for N ticks, run after run, each on a fresh server + gateway
pair. A run that does not finish within its limit is a hang: its threads
are printed (gdb) and counted. Prints one JSON object: runs, hangs,
failures, the slowest run.

    SIMBUS_BIN_DIR=target/debug python carla_tm_soak.py --runs 100 --ticks 2000

The fault suite (bench/run-fault-suite) runs it 100 times; the test suite
runs it twice, short (test_carla_scripts_traffic.py)."""

import argparse
import json
import os
import socket
import subprocess
import sys
import time

HERE = os.path.dirname(os.path.abspath(__file__))
sys.path.insert(0, HERE)

from carla_tm_deadlock import threads_of  # noqa: E402
from conftest import kill_all, start  # noqa: E402
from test_carla_scripts_traffic import GENERATE_TRAFFIC  # noqa: E402


def free_port():
    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def soak(runs, ticks, walkers, limit, prefix):
    """Runs the mirror `runs` times: {"runs", "hangs", "failures",
    "slowest_s", "ticks"}."""
    hangs, failures, slowest = [], [], 0.0
    for run in range(runs):
        procs = []
        try:
            gateway = start(f"{prefix}-{os.getpid()}-{run}", ["--scene", "town"], procs)
            began = time.monotonic()
            script = subprocess.Popen(
                [sys.executable, "-c", GENERATE_TRAFFIC, str(gateway.port), str(free_port()),
                 "30", "sync", str(walkers), str(ticks)],
                stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
            try:
                _, err = script.communicate(timeout=limit)
                if script.returncode != 0:
                    failures.append({"run": run, "error": err[-2000:]})
                    print(f"run {run + 1} failed:\n{err[-2000:]}", file=sys.stderr, flush=True)
            except subprocess.TimeoutExpired:
                hangs.append({"run": run, "threads": threads_of(script.pid)[:4]})
            finally:
                script.kill()
                script.communicate()
            slowest = max(slowest, time.monotonic() - began)
        finally:
            kill_all(procs)
        print(f"run {run + 1}/{runs}: {len(hangs)} hangs, {len(failures)} failures",
              file=sys.stderr, flush=True)
    return {"runs": runs, "ticks": ticks, "walkers": walkers, "hangs": len(hangs),
            "failures": len(failures), "slowest_s": round(slowest, 1),
            "hang_threads": hangs[:2], "failure_errors": failures[:2]}


def main():
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--runs", type=int, default=100)
    parser.add_argument("--ticks", type=int, default=2000)
    parser.add_argument("--walkers", type=int, default=10)
    parser.add_argument("--limit", type=float, default=300.0,
                        help="seconds a run may take before it counts as a hang")
    args = parser.parse_args()
    result = soak(args.runs, args.ticks, args.walkers, args.limit, "soak")
    print(json.dumps(result))
    sys.exit(0 if result["hangs"] == 0 and result["failures"] == 0 else 1)


if __name__ == "__main__":
    main()
