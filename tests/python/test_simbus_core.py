"""The `simbus` Python package against real servers: connecting, settings,
the ticker, frames as numpy arrays over shared memory, and what a Python
program relies on (exceptions, the GIL released while waiting, Ctrl-C,
thread binding, determinism)."""

import itertools
import json
import os
import signal
import subprocess
import sys
import threading

import pytest

import simbus

from simbus_support import server, unique_world  # noqa: F401 (a fixture)


def python_child(code, world):
    """A Python process running `code` (with `world` and simbus imported),
    its stdout a pipe. Ctrl-C raises KeyboardInterrupt in it whatever its
    parent ignored (a shell's background job inherits SIGINT ignored)."""
    prelude = "import signal, simbus, sys\nsignal.signal(signal.SIGINT, signal.default_int_handler)\n"
    return subprocess.Popen(
        [sys.executable, "-c", f"{prelude}world = {world!r}\n{code}"],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )


def interrupt_once_asleep(child, said, asleep_in):
    """Sends SIGINT to `child` once it said `said` and sleeps in a kernel
    function named like `asleep_in` (its /proc wchan), and checks that it
    printed "interrupted" (its KeyboardInterrupt handler); kills and reaps
    it whatever happens."""
    try:
        assert child.stdout.readline().strip() == said
        while asleep_in not in open(f"/proc/{child.pid}/wchan").read():
            assert child.poll() is None, child.stderr.read()
        os.kill(child.pid, signal.SIGINT)
        out, err = child.communicate(timeout=30)
        assert out.strip() == "interrupted", err
    finally:
        child.kill()
        child.wait()


def test_settings_round_trip_and_the_substep_rule(server):
    client = server().client()
    before = client.settings()
    assert before.synchronous_mode is False
    frame = client.apply_settings(fixed_delta_seconds=0.02, max_substeps=4)
    assert frame >= 1
    after = client.settings()
    assert (after.fixed_delta_seconds, after.max_substeps) == (0.02, 4)
    assert after.max_substep_delta_time == before.max_substep_delta_time
    # 0.5 s in substeps of at most 0.01 s x 4: refused, nothing changed.
    with pytest.raises(simbus.SettingsError, match="substep"):
        client.apply_settings(fixed_delta_seconds=0.5)
    with pytest.raises(ValueError):  # SettingsError is a ValueError too
        client.apply_settings(max_substeps=0)
    with pytest.raises(simbus.SettingsError):
        client.apply_settings(fixed_delta_seconds=float("nan"))
    assert client.settings() == after
    with pytest.raises(TypeError):
        client.apply_settings(max_substeps="four")
    with pytest.raises(simbus.SettingsError, match="tick owner"):
        client.apply_settings(synchronous_mode=True)
    assert client.settings() == after


def test_a_thousand_ticks_keep_exact_integer_nanosecond_time(server):
    client = server().client()
    with client.ticker(delta_seconds=0.05) as ticker:
        assert client.settings().synchronous_mode
        first = ticker.tick()
        with client.wait_for_frame() as frame:
            assert frame.frame == first
            start_ns = frame.elapsed_ns
        for n in range(1, 1000):
            assert ticker.tick() == first + n
            with client.wait_for_frame() as frame:
                assert (frame.frame, frame.missed) == (first + n, 0)
                assert frame.elapsed_ns == start_ns + n * 50_000_000
                assert frame.delta_seconds == 0.05
    # Leaving the block gave the world back, asynchronous, as it was.
    settings = client.settings()
    assert settings.synchronous_mode is False
    assert settings.fixed_delta_seconds is None
    assert client.status().ticker is None


@pytest.mark.parametrize("mode", ["block", "hybrid", "spin"])
def test_every_wait_mode_ticks_and_reads_the_same_frames(server, mode):
    client = server().client(wait_mode=mode)
    assert client.wait_mode == mode
    with client.ticker(delta_seconds=0.05) as ticker:
        for _ in range(50):
            frame = ticker.tick()
            with client.wait_for_frame() as seen:
                assert (seen.frame, seen.missed) == (frame, 0)


@pytest.mark.parametrize("mode", ["block", "hybrid", "spin"])
def test_a_tick_answered_by_its_frame_returns_that_frame(server, mode):
    client = server().client(wait_mode=mode)
    with client.ticker(delta_seconds=0.05) as ticker:
        first = ticker.tick()  # never read: skipped by the next call
        for n in range(1, 51):
            with ticker.tick_and_read(client) as frame:
                assert (frame.frame, frame.missed) == (first + n, 0)
            assert ticker.last_frame == first + n


def test_a_ticker_puts_back_settings_it_changed_itself(server):
    client = server().client()
    before = client.settings()
    with client.ticker() as ticker:
        assert client.settings() == before
        ticker.apply_settings(synchronous_mode=True, fixed_delta_seconds=0.05)
        assert ticker.settings.synchronous_mode
        ticker.tick()
    assert client.settings() == before
    assert client.status().ticker is None


def test_a_world_started_synchronous_stays_synchronous_after_a_ticker(server):
    """Issue 44, item 3: the `with` block gives back what was there before
    the claim; a world started `--sync` is not left running free."""
    client = server("--sync", "--delta-seconds", "0.02").client()
    before = client.settings()
    assert before.synchronous_mode
    with client.ticker(delta_seconds=0.05) as ticker:
        frame = ticker.tick()
    assert client.settings() == before
    status = client.status()
    assert status.ticker is None and status.frame == frame


def test_ctrl_c_interrupts_a_connect_that_waits_for_a_server():
    child = python_child(
        "print('connecting', flush=True)\n"
        "try:\n"
        "    simbus.connect(world, timeout=60)\n"
        "except KeyboardInterrupt:\n"
        "    print('interrupted', flush=True)\n",
        unique_world("nobody"),
    )
    # Signalled once asleep between two looks for the server.
    interrupt_once_asleep(child, "connecting", "sleep")


def test_a_second_ticker_is_refused_naming_the_owner(server):
    s = server()
    owner = s.client()
    other = s.client()
    with owner.ticker(delta_seconds=0.05) as ticker:
        ticker.tick()
        with pytest.raises(simbus.NotTickerError, match=str(os.getpid())):
            other.ticker()
        # Refused changes nothing: the owner still ticks.
        assert ticker.tick() == ticker.last_frame
        assert other.status().ticker.pid == os.getpid()


def test_a_killed_python_ticker_is_replaced_from_the_next_frame(server):
    s = server("--sync", "--delta-seconds", "0.05")
    child = python_child(
        "c = simbus.connect(world, timeout=10)\n"
        "t = c.ticker()\n"
        "for _ in range(20):\n"
        "    print(t.tick(), flush=True)\n"
        "print('ticked', flush=True)\n"
        "sys.stdin.read() if False else __import__('time').sleep(3600)\n",
        s.world,
    )
    try:
        lines = [child.stdout.readline() for _ in range(21)]
        assert lines[-1].strip() == "ticked", lines
        last = int(lines[-2])
    finally:
        child.kill()
        child.wait()
    client = s.client()
    # The server notices the death (a pidfd); a claim succeeds once it has.
    for attempt in itertools.count():
        try:
            ticker = client.ticker()
            break
        except simbus.NotTickerError:
            assert attempt < 100_000, "the dead ticker's claim was never dropped"
    with ticker:
        assert client.status().frame == last
        assert ticker.tick() == last + 1


def test_frames_actors_match_sim_client_watch_json(server):
    s = server("--sync", "--delta-seconds", "0.05", "--seed", "7")
    client = s.client()
    watch = s.sim_client("watch", "--json", "--lockstep", "--frames", "20",
                         stdout=subprocess.PIPE, text=True)
    try:
        seen = {}
        with client.ticker() as ticker:
            # The watcher joins the lockstep, then every tick waits for it.
            while client.status().participants == 0:
                assert watch.poll() is None, "the watcher exited"
            for _ in range(20):
                ticker.tick()
                with client.wait_for_frame() as frame:
                    actors = frame.actors
                    assert actors.flags.writeable is False
                    assert list(actors["id"]) == sorted(actors["id"])
                    norms = (actors["rotation"] ** 2).sum(axis=1)
                    assert abs(norms - 1).max() < 1e-4
                    seen[frame.frame] = (frame.elapsed_ns, len(actors), frame.digest,
                                         actors.copy())
                    del actors
        out, _ = watch.communicate(timeout=30)
    finally:
        watch.kill()
        watch.wait()
    rows = [json.loads(line) for line in out.splitlines()]
    assert len(rows) == 20
    for row in rows:
        elapsed_ns, count, digest, _ = seen[row["frame"]]
        assert row["elapsed_ns"] == elapsed_ns
        assert row["actors"] == count
        assert row["digest"] == f"{digest:016x}"


def test_an_array_never_outlives_its_frame(server):
    s = server()
    client = s.client()
    frame = client.wait_for_frame()
    actors = frame.actors
    ids = actors["id"].copy()
    # The frame cannot go back while an array views it...
    with pytest.raises(BufferError, match="still view"):
        frame.release()
    assert (actors["id"] == ids).all()
    assert actors.base is not None
    kept = frame.copy()
    del actors
    frame.release()
    # ...and once released, it raises instead of reading freed memory.
    assert not frame.held
    with pytest.raises(simbus.ReleasedError):
        frame.actors
    assert (kept.actors["id"] == ids).all()
    assert kept.held


def assert_poses_are_the_actors(frame):
    """`frame.poses` holds every actor's id, kind, flags, position and
    rotation, in the actors' order, read-only, in half their bytes."""
    actors, poses = frame.actors, frame.poses
    assert len(poses) == len(actors) > 0
    assert poses.dtype.itemsize * 2 == actors.dtype.itemsize
    for field in ("id", "kind", "flags", "position", "rotation"):
        assert (poses[field] == actors[field]).all(), field
    assert poses.flags.writeable is False


def test_poses_are_every_actors_pose_packed_in_the_same_frame(server):
    client = server().client()
    with client.ticker(delta_seconds=0.05) as ticker:
        ticker.tick()
        counts = set()
        for at in ((20.0, 5.0, 20.0), (-20.0, 5.0, 20.0)):
            client.spawn("box", at=at)
            frame_id = ticker.tick()
            frame = client.wait_for_frame()
            while frame.frame < frame_id:
                frame.release()
                frame = client.wait_for_frame()
            with frame:
                assert frame.frame == frame_id
                assert_poses_are_the_actors(frame)
                counts.add(len(frame.poses) % 2)
                # The box spawned in the air has fallen: this frame's poses.
                y = frame.poses["position"][frame.poses["id"] == frame.actors["id"].max()][0][1]
                assert 0 < y < 5
        assert counts == {0, 1}, "an odd and an even number of actors"
        ticker.tick()
        frame = client.wait_for_frame()
        poses = frame.poses
        with pytest.raises(BufferError, match="still view"):
            frame.release()
        kept = frame.copy()
        del poses
        frame.release()
        with pytest.raises(simbus.ReleasedError):
            frame.poses
        assert (kept.poses["id"] == kept.actors["id"]).all()
        assert (kept.poses["position"] == kept.actors["position"]).all()


def test_an_array_over_shared_memory_is_read_only(server):
    client = server().client()
    with client.wait_for_frame() as frame:
        actors = frame.actors
        with pytest.raises(ValueError, match="read-only"):
            actors["position"][0] = (1.0, 2.0, 3.0)
        with pytest.raises(ValueError):
            actors.flags.writeable = True
        del actors


def test_the_gil_is_released_while_a_wait_waits(server):
    # Only another Python thread's tick can end the main thread's wait, and
    # with a switch interval of 60 s that thread runs only when the main
    # thread lets go of the GIL: a wait that held it would time out.
    s = server("--sync", "--delta-seconds", "0.05")
    client = s.client()
    with client.wait_for_frame() as current:
        first = current.frame
    ticked = []

    def tick():
        other = s.client()
        with other.ticker() as ticker:
            ticked.append(ticker.tick())

    interval = sys.getswitchinterval()
    sys.setswitchinterval(60.0)
    try:
        thread = threading.Thread(target=tick)
        thread.start()
        with client.wait_for_frame(timeout=30) as frame:
            assert frame.frame == first + 1
    finally:
        sys.setswitchinterval(interval)
        thread.join()
    assert ticked == [first + 1]


def test_ctrl_c_interrupts_a_wait(server):
    s = server("--sync", "--delta-seconds", "0.05")
    child = python_child(
        "c = simbus.connect(world, timeout=10)\n"
        "c.wait_for_frame().release()  # the current frame: at once\n"
        "print('waiting', flush=True)\n"
        "try:\n"
        "    c.wait_for_frame(timeout=60)  # none comes: nobody ticks\n"
        "except KeyboardInterrupt:\n"
        "    print('interrupted', flush=True)\n",
        s.world,
    )
    # Signalled once asleep in the wait (a futex), not before it.
    interrupt_once_asleep(child, "waiting", "futex")


def test_a_client_is_bound_to_its_thread(server):
    client = server().client()
    errors = []

    def use_and_keep_the_error():
        # PyO3 raises its PanicException (a BaseException) for an object
        # used off its thread; nothing of the client is touched.
        try:
            client.status()
        except BaseException as e:  # noqa: B036
            errors.append(f"{type(e).__name__}: {e}")

    thread = threading.Thread(target=use_and_keep_the_error)
    thread.start()
    thread.join()
    assert len(errors) == 1 and "unsendable" in errors[0], errors
    assert client.status().frame >= 0


def test_bad_input_raises_and_changes_nothing(server):
    s = server()
    with pytest.raises(ValueError, match="timeout"):
        simbus.connect(s.world, timeout=float("nan"))
    with pytest.raises(ValueError, match="wait_mode"):
        simbus.connect(s.world, wait_mode="fast")
    with pytest.raises(ValueError):
        simbus.connect("no spaces allowed")
    with pytest.raises(simbus.TimeoutError):
        simbus.connect(unique_world("nobody"), timeout=0.2)
    client = s.client()
    before = client.settings()
    with pytest.raises(ValueError):
        client.load_world("no-such-scene")
    with pytest.raises(ValueError):
        client.wait_for_frame(timeout=-1)
    assert client.settings() == before
    assert client.status().scene == "default"


def test_the_package_digest_of_300_frames_equals_the_rust_clients(server):
    args = ("--sync", "--delta-seconds", "0.05", "--seed", "3")
    s = server(*args)
    client = s.client()
    python_digests = []
    with client.ticker() as ticker:
        for _ in range(300):
            ticker.tick()
            with client.wait_for_frame() as frame:
                python_digests.append(f"frame {frame.frame} digest {frame.digest:016x}")
    r = server(*args)
    watch = r.sim_client("watch", "--digest", "--lockstep", "--frames", "300",
                         stdout=subprocess.PIPE, text=True)
    try:
        probe = r.client()
        while probe.status().participants == 0:
            assert watch.poll() is None, "the watcher exited"
        tick = r.sim_client("tick", "--count", "300", stdout=subprocess.DEVNULL)
        try:
            assert tick.wait(timeout=120) == 0
        finally:
            tick.kill()
            tick.wait()
        out, _ = watch.communicate(timeout=60)
    finally:
        watch.kill()
        watch.wait()
    rust_digests = [line.strip() for line in out.splitlines() if line.startswith("frame")]
    assert len(rust_digests) == 300
    assert [d.split()[3] for d in python_digests] == [d.split()[3] for d in rust_digests]


def test_the_type_stubs_cover_every_class_and_method():
    import ast
    import inspect

    from simbus import _simbus

    path = os.path.join(os.path.dirname(_simbus.__file__), "_simbus.pyi")
    tree = ast.parse(open(path).read())
    stubbed = {node.name: {item.name for item in node.body if isinstance(item, ast.FunctionDef)}
               for node in tree.body if isinstance(node, ast.ClassDef)}
    functions = {node.name for node in tree.body if isinstance(node, ast.FunctionDef)}
    for name, value in vars(_simbus).items():
        if name.startswith("_"):
            continue
        if inspect.isclass(value):
            assert name in stubbed, f"class {name} has no stub"
            methods = {m for m in vars(value) if not m.startswith("_")}
            assert methods <= stubbed[name], f"{name}: no stub for {methods - stubbed[name]}"
        elif callable(value):
            assert name in functions, f"function {name} has no stub"
    assert set(simbus.__all__) <= set(dir(simbus))
