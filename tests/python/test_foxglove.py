"""`sim-client foxglove` read by a Foxglove WebSocket client simbus did not
write: the `websockets` package speaking the Foxglove WebSocket protocol
as documented (subprotocol `foxglove.sdk.v1`, the SDK's name for
`foxglove.websocket.v1` with inline schemas: JSON `advertise`/`subscribe`,
binary message-data and time frames), and every message decoded by Google's
protobuf runtime from the schema the server advertises."""

import asyncio
import base64
import json
import os
import struct
import subprocess

from google.protobuf import descriptor_pb2, descriptor_pool, message_factory
import websockets

from conftest import BIN, kill_all, wait_line, world_name

SUBPROTOCOL = "foxglove.sdk.v1"
# Server binary opcodes.
MESSAGE_DATA, TIME = 0x01, 0x02


def message_class(channel):
    """The protobuf class of `channel`, built from its advertised schema."""
    assert channel["encoding"] == "protobuf", channel
    assert channel["schemaEncoding"] == "protobuf", channel
    files = descriptor_pb2.FileDescriptorSet.FromString(base64.b64decode(channel["schema"]))
    pool = descriptor_pool.DescriptorPool()
    for file in files.file:
        pool.Add(file)
    return message_factory.GetMessageClass(pool.FindMessageTypeByName(channel["schemaName"]))


async def collect(port, topics, count, timeout=30.0):
    """Subscribes to `topics` and returns, per topic, the first `count`
    messages as (log time ns, decoded message), and the time messages."""
    async with websockets.connect(
        f"ws://127.0.0.1:{port}", subprotocols=[SUBPROTOCOL], max_size=None
    ) as ws:
        assert ws.subprotocol == SUBPROTOCOL
        channels, subscribed, got, times = {}, {}, {t: [] for t in topics}, []
        deadline = asyncio.get_running_loop().time() + timeout
        while any(len(got[t]) < count for t in topics):
            remaining = deadline - asyncio.get_running_loop().time()
            assert remaining > 0, f"only {[(t, len(m)) for t, m in got.items()]} in {timeout} s"
            try:
                raw = await asyncio.wait_for(ws.recv(), remaining)
            except asyncio.TimeoutError:
                raise AssertionError(
                    f"only {[(t, len(m)) for t, m in got.items()]} in {timeout} s; "
                    f"subscribed to {sorted(subscribed.values())}, {len(times)} time messages"
                ) from None
            if isinstance(raw, str):
                op = json.loads(raw)
                if op["op"] == "advertise":
                    for channel in op["channels"]:
                        channels[channel["id"]] = channel
                        if channel["topic"] in topics and channel["topic"] not in subscribed.values():
                            sub = len(subscribed) + 1
                            subscribed[sub] = channel["topic"]
                            await ws.send(json.dumps({
                                "op": "subscribe",
                                "subscriptions": [{"id": sub, "channelId": channel["id"]}],
                            }))
                continue
            if raw[0] == TIME:
                times.append(struct.unpack_from("<Q", raw, 1)[0])
                continue
            assert raw[0] == MESSAGE_DATA, raw[0]
            sub, log_time = struct.unpack_from("<IQ", raw, 1)
            topic = subscribed[sub]
            channel = next(c for c in channels.values() if c["topic"] == topic)
            if len(got[topic]) < count:
                got[topic].append((log_time, message_class(channel).FromString(raw[13:])))
        return got, times


def test_the_scene_clock_and_a_depth_camera_reach_a_foxglove_client(request, tmp_path):
    world = world_name(request)
    procs = []
    try:
        server = subprocess.Popen(
            [os.path.join(BIN, "sim-server"), "--world", world, "--scene", "default"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
        )
        procs.append(server)
        status = subprocess.run(
            [os.path.join(BIN, "sim-client"), "--world", world, "--timeout", "20", "status", "--json"],
            capture_output=True, text=True, timeout=60, check=True,
        )
        actors = json.loads(status.stdout)["actors"]
        spawned = subprocess.run(
            [os.path.join(BIN, "sim-client"), "--world", world, "sensor", "spawn", "depth", "--size", "64,48"],
            capture_output=True, text=True, timeout=60, check=True,
        )
        sensor = spawned.stdout.split()[-1]
        lidar = subprocess.run(
            [os.path.join(BIN, "sim-client"), "--world", world, "sensor", "spawn", "lidar",
             "--channels", "8", "--points", "64"],
            capture_output=True, text=True, timeout=60, check=True,
        ).stdout.split()[-1]
        # The bridge's own log, shown if the messages do not come.
        log = tmp_path / "bridge.log"
        bridge = subprocess.Popen(
            [os.path.join(BIN, "sim-client"), "--world", world, "foxglove", "--port", "0", "--max-hz", "0"],
            stdout=subprocess.PIPE, stderr=open(log, "w"), text=True, start_new_session=True,
            env={**os.environ, "RUST_LOG": "simbus_foxglove=debug,foxglove=info"},
        )
        procs.append(bridge)
        line = wait_line(bridge, "foxglove:")
        port = int(line.split("ws://127.0.0.1:")[1].split()[0])

        depth_topic = f"/simbus/sensor/{sensor}/depth"
        lidar_topic = f"/simbus/sensor/{lidar}/points"
        try:
            got, times = asyncio.run(collect(port, ["/simbus/scene", depth_topic, lidar_topic], 10))
        except AssertionError as e:
            raise AssertionError(f"{e}\nthe bridge's log:\n{log.read_text()[-4000:]}") from None

        scene = got["/simbus/scene"]
        previous = -1
        for log_time, update in scene:
            assert len(update.entities) == actors
            assert len({e.id for e in update.entities}) == actors, "one entity per actor"
            assert all(e.frame_id == "world" for e in update.entities)
            # Every entity carries the frame's time, the message's log time.
            stamps = {e.timestamp.seconds * 10**9 + e.timestamp.nanos for e in update.entities}
            assert stamps == {log_time}
            assert log_time > previous, "frames in order, none twice"
            previous = log_time
        kinds = {
            ("cubes" if e.cubes else "spheres" if e.spheres and not e.cylinders else "capsule")
            for _, u in scene[:1] for e in u.entities
        }
        assert kinds == {"cubes", "spheres", "capsule"}, kinds
        assert times, "the simulation clock is broadcast"
        assert max(times) >= scene[0][0]

        for log_time, image in got[depth_topic]:
            assert (image.width, image.height, image.encoding) == (64, 48, "32FC1")
            assert image.step == 64 * 4 and len(image.data) == 64 * 48 * 4
            depths = struct.unpack(f"<{64 * 48}f", image.data)
            assert all(0.0 < d <= 100.0 for d in depths), "planar depths within range"
            assert image.timestamp.seconds * 10**9 + image.timestamp.nanos == log_time

        for _, cloud in got[lidar_topic]:
            assert cloud.point_stride == 16 and cloud.frame_id == "world"
            assert [(f.name, f.offset) for f in cloud.fields] == [
                ("x", 0), ("y", 4), ("z", 8), ("intensity", 12)]
            points = len(cloud.data) // 16
            assert 0 < points <= 8 * 64 and len(cloud.data) == points * 16
            # Posed at the sensor: 2 m up, by default.
            assert abs(cloud.pose.position.y - 2.0) < 1e-6
    finally:
        kill_all(procs)


def test_debug_shapes_clients_draw_join_the_foxglove_scene(request, tmp_path):
    """Shapes a client draws (`client.draw_*`, what the CARLA gateway's
    `world.debug.draw_*` become) reach a Foxglove client as one `debug`
    entity of the scene: points as spheres, lines and boxes as line lists,
    texts as billboards, in the world's frame."""
    import simbus

    world = world_name(request)
    procs = []
    try:
        server = subprocess.Popen(
            [os.path.join(BIN, "sim-server"), "--world", world, "--scene", "empty"],
            stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL, start_new_session=True,
        )
        procs.append(server)
        client = simbus.connect(world, timeout=20.0)
        client.draw_point([1.0, 2.0, 3.0], size=0.5, color=[0, 255, 0], life_time=0.0)
        client.draw_line([0.0, 0.0, 0.0], [5.0, 0.0, 0.0], thickness=0.05, life_time=0.0)
        client.draw_box([0.0, 1.0, 0.0], [1.0, 1.0, 2.0], life_time=0.0)
        client.draw_string([0.0, 3.0, 0.0], "hello", color=[255, 255, 255, 128], life_time=0.0)
        log = tmp_path / "bridge.log"
        bridge = subprocess.Popen(
            [os.path.join(BIN, "sim-client"), "--world", world, "foxglove", "--port", "0", "--max-hz", "0"],
            stdout=subprocess.PIPE, stderr=open(log, "w"), text=True, start_new_session=True,
        )
        procs.append(bridge)
        line = wait_line(bridge, "foxglove:")
        port = int(line.split("ws://127.0.0.1:")[1].split()[0])
        try:
            got, _ = asyncio.run(collect(port, ["/simbus/scene"], 3))
        except AssertionError as e:
            raise AssertionError(f"{e}\nthe bridge's log:\n{log.read_text()[-4000:]}") from None
        for _, update in got["/simbus/scene"]:
            [debug] = [e for e in update.entities if e.id == "debug"]
            assert debug.frame_id == "world"
            [point] = debug.spheres
            assert (point.pose.position.x, point.pose.position.y, point.pose.position.z) == (1.0, 2.0, 3.0)
            assert (point.color.g, point.size.x) == (1.0, 0.5)
            line, box = debug.lines
            assert len(line.points) == 2 and len(box.points) == 24, "a box's 12 edges"
            [text] = debug.texts
            assert text.text == "hello" and text.billboard and abs(text.color.a - 128 / 255) < 1e-6
        client.clear_debug_shapes()
    finally:
        kill_all(procs)
