"""Running scripts that use CARLA 0.9.16's traffic manager in synchronous
mode, which can deadlock inside CARLA's own client (not simbus):
`TrafficManagerLocal::SynchronousTick()` sets its worker's `step_begin`
flag and notifies it without holding the mutex the worker checks that flag
under, so a notification that lands between the worker's check and its
wait is lost, and `world.tick()` and the worker then wait for each other
forever (carla-simulator/carla#9172, fixed after 0.9.16 by #9344). Seen
here about once in 70 runs of 500 ticks on a busy 2-core machine.

A script that stops is looked at with gdb: CARLA's deadlock (one thread
waiting in `SynchronousTick`, another in the worker's `Run`) is run again
on a fresh server + gateway pair; any other stop fails the test with every
thread's backtrace."""

import subprocess

from conftest import kill_all, start, world_name

# A normal run takes seconds (500 ticks of 30 vehicles: ~3 s in a debug
# build on a busy 2-core machine); one still running past this has stopped.
RUN_LIMIT = 120
# Attempts at a run that may meet CARLA's deadlock before the test fails.
ATTEMPTS = 3


class CarlaTrafficManagerDeadlock(Exception):
    """The script stopped in CARLA 0.9.16's traffic-manager deadlock."""


def threads_of(pid):
    """Every thread's backtrace in process `pid` (gdb), one text each."""
    done = subprocess.run(
        ["gdb", "-p", str(pid), "-batch", "-ex", "thread apply all bt 16"],
        capture_output=True, text=True, timeout=120,
    )
    return done.stdout.split("\nThread ")[1:]


def carlas_deadlock(threads):
    """Whether `threads` are stopped in CARLA's traffic-manager deadlock:
    one waits in `SynchronousTick` for the step's end, another in the
    worker's `Run` for the step's beginning."""
    waiting = [t for t in threads if "condition_variable::wait" in t]
    return (any("TrafficManagerLocal::SynchronousTick" in t for t in waiting)
            and any("TrafficManagerLocal::Run" in t for t in waiting))


def run_script(argv, limit=RUN_LIMIT):
    """Runs `argv`; returns (exit status, stdout, stderr). One still
    running after `limit` seconds is looked at with gdb and killed: CARLA's
    deadlock raises CarlaTrafficManagerDeadlock, anything else fails with
    every thread's backtrace."""
    script = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        out, err = script.communicate(timeout=limit)
    except subprocess.TimeoutExpired:
        threads = threads_of(script.pid)
        if carlas_deadlock(threads):
            raise CarlaTrafficManagerDeadlock() from None
        raise AssertionError(
            f"the script stopped after {limit} s:\nThread " + "\nThread ".join(threads)
        ) from None
    finally:
        script.kill()
        script.communicate()
    return script.returncode, out, err


def on_fresh_pairs(request, attempts, server_args=(), gateway_args=()):
    """Calls each of `attempts` with a gateway of its own, a fresh server +
    gateway pair (on `server_args`, the gateway with `gateway_args`), and
    returns their results; an attempt
    that meets CARLA's deadlock is made again on another fresh pair, up to
    ATTEMPTS times in all."""
    results = []
    for run, attempt in enumerate(attempts):
        for tries in range(1, ATTEMPTS + 1):
            procs = []
            try:
                gateway = start(world_name(request, f"-{run}-{tries}"), list(server_args), procs,
                                gateway_args=list(gateway_args))
                results.append(attempt(gateway))
                break
            except CarlaTrafficManagerDeadlock:
                print(f"run {run}: CARLA 0.9.16's traffic manager deadlocked "
                      "(carla-simulator/carla#9172); again on a fresh pair")
                if tries == ATTEMPTS:
                    raise
            finally:
                kill_all(procs)
    return results
