"""`sim-client bridge zenoh` read and attacked by a Zenoh peer simbus did not
write: the `eclipse-zenoh` package decodes frames by the book's header
layout, ROS 2's `/clock` is decoded by `rosbags` (its CDR decoder and the
ROS 2 message definitions), and garbage, wrong versions and a flood of
ticks from a foreign peer get clear errors and change nothing."""

import json
import os
import re
import struct
import subprocess
import sys
import threading
import time

import simbus
import zenoh
from rosbags.typesys import Stores, get_typestore

from conftest import BIN, kill_all, wait_line, world_name

DELTA_NS = 50_000_000
FRAME_HEADER = 112
ACTOR = 96
PROTOCOL_VERSION = simbus.PROTOCOL_VERSION


def free_port():
    import socket

    with socket.socket() as s:
        s.bind(("127.0.0.1", 0))
        return s.getsockname()[1]


def session(endpoint):
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    return zenoh.open(conf)


def sim_client(world, *args, env=None):
    return subprocess.run(
        [os.path.join(BIN, "sim-client"), "--world", world, "--timeout", "10", *args],
        capture_output=True, text=True, timeout=120, env=env,
    )


def start_export(world, procs, *extra):
    """A sync server on `world` and an exporting bridge; the endpoint."""
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    procs.append(subprocess.Popen(
        [os.path.join(BIN, "sim-server"), "--world", world, "--sync", "--delta-seconds", "0.05"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
    ))
    exporter = subprocess.Popen(
        [os.path.join(BIN, "sim-client"), "--world", world, "--timeout", "10",
         "bridge", "zenoh", "--listen", endpoint, *extra],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True, start_new_session=True,
    )
    procs.append(exporter)
    wait_line(exporter, "exporting world")
    return endpoint, exporter


def start_mirror(world, endpoint, tmp_path, procs):
    """A mirror of `world` from `endpoint` on this machine, in an iceoryx2
    root of its own under `tmp_path` (another host's shared memory), once it
    mirrors; the mirror and the environment that reaches its root."""
    config = tmp_path / "iox2.toml"
    config.write_text(f'[global]\nroot-path = "{tmp_path}/iox2/"\nprefix = "iox2_py{os.getpid()}_"\n')
    env = dict(os.environ, SIMBUS_IOX2_CONFIG=str(config))
    mirror = subprocess.Popen(
        [os.path.join(BIN, "sim-client"), "--world", world, "--timeout", "10",
         "bridge", "zenoh", "--connect", endpoint],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        start_new_session=True, env=env,
    )
    procs.append(mirror)
    wait_line(mirror, "mirroring world")
    return mirror, env


def replies(s, selector, payload=None, timeout=10.0):
    """Every reply to one query: ("ok", bytes) or ("err", text)."""
    out = []
    for reply in s.get(selector, payload=payload, timeout=timeout):
        if reply.ok is not None:
            out.append(("ok", bytes(reply.ok.payload.to_bytes())))
        else:
            out.append(("err", reply.err.payload.to_string()))
    return out


def test_a_foreign_zenoh_peer_decodes_frames_and_ros2_clock(request):
    world = world_name(request)
    procs = []
    s = None
    try:
        endpoint, _ = start_export(world, procs, "--ros2-clock")
        s = session(endpoint)
        frames, clocks = [], []
        got = threading.Condition()

        def keep(into):
            def handler(sample):
                with got:
                    into.append(bytes(sample.payload.to_bytes()))
                    got.notify_all()
            return handler

        subs = [s.declare_subscriber(f"simbus/{world}/frames", keep(frames)),
                s.declare_subscriber("clock", keep(clocks))]
        # A reply from the exporter means it has seen our subscriptions
        # (declarations and queries travel in order on the one link).
        assert replies(s, f"simbus/{world}/frames/latest")[0][0] == "ok"

        ticked = sim_client(world, "tick", "--count", "20", "--leave-sync", "--json")
        assert ticked.returncode == 0, ticked.stderr
        ticks = [json.loads(line) for line in ticked.stdout.splitlines()]
        assert [t["frame"] for t in ticks] == list(range(1, 21))
        # The exporter may still send the frame current when it started
        # (frame 0, time 0) after we subscribed: the ticks' frames follow it.
        typestore = get_typestore(Stores.ROS2_HUMBLE)

        def ticked_frames():
            return [f for f in frames if struct.unpack_from("<Q", f, 16)[0] > 0]

        def ticked_clocks():
            def ns(cdr):
                clock = typestore.deserialize_cdr(cdr, "rosgraph_msgs/msg/Clock").clock
                return clock.sec * 1_000_000_000 + clock.nanosec
            return [c for c in clocks if ns(c) > 0]

        with got:
            assert got.wait_for(lambda: len(ticked_frames()) >= 20 and len(ticked_clocks()) >= 20, timeout=30), (len(frames), len(clocks))
        frames, clocks = ticked_frames(), ticked_clocks()

        for i, (payload, cdr) in enumerate(zip(frames[:20], clocks[:20]), start=1):
            # The book's layout of the frame header (docs/src/wire.md).
            version, actors, _episode = struct.unpack_from("<IIQ", payload, 0)
            frame, elapsed_ns, delta_ns, platform = struct.unpack_from("<QQQd", payload, 16)
            substeps, _flags, _first_actor, server_pid = struct.unpack_from("<IIQI", payload, 72)
            assert version == PROTOCOL_VERSION
            assert len(payload) == FRAME_HEADER + ACTOR * actors and actors > 0
            assert (frame, elapsed_ns, delta_ns) == (i, i * DELTA_NS, DELTA_NS)
            assert substeps == 5 and server_pid > 0 and platform > 1e9
            actor_id, kind = struct.unpack_from("<QI", payload, FRAME_HEADER)
            assert actor_id > 0 and 1 <= kind <= 5
            # /clock: exactly the frame's simulation time.
            clock = typestore.deserialize_cdr(cdr, "rosgraph_msgs/msg/Clock").clock
            assert clock.sec * 1_000_000_000 + clock.nanosec == elapsed_ns

        status = replies(s, f"simbus/{world}/status")
        assert status[0][0] == "ok", status
        report = json.loads(status[0][1])
        assert report["world"] == world and report["frame"] == 20 and report["synchronous_mode"]
        settings = json.loads(replies(s, f"simbus/{world}/settings")[0][1])
        assert settings["fixed_delta_seconds"] == 0.05
        for sub in subs:
            sub.undeclare()
    finally:
        # A session left open keeps zenoh's threads, and pytest waits for
        # them at exit: closed even when an assertion failed.
        if s is not None:
            s.close()
        kill_all(procs)


def needed_size(s, world, service):
    """The size of `service`'s request, from the exporter's own error."""
    (kind, text), = replies(s, f"simbus/{world}/rpc/{service}?mirror=probe", payload=struct.pack("<II", PROTOCOL_VERSION, 0))
    assert kind == "err", text
    return int(re.search(r"header of (\d+) bytes", text).group(1))


def test_garbage_wrong_versions_and_a_tick_flood_change_nothing(request, tmp_path):
    world = world_name(request)
    procs = []
    try:
        endpoint, exporter = start_export(world, procs)
        mirror, mirror_env = start_mirror(world, endpoint, tmp_path, procs)
        s = session(endpoint)

        # Garbage frames: the mirror drops and counts them (put until it
        # says so: the peer's link to the mirror comes up by gossip).
        mirror_log, said = [], threading.Condition()

        def read_log():
            for line in mirror.stderr:
                with said:
                    mirror_log.append(line)
                    said.notify_all()

        threading.Thread(target=read_log, daemon=True).start()

        def logged(text):
            return any(text in line for line in mirror_log)

        deadline = time.time() + 30
        while not (logged("dropped a frame publication") and logged("dropped a capture publication")
                   and logged("dropped tick answers")):
            assert time.time() < deadline, "".join(mirror_log)
            s.put(f"simbus/{world}/frames", b"garbage")
            s.put(f"simbus/{world}/frames", struct.pack("<II", PROTOCOL_VERSION, 1000) + bytes(FRAME_HEADER - 8))
            s.put(f"simbus/{world}/sensor/7", b"\x00" * 3)
            s.put(f"simbus/{world}/tick/answer", b"\x05garbage")
            s.put(f"simbus/{world}/tick/ask", b"garbage")
            with said:
                said.wait(timeout=0.2)

        # Requests: without the mirror parameter, malformed, of another version.
        errors = [replies(s, f"simbus/{world}/rpc/control", payload=b"x")[0],
                  replies(s, f"simbus/{world}/rpc/nothing?mirror=m", payload=b"x")[0],
                  replies(s, f"simbus/{world}/rpc/control?mirror=m", payload=b"x")[0]]
        assert all(kind == "err" for kind, _ in errors), errors
        assert "must name its mirror" in errors[0][1]
        assert "no such service" in errors[1][1]
        assert "malformed control request" in errors[2][1]
        size = needed_size(s, world, "control")
        (kind, text), = replies(s, f"simbus/{world}/rpc/control?mirror=m", payload=struct.pack("<I", 99) + bytes(size - 4))
        assert kind == "err" and "protocol version 99" in text, text

        # A flood of ticks from a peer that does not hold the world: every
        # one answered (refused by the server, or dropped as too many in
        # flight), nothing steps.
        size = needed_size(s, world, "tick")
        tick = struct.pack("<IIII", PROTOCOL_VERSION, 3, 1, 0) + bytes(size - 16)
        answers = []
        lock = threading.Lock()

        def flood():
            for _ in range(50):
                for kind, body in replies(s, f"simbus/{world}/rpc/tick?mirror=flood", payload=tick):
                    with lock:
                        answers.append((kind, body))

        threads = [threading.Thread(target=flood) for _ in range(6)]
        for t in threads:
            t.start()
        for t in threads:
            t.join()
        assert len(answers) == 300
        for kind, body in answers:
            if kind == "ok":
                status, = struct.unpack_from("<I", body, 4)
                assert status == 5, status  # NotTicker
            else:
                assert "cannot send" in body, body

        # The world is unchanged and the mirror still mirrors it.
        status = sim_client(world, "status", "--json")
        assert status.returncode == 0, status.stderr
        report = json.loads(status.stdout)
        assert report["frame"] == 0 and report["ticker"] is None
        ticked = sim_client(world, "tick", "--count", "3", "--leave-sync", "--json", env=mirror_env)
        assert ticked.returncode == 0, ticked.stderr
        assert [json.loads(l)["frame"] for l in ticked.stdout.splitlines()] == [1, 2, 3]
        s.close()
        kill_all(procs)
        procs = []
        exporter_log = exporter.stderr.read()
        assert "dropped a request from another host" in exporter_log, exporter_log
    finally:
        kill_all(procs)


def test_a_mirror_refuses_an_exporter_of_another_protocol_version(request):
    """A fake exporter (this Zenoh peer) answers in protocol version 99: the
    mirror names both versions and creates nothing."""
    world = world_name(request)
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    conf = zenoh.Config()
    conf.insert_json5("mode", '"peer"')
    conf.insert_json5("listen/endpoints", json.dumps([endpoint]))
    conf.insert_json5("scouting/multicast/enabled", "false")
    s = zenoh.open(conf)
    asked = []

    def answer(query):
        asked.append(str(query.key_expr))
        query.reply(query.key_expr, struct.pack("<II", 99, 0) + bytes(64))

    queryable = s.declare_queryable(f"simbus/{world}/rpc/control", answer)
    # As an exporter does: its liveliness token after its queryables (the
    # mirror asks once it sees the token).
    token = s.liveliness().declare_token(f"simbus/{world}/alive/exporter")
    try:
        mirror = sim_client(world, "bridge", "zenoh", "--connect", endpoint)
        assert mirror.returncode == 1, mirror.stderr
        assert f"protocol version 99 is not this version's {PROTOCOL_VERSION}" in mirror.stderr, mirror.stderr
        assert asked == [f"simbus/{world}/rpc/control"]
    finally:
        token.undeclare()
        queryable.undeclare()
        s.close()


def test_a_mirrors_frames_carry_their_actors_poses(request, tmp_path):
    """The mirror writes each frame it receives (the header and the actors:
    the packed poses do not travel) with the actors' poses after them, as a
    server does: a Python client on the mirror's side, ticking through it,
    reads the same poses from `frame.poses` as from `frame.actors`."""
    world = world_name(request)
    procs = []
    try:
        endpoint, _ = start_export(world, procs)
        _, mirror_env = start_mirror(world, endpoint, tmp_path, procs)
        code = f"""
import simbus
client = simbus.connect({world!r}, timeout=20)
counts = []
with client.ticker() as ticker:
    for _ in range(5):
        ticked = ticker.tick()
        frame = client.wait_for_frame(timeout=10)
        while frame.frame < ticked:
            frame.release()
            frame = client.wait_for_frame(timeout=10)
        with frame:
            actors, poses = frame.actors, frame.poses
            assert len(poses) == len(actors) > 0, (len(poses), len(actors))
            for field in ("id", "kind", "flags", "position", "rotation"):
                assert (poses[field] == actors[field]).all(), field
            counts.append(len(poses))
            del actors, poses
print("poses", counts)
"""
        child = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                               timeout=120, env=mirror_env)
        assert child.returncode == 0, child.stderr
        assert child.stdout.strip() == "poses [17, 17, 17, 17, 17]", child.stdout
    finally:
        kill_all(procs)


def test_a_walker_crosses_to_the_mirror_and_walks_there(request, tmp_path):
    """A walker spawned on the server's host, walking with its control,
    is in the mirror's frames on the other host: kind walker (6), its size,
    and the same steps frame by frame as the server computes them."""
    import simbus

    world = world_name(request)
    procs = []
    try:
        endpoint, _ = start_export(world, procs)
        origin = simbus.connect(world, timeout=20)
        walker = origin.spawn("walker", at=(-20.0, 1.0, 5.0), radius=0.3, half_height=0.9)
        origin.apply_batch_sync([simbus.ApplyWalkerControl(walker, (1.0, 0.0, 0.0), 1.4)])
        _, mirror_env = start_mirror(world, endpoint, tmp_path, procs)
        code = f"""
import simbus
client = simbus.connect({world!r}, timeout=20)
xs = []
with client.ticker() as ticker:
    for _ in range(20):
        ticked = ticker.tick()
        frame = client.wait_for_frame(timeout=10)
        while frame.frame < ticked:
            frame.release()
            frame = client.wait_for_frame(timeout=10)
        with frame:
            actors = frame.actors
            [me] = actors[actors["id"] == {walker}]
            assert me["kind"] == 6, me["kind"]
            assert abs(float(me["extent"][0]) - 0.3) < 1e-6
            xs.append(float(me["position"][0]))
            del actors, me
print("xs", xs)
"""
        child = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True,
                               timeout=120, env=mirror_env)
        assert child.returncode == 0, child.stderr
        xs = [float(x) for x in child.stdout.split("[")[1].split("]")[0].split(",")]
        assert len(xs) == 20
        # 1 s at 1.4 m/s along +x.
        assert 1.0 < xs[-1] - xs[0] < 1.6, xs
        assert all(b >= a for a, b in zip(xs, xs[1:])), xs
    finally:
        kill_all(procs)
