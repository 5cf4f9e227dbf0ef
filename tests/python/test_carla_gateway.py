"""CARLA 0.9.16's own Python client drives a simbus world through the
gateway: version, world, settings, ticks with simbus's exact timestamps,
the single-ticker rule for CARLA connections, and bad input on the RPC port."""

import os
import signal
import socket
import subprocess
import sys
import textwrap
import threading

import carla
import pytest

from conftest import BIN


def test_version_world_and_settings(gateway):
    client = gateway.client()
    assert client.get_server_version() == "0.9.16"
    assert client.get_client_version() == "0.9.16"
    world = client.get_world()
    settings = world.get_settings()
    assert settings.synchronous_mode is False
    assert settings.fixed_delta_seconds is None
    assert "default" in client.get_available_maps()
    # The fields simbus does not have are accepted and read back as set.
    settings.no_rendering_mode = True
    settings.tile_stream_distance = 500.0
    settings.spectator_as_ego = True
    world.apply_settings(settings)
    back = world.get_settings()
    assert (back.no_rendering_mode, back.tile_stream_distance, back.spectator_as_ego) == (True, 500.0, True)
    assert back.synchronous_mode is False and back.fixed_delta_seconds is None


def test_seed_variable_fixed_and_substepping_settings(gateway):
    world = gateway.client().get_world()
    # The seeds' snippets: variable step, fixed 0.05, substepping 0.01 x 10.
    settings = world.get_settings()
    settings.fixed_delta_seconds = None
    world.apply_settings(settings)
    assert world.get_settings().fixed_delta_seconds is None
    settings.fixed_delta_seconds = 0.05
    world.apply_settings(settings)
    assert world.get_settings().fixed_delta_seconds == 0.05
    settings.substepping = True
    settings.max_substep_delta_time = 0.01
    settings.max_substeps = 10
    world.apply_settings(settings)
    got = world.get_settings()
    assert (got.substepping, got.max_substep_delta_time, got.max_substeps) == (True, 0.01, 10)
    # Invalid settings name the rule, and change nothing. (A step longer
    # than 0.01 x 10 is not one: CARLA accepts it, and so does the gateway,
    # with the substep rule 'clamp'; see test_carla_substepping.py.)
    settings.max_substeps = 17
    with pytest.raises(RuntimeError, match="max_substeps = 17"):
        world.apply_settings(settings)
    assert world.get_settings().fixed_delta_seconds == 0.05


def test_timestamps_equal_simbus_exactly_for_1000_ticks(gateway):
    world = gateway.client().get_world()
    settings = world.get_settings()
    settings.synchronous_mode = True
    settings.fixed_delta_seconds = 0.05
    world.apply_settings(settings)
    first = world.get_snapshot().timestamp
    base_ns = round(first.elapsed_seconds * 1e9)
    for i in range(1, 1001):
        frame = world.tick()
        t = world.get_snapshot().timestamp
        assert t.frame == frame == first.frame + i
        # simbus keeps integer nanoseconds; CARLA reads its double.
        assert t.elapsed_seconds == (base_ns + i * 50_000_000) / 1e9
        assert abs(t.delta_seconds - 0.05) < 1e-7  # CARLA's stream carries it as f32
    settings.synchronous_mode = False
    world.apply_settings(settings)


def test_wait_for_tick_and_on_tick_see_every_frame(gateway):
    ticker = gateway.client().get_world()
    watcher = gateway.client().get_world()
    seen = []
    arrived = threading.Condition()

    def on_tick(snapshot):
        with arrived:
            seen.append(snapshot.frame)
            arrived.notify_all()

    callback = watcher.on_tick(on_tick)
    settings = ticker.get_settings()
    settings.synchronous_mode = True
    settings.fixed_delta_seconds = 0.05
    ticker.apply_settings(settings)
    frames = [ticker.tick() for _ in range(50)]
    # The watcher's stream is its own: wait until it has the last frame.
    with arrived:
        assert arrived.wait_for(lambda: frames[-1] in seen, timeout=10)
    last = watcher.get_snapshot()
    assert last.frame == frames[-1]
    assert last.find(next(iter(last)).id) is not None
    watcher.remove_on_tick(callback)
    assert [f for f in seen if f >= frames[0]][: len(frames)] == frames
    # Asynchronous: wait_for_tick returns each next frame.
    settings.synchronous_mode = False
    settings.fixed_delta_seconds = None
    ticker.apply_settings(settings)
    a = watcher.wait_for_tick()
    b = watcher.wait_for_tick()
    assert b.frame > a.frame and b.timestamp.elapsed_seconds > a.timestamp.elapsed_seconds


def test_a_second_ticker_is_refused_naming_the_owner(gateway):
    first = gateway.client().get_world()
    second = gateway.client().get_world()
    settings = first.get_settings()
    settings.synchronous_mode = True
    settings.fixed_delta_seconds = 0.05
    first.apply_settings(settings)
    first.tick()
    with pytest.raises(RuntimeError, match="already has a ticker: carla:127.0.0.1"):
        second.tick()
    with pytest.raises(RuntimeError, match="already has a ticker"):
        second.apply_settings(settings)
    # A native ticker is refused the same way.
    native = gateway.sim_client("tick", "--count", "1")
    assert native.returncode != 0 and "carla:127.0.0.1" in native.stderr, native.stderr
    settings.synchronous_mode = False
    first.apply_settings(settings)


def test_a_killed_ticking_script_lets_another_take_over_without_a_skipped_frame(gateway):
    script = textwrap.dedent(f"""
        import carla, sys
        world = carla.Client("127.0.0.1", {gateway.port}).get_world()
        s = world.get_settings(); s.synchronous_mode = True; s.fixed_delta_seconds = 0.05
        world.apply_settings(s)
        for _ in range(5):
            world.tick()
        print(world.get_snapshot().frame, flush=True)
        sys.stdin.read()
    """)
    proc = subprocess.Popen([sys.executable, "-c", script], stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)
    try:
        last = int(proc.stdout.readline())
    finally:
        proc.send_signal(signal.SIGKILL)
        proc.wait()
    world = gateway.client().get_world()
    # The dead script's ownership is released; this client ticks on from the next frame.
    assert world.tick() == last + 1
    assert world.tick() == last + 2


def test_garbage_on_the_rpc_port_is_dropped_and_others_are_served(gateway):
    client = gateway.client()
    bad = []
    # Not msgpack; a request cut short; a map instead of a request.
    for payload in [b"\xc1\xc1garbage", b"\x93\x00\x01", b"\x81\xa1a\xa1b"]:
        s = socket.create_connection(("127.0.0.1", gateway.port))
        s.sendall(payload)
        bad.append(s)
    silent = socket.create_connection(("127.0.0.1", gateway.port))  # connects and never reads
    # An oversized message (20 MiB string) is refused.
    huge = socket.create_connection(("127.0.0.1", gateway.port))
    huge.sendall(b"\x94\x00\x01\xa7version\x91\xdb" + (20 << 20).to_bytes(4, "big"))
    try:
        huge.sendall(b"x" * (17 << 20))
    except OSError:
        pass
    # An unknown method and wrong argument types are RuntimeErrors, not hangs.
    world = client.get_world()
    with pytest.raises(RuntimeError, match="not supported by simbus"):
        world.get_environment_objects()
    assert client.get_server_version() == "0.9.16"
    for s in bad + [silent, huge]:
        s.close()


def test_the_recorder_calls_map_onto_simbus_recorder(gateway, tmp_path):
    client = gateway.client()
    world = client.get_world()
    settings = world.get_settings()
    settings.synchronous_mode = True
    settings.fixed_delta_seconds = 0.05
    world.apply_settings(settings)
    path = str(tmp_path / "run.mcap")
    assert client.start_recorder(path, False) == path
    for _ in range(20):
        world.tick()
    client.stop_recorder()
    # stop_recorder is one of CARLA's fire-and-forget calls, but the gateway
    # answers a connection's calls in order: the next one sees the file closed.
    # CARLA's text: its footer counts the recorded frames.
    info = client.show_recorder_file_info(path, False)
    assert "\nFrames: 21\n" in info, info
    assert client.show_recorder_collisions(path, "a", "a").startswith("Version: 1\n")
    assert client.show_recorder_actors_blocked(path, 0.5, 0.1).startswith("Version: 1\n")
    with pytest.raises(RuntimeError, match="cannot read .*missing.mcap"):
        client.replay_file(str(tmp_path / "missing.mcap"), 0.0, 0.0, 0, False)
    answer = client.replay_file(path, 0.0, 0.0, 0, False)
    assert "21 frames" in answer, answer
    # Synchronous: one recorded frame per tick, the recorded frame ids.
    first = world.tick()
    second = world.tick()
    assert second == first + 1
    settings.synchronous_mode = False
    world.apply_settings(settings)


def test_get_actors_lists_the_worlds_actors_with_carla_type_ids(gateway):
    world = gateway.client().get_world()
    snapshot = world.wait_for_tick()
    actors = world.get_actors()
    ids = {a.id for a in actors}
    assert ids == {a.id for a in snapshot}
    kinds = {a.type_id for a in actors}
    assert "static.prop.box" in kinds and "static.prop.sphere" in kinds
    cars = world.get_actors().filter("vehicle.*")
    assert len(cars) == 2 and all(c.type_id == "vehicle.simbus.car" for c in cars)
    box = world.get_actors().filter("static.prop.box")[0]
    assert box.get_transform().location.z > 0.0


def test_a_dead_server_is_an_error_within_the_timeout_and_a_new_one_is_served(gateway):
    client = gateway.client(timeout=5.0)
    world = client.get_world()
    settings = world.get_settings()
    settings.synchronous_mode = True
    settings.fixed_delta_seconds = 0.05
    world.apply_settings(settings)
    world.tick()
    server = gateway.procs[0]
    os.killpg(server.pid, signal.SIGKILL)
    server.wait()
    box = world.get_blueprint_library().find("static.prop.box")
    # simbus's own error, so the gateway answered before the client's
    # 5 s timeout (which would raise CARLA's "time-out of 5000ms").
    for call in (world.get_settings, world.tick, lambda: world.spawn_actor(box, carla.Transform())):
        with pytest.raises(RuntimeError, match="^simbus: "):
            call()
    # A new server on the world: the gateway connects to it on the next call.
    gateway.procs.append(subprocess.Popen(
        [os.path.join(BIN, "sim-server"), "--world", gateway.world],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    ))
    up = gateway.sim_client("--timeout", "30", "status")
    assert up.returncode == 0, up.stderr
    world = client.get_world()
    settings = world.get_settings()
    assert settings.synchronous_mode is False
    settings.synchronous_mode = True
    settings.fixed_delta_seconds = 0.05
    world.apply_settings(settings)
    first = world.tick()
    assert world.tick() == first + 1
    assert world.get_snapshot().frame == first + 1
