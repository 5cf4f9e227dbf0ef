"""simbus's sensors from Python: `client.spawn_sensor(...)`, captures whose
`array` is a read-only numpy view of the capture's shared memory (the very
bytes the server published and the Rust client reads), the loan rules
(released captures raise, a live array keeps its capture), the stream's end
with its reason, `listen(callback)` on a thread of its own, and bad specs
refused before anything is spawned. Each test runs its own sim-server on a
world of its own."""

import builtins
import itertools
import json
import os
import struct
import subprocess
import threading

import numpy as np
import pytest
from mcap.reader import make_reader

import simbus

BIN = os.environ["SIMBUS_BIN_DIR"]
_worlds = itertools.count()

# simbus::SensorHeader/2, as the recorder writes it before each capture.
SENSOR_HEADER = struct.Struct("<IIQQQQQ3fI4f2IIId")
# A camera 2 m up, pitched 15 degrees down (about Z): it sees the ground.
LOOKING_DOWN = (0.0, 0.0, -0.130526, 0.991445)


@pytest.fixture
def world():
    name = f"py-sensors-{os.getpid()}-{next(_worlds)}"
    server = subprocess.Popen(
        [os.path.join(BIN, "sim-server"), "--world", name, "--scene", "default"],
        stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL,
    )
    try:
        yield name
    finally:
        server.kill()
        server.wait(timeout=10)


@pytest.fixture
def client(world):
    return simbus.connect(world, timeout=10)


def sim_client(world, *args, check=True):
    run = subprocess.run(
        [os.path.join(BIN, "sim-client"), "--world", world, *args],
        capture_output=True, text=True, timeout=60,
    )
    if check:
        assert run.returncode == 0, f"{run.args}: {run.returncode}\n{run.stdout}\n{run.stderr}"
    return run


def drain_until_ended(sensor, reads=20):
    """Reads until the stream ends; returns the SensorEnded raised."""
    with pytest.raises(simbus.SensorEnded) as ended:
        for _ in range(reads):
            sensor.read(timeout=5).release()
    return ended.value


def save_raw_while_ticking(world, sensor_id, out, ticker, each_frame):
    """Runs `sim-client sensor save ID --raw` into `out` and ticks, calling
    `each_frame(frame)` after every tick, until the CLI has subscribed,
    taken a capture and written it; asserts it exited 0."""
    save = subprocess.Popen(
        [os.path.join(BIN, "sim-client"), "--world", world, "--timeout", "30",
         "sensor", "save", str(sensor_id), "--raw", "--out", str(out)],
        stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
    )
    try:
        for _ in range(100_000):
            if save.poll() is not None:
                break
            each_frame(ticker.tick())
    finally:
        save.kill()
        stdout, stderr = save.communicate(timeout=10)
    assert save.returncode == 0, stdout + stderr


def recorded_captures(path, sensor_id):
    """{frame: (header fields, payload bytes)} of a sensor in a recording."""
    captures = {}
    with open(path, "rb") as f:
        for _, channel, message in make_reader(f).iter_messages(topics=[f"/simbus/sensor/{sensor_id}"]):
            header = SENSOR_HEADER.unpack_from(message.data)
            captures[header[3]] = (header, message.data[SENSOR_HEADER.size:])
    return captures


def test_depth_and_lidar_arrays_are_the_bytes_the_server_recorded(world, client, tmp_path):
    recording = tmp_path / "sensors.mcap"
    seen = {}
    with client.ticker(delta_seconds=0.05) as ticker:
        depth = client.spawn_sensor("depth", width=32, height=24, fov=70, rotation=LOOKING_DOWN)
        lidar = client.spawn_sensor("lidar", channels=8, points=64, range=40)
        sim_client(world, "recorder", "start", str(recording), "--sensors")
        for _ in range(3):
            frame = ticker.tick()
            for sensor in (depth, lidar):
                with sensor.read() as capture:
                    assert capture.frame == frame
                    seen[sensor.id, frame] = (capture.array.tobytes(), capture.count,
                                              capture.position, capture.rotation)
        sim_client(world, "recorder", "stop")
    frames = sorted({f for (_, f) in seen})
    for sensor in (depth, lidar):
        recorded = recorded_captures(recording, sensor.id)
        assert set(frames) <= set(recorded), (frames, sorted(recorded))
        for frame in frames:
            array_bytes, count, position, rotation = seen[sensor.id, frame]
            header, payload = recorded[frame]
            assert (header[2], header[10]) == (sensor.id, count)
            assert (position, rotation) == (header[7:10], header[11:15])
            element = 4 if sensor.kind == "depth" else 16
            assert array_bytes == payload[: count * element], (sensor.kind, frame)
    # Not a trivial comparison: the camera sees the ground at many depths,
    # the lidar hits something.
    depth_bytes = seen[depth.id, frames[-1]][0]
    assert len(np.unique(np.frombuffer(depth_bytes, np.float32))) > 10
    assert seen[lidar.id, frames[-1]][1] > 0


def test_lidar_array_is_what_the_rust_client_reads(world, client, tmp_path):
    """`sim-client sensor save` writes the lidar returns it reads (PLY,
    each float printed to round-trip); the same frame's array holds them."""
    mine = {}
    with client.ticker(delta_seconds=0.05) as ticker:
        lidar = client.spawn_sensor("lidar", channels=8, points=64, range=40)
        save = subprocess.Popen(
            [os.path.join(BIN, "sim-client"), "--world", world, "--timeout", "30",
             "sensor", "save", str(lidar.id), "--out", str(tmp_path)],
            stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
        )
        try:
            # Tick until the CLI has subscribed, taken a capture and written it.
            for _ in range(100_000):
                if save.poll() is not None:
                    break
                frame = ticker.tick()
                with lidar.read() as capture:
                    mine[frame] = capture.array.tobytes()
        finally:
            save.kill()
            out, err = save.communicate(timeout=10)
    assert save.returncode == 0, out + err
    [ply] = tmp_path.glob(f"sensor{lidar.id}-frame*.ply")
    frame = int(ply.stem.rsplit("frame", 1)[1])
    lines = ply.read_text().splitlines()
    body = lines[lines.index("end_header") + 1:]
    saved = np.array([line.split() for line in body], dtype=np.float32).reshape(-1, 4)
    assert len(saved) > 0
    assert mine[frame] == saved.tobytes()


def test_camera_images_are_bgra_views_the_cli_saves_raw_and_the_recorder_keeps(world, client, tmp_path):
    """An RGB, a semantic and an instance camera at one pose: each capture
    is a read-only `uint8 (height, width, 4)` view over its loan; the
    bytes `sim-client sensor save --raw` writes (what the Rust client
    reads) and the recording holds are the array's."""
    mine = {}
    recording = tmp_path / "cameras.mcap"
    with client.ticker(delta_seconds=0.05) as ticker:
        cameras = [client.spawn_sensor(kind, width=40, height=30, fov=70, rotation=LOOKING_DOWN)
                   for kind in ("rgb", "semantic", "instance")]
        rgb = cameras[0]
        sim_client(world, "recorder", "start", str(recording), "--sensors")
        def read_cameras(frame):
            for camera in cameras:
                with camera.read() as capture:
                    assert capture.frame == frame
                    array = capture.array
                    assert array.dtype == np.uint8 and array.shape == (30, 40, 4)
                    assert not array.flags.writeable
                    assert (array[:, :, 3] == 255).all()
                    mine[camera.kind, frame] = array.tobytes()
                    del array

        save_raw_while_ticking(world, rgb.id, tmp_path, ticker, read_cameras)
        sim_client(world, "recorder", "stop")
    [raw] = tmp_path.glob(f"sensor{rgb.id}-frame*.raw")
    frame = int(raw.stem.rsplit("frame", 1)[1])
    assert raw.read_bytes() == mine["rgb", frame]
    assert (tmp_path / f"sensor{rgb.id}-frame{frame}.png").exists()
    recorded = recorded_captures(recording, cameras[1].id)
    assert recorded[frame][1] == mine["semantic", frame]
    # Not trivial: the camera looking down sees the ground's tags and the
    # sky's, and the RGB image is not one colour.
    tags = set(np.frombuffer(mine["semantic", frame], np.uint8)[2::4])
    assert {11} < tags, tags
    assert len(set(np.frombuffer(mine["rgb", frame], np.uint32))) > 10


def test_semantic_lidar_and_radar_are_structured_views_the_cli_saves_raw_and_the_recorder_keeps(
        world, client, tmp_path):
    """A semantic lidar and a radar over the default scene: each capture
    is a read-only structured array of CARLA's layout over its loan (24-
    and 16-byte records, `count` of them), frame-exact; the bytes `sim-client
    sensor save --raw` writes (what the Rust client reads) and the
    recording holds start with the array's."""
    mine = {}
    recording = tmp_path / "ranging.mcap"
    with client.ticker(delta_seconds=0.05) as ticker:
        lidar = client.spawn_sensor("semantic_lidar", channels=16, points=256, range=40)
        radar = client.spawn_sensor("radar", at=(-12.0, 1.0, 0.0), fov=40, vertical_fov=20,
                                    points_per_second=2000, noise={"seed": 3})
        assert (lidar.kind, radar.kind) == ("semantic_lidar", "radar")
        sim_client(world, "recorder", "start", str(recording), "--sensors")
        def read_both(frame):
            for sensor in (lidar, radar):
                with sensor.read() as capture:
                    assert capture.frame == frame
                    array = capture.array
                    assert not array.flags.writeable and array.shape == (capture.count,)
                    mine[sensor.kind, frame] = (array.tobytes(), array.copy())
                    del array

        save_raw_while_ticking(world, lidar.id, tmp_path, ticker, read_both)
        sim_client(world, "recorder", "stop")
    [raw] = tmp_path.glob(f"sensor{lidar.id}-frame*.raw")
    frame = int(raw.stem.rsplit("frame", 1)[1])
    points_bytes, points = mine["semantic_lidar", frame]
    assert raw.read_bytes()[:len(points_bytes)] == points_bytes
    assert (tmp_path / f"sensor{lidar.id}-frame{frame}.ply").exists()
    assert points.dtype.names == ("x", "y", "z", "cos_inc_angle", "object_idx", "object_tag")
    assert points.dtype.itemsize == 24
    # The ground (actor 1, tagged by its cover) and the scene's bodies
    # (boxes, spheres, capsules: dynamic 21).
    tags = set(points["object_tag"])
    assert 1 in set(points["object_idx"]) and 21 in tags and tags & {1, 2, 10, 24, 25}
    assert ((points["cos_inc_angle"] > 0) & (points["cos_inc_angle"] <= 1)).all()
    detections_bytes, detections = mine["radar", frame]
    assert detections.dtype.names == ("velocity", "azimuth", "altitude", "depth")
    assert detections.dtype.itemsize == 16 and 0 < len(detections) <= 100
    assert (abs(detections["azimuth"]) <= np.radians(20) + 1e-4).all()
    assert (abs(detections["altitude"]) <= np.radians(10) + 1e-4).all()
    recorded = recorded_captures(recording, radar.id)
    assert recorded[frame][1][:len(detections_bytes)] == detections_bytes


def test_a_gnss_reading_is_one_float64_record_of_the_place(client):
    """A GNSS receiver 100 m along Z and 30 m along X of the origin, 2 m
    up: one record (latitude, longitude, altitude), float64, over the
    capture's memory; near the map's origin a degree is 111 274.955 m
    (0.9996 x 6 378 137 m x pi / 180) both ways."""
    with client.ticker(delta_seconds=0.05) as ticker:
        gnss = client.spawn_sensor("gnss", at=(30.0, 2.0, 100.0))
        assert gnss.kind == "gnss"
        frame = ticker.tick()
        with gnss.read() as capture:
            assert (capture.frame, capture.kind) == (frame, "gnss")
            record = capture.array
            assert record.dtype.names == ("latitude", "longitude", "altitude")
            assert record.shape == (1,) and record.dtype.itemsize == 24
            assert record["latitude"][0] == pytest.approx(100.0 / 111274.955, abs=1e-7)
            assert record["longitude"][0] == pytest.approx(30.0 / 111274.955, abs=1e-7)
            assert record["altitude"][0] == pytest.approx(2.0, abs=1e-5)
            del record  # a view may not outlive the capture's loan
    with pytest.raises(ValueError, match="unknown sensor kind \"sonar\": expected 'depth'"):
        client.spawn_sensor("sonar")


def test_gnss_noise_repeats_with_its_seed_and_bad_noise_spawns_nothing(client):
    noise = {"lat_stddev": 1e-5, "alt_stddev": 0.5, "alt_bias": 10.0, "seed": 7}
    with client.ticker(delta_seconds=0.05) as ticker:
        sensors = [client.spawn_sensor("gnss", noise=n) for n in (noise, noise, {**noise, "seed": 8})]
        readings = [[], [], []]
        for _ in range(10):
            ticker.tick()
            for sensor, got in zip(sensors, readings):
                with sensor.read() as capture:
                    got.append(capture.array.copy())
    assert readings[0] == readings[1] and readings[0] != readings[2]
    assert 11.0 < np.mean([r["altitude"][0] for r in readings[0]]) < 13.0
    spawned = len(client.list_sensors())
    for bad, message in [({"alt_stddev": -1.0}, "GNSS biases must be finite"),
                         ({"seed": 0.5}, "GNSS biases must be finite"),
                         ({"colour": 1.0}, "unknown noise setting 'colour'")]:
        with pytest.raises(ValueError, match=message):
            client.spawn_sensor("gnss", noise=bad)
    with pytest.raises(ValueError, match="noise applies to gnss, lidar or radar sensors, not to depth"):
        client.spawn_sensor("depth", noise={"seed": 1})
    assert len(client.list_sensors()) == spawned


def test_arrays_have_each_kind_s_shape_and_dtype_over_the_loan(client):
    with client.ticker(delta_seconds=0.05) as ticker:
        depth = client.spawn_sensor("depth", width=32, height=24, rotation=LOOKING_DOWN)
        lidar = client.spawn_sensor("lidar", channels=8, points=64)
        imu = client.spawn_sensor("imu", at=(1.0, 0.5, -2.0))
        assert (depth.kind, lidar.kind, imu.kind) == ("depth", "lidar", "imu")
        frame = ticker.tick()
        d, l, i = depth.read(), lidar.read(), imu.read()
        assert (d.frame, l.frame, i.frame) == (frame, frame, frame)
        assert (d.width, d.height, d.kind, d.sensor_id) == (32, 24, "depth", depth.id)
        assert d.array.dtype == np.float32 and d.array.shape == (24, 32)
        # Rows top to bottom: a camera looking down sees nearer ground below.
        assert d.array[-1].mean() < d.array[0].mean()
        assert (l.width, l.height) == (8, 64)
        assert l.array.dtype == np.float32 and l.array.shape == (l.count, 4)
        assert 0 < l.count <= 8 * 64
        assert i.array.dtype.names == ("accelerometer", "gyroscope")
        assert i.array.shape == (1,) and i.array.dtype.itemsize == 24
        # At rest in the world: gravity's reaction, up; no rotation.
        assert i.array["accelerometer"][0] == pytest.approx([0.0, 9.81, 0.0], abs=1e-3)
        assert i.array["gyroscope"][0] == pytest.approx([0.0, 0.0, 0.0], abs=1e-6)
        assert i.position == pytest.approx((1.0, 0.5, -2.0))
        assert i.rotation == pytest.approx((0.0, 0.0, 0.0, 1.0))
        for capture in (d, l, i):
            array = capture.array
            assert not array.flags.writeable
            with pytest.raises(ValueError):
                array.flat[0] = 0
            base = array
            while isinstance(base, np.ndarray):
                base = base.base
            assert type(base).__name__ == "Loan"
            del array, base
            capture.release()


def test_release_rules(client):
    with client.ticker(delta_seconds=0.05) as ticker:
        depth = client.spawn_sensor("depth", width=16, height=12, rotation=LOOKING_DOWN)
        frame = ticker.tick()
        capture = depth.read()
        kept = capture.copy()
        live = capture.array
        expected = live.copy()
        with pytest.raises(BufferError, match="1 numpy array"):
            capture.release()
        assert capture.held
        np.testing.assert_array_equal(live, expected)
        del live
        capture.release()
        assert not capture.held
        with pytest.raises(simbus.ReleasedError, match=f"frame {frame}"):
            capture.array
        with pytest.raises(simbus.ReleasedError):
            capture.copy()
        capture.release()  # harmless twice
        assert capture.frame == frame  # the header's values stay
        assert kept.frame == frame and kept.array.tobytes() == expected.tobytes()
        # The end of a `with` block releases.
        ticker.tick()
        with depth.read() as inside:
            pass
        with pytest.raises(simbus.ReleasedError):
            inside.array


def test_a_reader_holds_two_captures_at_most(client):
    with client.ticker(delta_seconds=0.05) as ticker:
        imu = client.spawn_sensor("imu")
        frames = [ticker.tick() for _ in range(3)]
        first, second = imu.read(), imu.read()
        with pytest.raises(simbus.Full, match=f"sensor {imu.id} already holds 2"):
            imu.read()
        first.release()
        third = imu.read()  # the queued capture was not lost
        assert [first.frame, second.frame, third.frame] == frames
        assert imu.missed == 0


def test_a_destroyed_sensor_ends_its_stream_with_the_reason(world, client):
    with client.ticker(delta_seconds=0.05) as ticker:
        depth = client.spawn_sensor("depth", width=8, height=6)
        ticker.tick()
        other = simbus.connect(world)
        other.destroy_sensor(depth.id)
        ticker.tick()
        ended = drain_until_ended(depth)
        assert ended.reason == "destroyed"
        assert isinstance(ended, simbus.Error) and f"sensor {depth.id}" in str(ended)
        with pytest.raises(simbus.SensorEnded):
            depth.read()
        assert depth.id not in [s.id for s in client.list_sensors()]
        with pytest.raises(simbus.CommandError, match=f"unknown sensor {depth.id}"):
            client.destroy_sensor(depth.id)
        with pytest.raises(simbus.CommandError, match=f"unknown sensor {depth.id}"):
            client.sensor(depth.id)


def test_a_sensor_ends_with_its_parent(world, client):
    spawned = sim_client(world, "spawn", "box", "--at", "0,3,0", "--json")
    parent = json.loads(spawned.stdout)["id"]
    imu = client.spawn_sensor("imu", parent=parent, at=(0.0, 1.0, 0.0))
    [info] = [s for s in client.list_sensors() if s.id == imu.id]
    assert (info.parent, info.kind, info.position) == (parent, "imu", (0.0, 1.0, 0.0))
    imu.read().release()  # asynchronous mode: captures come by themselves
    sim_client(world, "destroy", str(parent))
    ended = drain_until_ended(imu, reads=1000)
    assert ended.reason == "parent destroyed"
    with pytest.raises(simbus.CommandError, match=f"no actor {parent}"):
        client.spawn_sensor("imu", parent=parent)


def test_listen_gets_every_frame_on_its_own_thread_until_stopped(client):
    with client.ticker(delta_seconds=0.05) as ticker:
        depth = client.spawn_sensor("depth", width=16, height=12, rotation=LOOKING_DOWN)
        main = threading.get_ident()
        got, arrived = [], threading.Condition()

        def on_capture(capture):
            with arrived:
                got.append((capture.frame, capture.sequence, threading.get_ident(),
                            capture.array.copy(), capture))
                arrived.notify()

        listening = depth.listen(on_capture)
        assert listening.running
        ticked, mine = [], []
        for _ in range(5):
            ticked.append(ticker.tick())
            with arrived:
                assert arrived.wait_for(lambda: len(got) == len(ticked), timeout=10)
            with depth.read() as capture:  # the main thread's own reader
                mine.append((capture.frame, capture.array.tobytes()))
        listening.stop()
        assert not listening.running and listening.ended is None
        assert [g[0] for g in got] == ticked
        assert [g[1] for g in got] == list(range(got[0][1], got[0][1] + 5))
        assert {g[2] for g in got} != {main}
        assert mine == [(g[0], g[3].tobytes()) for g in got]
        # A capture kept past its callback was given back, its values kept.
        kept = got[0][4]
        assert kept.frame == ticked[0] and not kept.held
        with pytest.raises(simbus.ReleasedError):
            kept.array
        ticker.tick()
        assert listening.captures == 5 and len(got) == 5
        listening.stop()  # harmless twice


def test_listen_prints_callback_errors_and_ends_with_the_sensor(world, client, capfd):
    with client.ticker(delta_seconds=0.05) as ticker:
        imu = client.spawn_sensor("imu")
        frames, arrived = [], threading.Condition()

        def on_capture(capture):
            with arrived:
                frames.append(capture.frame)
                arrived.notify()
            if len(frames) == 2:
                raise RuntimeError(f"callback failed on frame {capture.frame}")

        with imu.listen(on_capture) as listening:
            ticked = [ticker.tick() for _ in range(3)]
            with arrived:
                assert arrived.wait_for(lambda: len(frames) == 3, timeout=10)
            simbus.connect(world).destroy_sensor(imu.id)
            assert listening.wait(timeout=10)
        assert frames == ticked and listening.errors == 1
        assert isinstance(listening.ended, simbus.SensorEnded)
        assert listening.ended.reason == "destroyed"
        assert f"RuntimeError: callback failed on frame {ticked[1]}" in capfd.readouterr().err


def test_reads_time_out_and_closed_readers_refuse(client):
    with client.ticker(delta_seconds=0.05) as ticker:
        with client.spawn_sensor("imu") as imu:
            with pytest.raises(simbus.TimeoutError) as timed_out:
                imu.read(timeout=0.2)
            assert isinstance(timed_out.value, builtins.TimeoutError)
            assert imu.try_read() is None
            again = client.sensor(imu.id)  # a second reader of the same sensor
            frame = ticker.tick()
            assert again.read().frame == imu.read().frame == frame
        assert imu.closed
        with pytest.raises(simbus.Error, match="closed"):
            imu.read()
        assert imu.id in [s.id for s in client.list_sensors()]  # closed, not destroyed
        with pytest.raises(simbus.CommandError, match="unknown sensor 999"):
            client.sensor(999)


@pytest.mark.parametrize(
    "kind, arguments, error",
    [
        ("camera", {}, "unknown sensor kind"),
        ("depth", {"width": 0}, "width and height must be whole numbers"),
        ("depth", {"height": -4}, "width and height must be whole numbers"),
        ("depth", {"width": 6.5}, "width and height must be whole numbers"),
        ("depth", {"fov": float("nan")}, "finite"),
        ("depth", {"fov": 180}, "field of view"),
        ("lidar", {"channels": 0}, "lidar channels"),
        ("lidar", {"upper_fov": -40, "lower_fov": 10}, "lower_fov <= upper_fov"),
        ("imu", {"at": (float("inf"), 0, 0)}, "finite"),
        ("imu", {"sensor_tick": -1}, "sensor_tick"),
        ("radar", {"points_per_second": 0}, "radar's fields of view"),
        ("radar", {"points_per_second": 10.5}, "radar's fields of view"),
        ("radar", {"vertical_fov": 180}, "radar's fields of view"),
        ("radar", {"range": -1}, "radar's fields of view"),
        ("radar", {"noise": {"seed": -1}}, "radar's fields of view"),
        ("radar", {"noise": {"lat_bias": 1}}, "unknown noise setting 'lat_bias' for a radar"),
        ("semantic_lidar", {"channels": 0}, "lidar channels"),
        ("semantic_lidar", {"noise": {"seed": 1}}, "noise applies to gnss, lidar or radar sensors, not to semantic_lidar"),
        ("lidar", {"noise": {"dropoff_general_rate": 2}}, "dropoff_general_rate"),
        ("lidar", {"noise": {"stddev": -1}}, "noise_stddev"),
        ("lidar", {"noise": {"seed": 0.5}}, "noise_seed"),
        ("lidar", {"noise": {"colour": 1}}, "unknown noise setting 'colour' for a lidar"),
        ("semantic_lidar", {"range": 0}, "lidar range"),
        ("radar", {"channels": 4}, "channels applies to lidar or semantic_lidar sensors, not to radar"),
        ("depth", {"channels": 4}, "channels applies to lidar or semantic_lidar sensors, not to depth"),
    ],
)
def test_bad_specs_are_refused_and_spawn_nothing(client, kind, arguments, error):
    before = [s.id for s in client.list_sensors()]
    with pytest.raises(ValueError, match=error):
        client.spawn_sensor(kind, **arguments)
    assert [s.id for s in client.list_sensors()] == before
