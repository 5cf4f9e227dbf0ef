"""`sim-client ros2` read and driven by a stock rclpy (ROS 2 Kilted's
wheels from PyPI, over Fast DDS; no ROS install): /clock frame-exact for
use_sim_time, one tick's sensors on one stamp with simbus's own bytes,
odometry, control from ROS (and a malformed control dropped and
counted), and a ROS node as the world's ticker under the single-ticker
rule. Each test on a world and a DDS domain of its own, localhost only."""

import itertools
import json
import os
import queue
import signal
import subprocess
import sys
import threading
import time

import numpy as np
import pytest

from simbus_support import BIN, server  # noqa: F401  (the fixture)

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import rclpy  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.parameter import Parameter  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import Image, Imu, PointCloud2  # noqa: E402
from nav_msgs.msg import Odometry  # noqa: E402
from std_msgs.msg import Empty, Float32MultiArray, String  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")  # rclpy's lark

# Domains 1..101: their ports stay below Linux's ephemeral range (ROS's
# advice); the Rust tests take 215..232.
_domains = itertools.count((os.getpid() % 25) * 4 + 1)
# Deep enough for every tick of a test: the node does not spin while the
# test ticks, so its reader keeps them all until it does.
RELIABLE = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)


def ns(stamp):
    return stamp.sec * 1_000_000_000 + stamp.nanosec


class Adapter:
    """`sim-client ros2 --json` on `world`, its JSON lines kept (to wait
    for one); killed and reaped by `stop`."""

    def __init__(self, world, domain, *args):
        self.proc = subprocess.Popen(
            [os.path.join(BIN, "sim-client"), "--world", world, "ros2", "--json",
             "--domain-id", str(domain), *args],
            stdout=subprocess.PIPE, stderr=subprocess.STDOUT if False else open(os.devnull, "w") if not os.environ.get("ROS2_TEST_LOG") else open(os.environ["ROS2_TEST_LOG"], "a"),
            text=True, start_new_session=True,
        )
        self.lines = []
        self.said = threading.Condition()
        threading.Thread(target=self._read, daemon=True).start()

    def _read(self):
        for line in self.proc.stdout:
            with self.said:
                self.lines.append(json.loads(line))
                self.said.notify_all()

    def wait_event(self, event, timeout=30, **fields):
        def found():
            return next((l for l in self.lines if l.get("event") == event
                         and all(l.get(k) == v for k, v in fields.items())), None)
        with self.said:
            if not self.said.wait_for(found, timeout):
                self.proc.kill()
                raise AssertionError(f"the adapter never said {event}: {self.lines}")
            return found()

    def stop(self):
        """Interrupts it (it prints what it published) and reaps it."""
        self.proc.send_signal(signal.SIGINT)
        try:
            self.proc.wait(timeout=10)
        except subprocess.TimeoutExpired:
            self.proc.kill()
            self.proc.wait()


@pytest.fixture
def ros(request):
    """`ros(world, *ARGS)`: an Adapter on a DDS domain of the test's own,
    and an rclpy node on it (with use_sim_time); all stopped after."""
    started = []
    domain = next(_domains)
    context = rclpy.context.Context()
    rclpy.init(context=context, domain_id=domain)
    node = Node("simbus_test", context=context,
                parameter_overrides=[Parameter("use_sim_time", value=True)])
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(node)

    class Ros:
        def __init__(self):
            self.node, self.domain = node, domain

        def adapter(self, world, *args):
            started.append(Adapter(world, domain, *args))
            started[-1].wait_event("ready")
            return started[-1]

        def spin_until(self, done, timeout=20):
            deadline = time.time() + timeout
            while not done():
                assert time.time() < deadline, "timed out spinning"
                executor.spin_once(timeout_sec=0.05)

        def spin_for(self, seconds):
            executor.spin_once(timeout_sec=seconds)

        def collect(self, msg_type, topic, qos=RELIABLE):
            got = []
            node.create_subscription(msg_type, topic, got.append, qos)
            return got

    yield Ros()
    for a in started:
        a.stop()
    node.destroy_node()
    rclpy.shutdown(context=context)


def wait_matched(ros, topic, publishers=1):
    ros.spin_until(lambda: ros.node.count_publishers(topic) >= publishers)


def frame_ns(client, frame_id):
    """The simulation time of frame `frame_id` (waiting for it)."""
    while True:
        with client.wait_for_frame(timeout=10) as frame:
            if frame.frame >= frame_id:
                assert frame.frame == frame_id
                return frame.elapsed_ns


def test_clock_follows_every_tick_exactly_and_now_is_the_frame_time(server, ros):
    world = server()
    ros.adapter(world.world)
    clock = ros.collect(Clock, "/clock")
    wait_matched(ros, "/clock")
    # Until the adapter's writer has matched this reader too (DDS discovers
    # both ways): a clock of the running (asynchronous) world comes.
    ros.spin_until(lambda: len(clock) > 2)
    # 1 000 ticks from a ticker of its own (sim-client tick, as fast as it
    # goes) while this node spins, as a ROS node would.
    ticker = world.sim_client("tick", "--count", "1000", "--delta-seconds", "0.05",
                              stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    ros.spin_until(lambda: ticker.poll() is not None, timeout=120)
    assert ticker.returncode == 0, ticker.stderr.read()
    # A frame after the ticker's exit (its release leaves synchronous mode:
    # the world runs on): every clock up to it.
    latest = world.client().status().elapsed_ns
    ros.spin_until(lambda: ns(clock[-1].clock) >= latest)
    stamps = [ns(m.clock) for m in clock]
    runs = "".join("t" if b - a == 50_000_000 else "." for a, b in zip(stamps, stamps[1:]))
    # Every tick once, in order, exactly 0.05 s apart (integer ns: no
    # drift): 999 steps of 0.05 s in a row.
    assert "t" * 999 in runs, runs
    assert len(set(stamps)) == len(stamps), "a clock repeated"
    # use_sim_time: the node's now() is a frame's time, to the nanosecond.
    ros.spin_until(lambda: ros.node.get_clock().now().nanoseconds >= latest)
    ros.spin_until(lambda: ros.node.get_clock().now().nanoseconds in {ns(m.clock) for m in clock})


def test_one_ticks_sensors_share_its_stamp_and_carry_simbus_own_bytes(server, ros):
    world = server()
    client = world.client()
    ticker = client.ticker(0.05)
    car = client.spawn("vehicle", at=(0.0, 1.0, 20.0))
    rgb = client.spawn_sensor("rgb", parent=car, at=(0.5, 1.5, 0.0), width=64, height=48, fov=90)
    depth = client.spawn_sensor("depth", parent=car, at=(0.5, 1.5, 0.0), width=64, height=48, fov=90)
    lidar = client.spawn_sensor("lidar", parent=car, at=(0.0, 2.0, 0.0), channels=8, points=90, range=40)
    imu = client.spawn_sensor("imu", parent=car)
    adapter = ros.adapter(world.world)
    for sensor in (rgb, depth, lidar, imu):
        adapter.wait_event("publishing", sensor=sensor.id)
    topic = lambda s, leaf: f"/simbus/sensor_{s.id}/{leaf}"
    got = {
        "rgb": ros.collect(Image, topic(rgb, "image"), qos_profile_sensor_data),
        "depth": ros.collect(Image, topic(depth, "image"), qos_profile_sensor_data),
        "lidar": ros.collect(PointCloud2, topic(lidar, "point_cloud"), qos_profile_sensor_data),
        "imu": ros.collect(Imu, topic(imu, "imu"), qos_profile_sensor_data),
    }
    # Ticks until the adapter's writers have matched this node's readers
    # (DDS discovers both ways; a best-effort sample sent before is lost),
    # then takes a tick whose four messages all came.
    for _ in range(100):
        frame = ticker.tick()
        when = frame_ns(client, frame)
        try:
            ros.spin_until(lambda: all(any(ns(m.header.stamp) == when for m in msgs)
                                       for msgs in got.values()), timeout=1)
            break
        except AssertionError:
            continue
    else:
        raise AssertionError({name: [ns(m.header.stamp) for m in msgs] for name, msgs in got.items()})
    of_frame = {name: next(m for m in msgs if ns(m.header.stamp) == when) for name, msgs in got.items()}
    captures = {}
    for name, sensor in (("rgb", rgb), ("depth", depth), ("lidar", lidar), ("imu", imu)):
        while True:
            capture = sensor.read(timeout=10).copy()
            if capture.frame == frame:
                captures[name] = capture
                break
    image = of_frame["rgb"]
    assert (image.encoding, image.width, image.height, image.step) == ("bgra8", 64, 48, 256)
    assert bytes(image.data) == captures["rgb"].array.tobytes()
    assert image.header.frame_id == f"sensor_{rgb.id}_optical"
    d = of_frame["depth"]
    assert d.encoding == "32FC1"
    assert bytes(d.data) == captures["depth"].array.astype("<f4").tobytes()
    cloud = of_frame["lidar"]
    assert [f.name for f in cloud.fields] == ["x", "y", "z", "intensity"] and cloud.point_step == 16
    points = np.frombuffer(bytes(cloud.data), dtype="<f4").reshape(-1, 4)
    simbus_points = captures["lidar"].array
    assert len(points) == len(simbus_points) > 0
    # simbus's axes (X forward, Y up, Z right) to ROS's (X forward, Y left, Z up).
    np.testing.assert_array_equal(points[:, 0], simbus_points[:, 0])
    np.testing.assert_array_equal(points[:, 1], -simbus_points[:, 2])
    np.testing.assert_array_equal(points[:, 2], simbus_points[:, 1])
    reading = of_frame["imu"]
    measured = captures["imu"].array
    accel, gyro = measured["accelerometer"][0], measured["gyroscope"][0]
    to_ros = lambda v: pytest.approx([v[0], -v[2], v[1]], abs=1e-6)
    a, w = reading.linear_acceleration, reading.angular_velocity
    assert [a.x, a.y, a.z] == to_ros(accel) and [w.x, w.y, w.z] == to_ros(gyro)
    ticker.release()


def actor(frame, actor_id):
    """Actor `actor_id`'s state in `frame`."""
    return next(a for a in frame.actors if a["id"] == actor_id)


def test_a_vehicle_driven_from_ros_accelerates_its_odometry_matches_and_bad_controls_are_dropped(server, ros):
    world = server()
    client = world.client()
    ticker = client.ticker(0.05)
    car = client.spawn("vehicle", at=(0.0, 0.6, 20.0))
    for _ in range(20):  # onto its wheels
        ticker.tick()
    adapter = ros.adapter(world.world, "--vehicles", str(car))
    base = f"/simbus/vehicle_{car}"
    odometry = ros.collect(Odometry, f"{base}/odometry")
    control = ros.node.create_publisher(Float32MultiArray, f"{base}/control", 10)
    ros.spin_until(lambda: control.get_subscription_count() >= 1)
    wait_matched(ros, f"{base}/odometry")
    # Full throttle, until the vehicle is seen moving (the adapter's reader
    # may match this publisher a little after it was seen).
    deadline = time.time() + 30
    while True:
        control.publish(Float32MultiArray(data=[1.0, 0.0, 0.0]))
        ros.spin_for(0.01)  # the node's events, while the adapter matches it
        frame = ticker.tick_and_read(client).copy()
        if np.linalg.norm(actor(frame, car)["linear_velocity"]) > 1.0:
            break
        assert time.time() < deadline, f"the vehicle never moved: {adapter.lines}"
    # Its odometry: the pose in map, the velocity along its own X.
    when = frame.elapsed_ns
    state = actor(frame, car)
    ros.spin_until(lambda: any(ns(m.header.stamp) == when for m in odometry))
    seen = next(m for m in odometry if ns(m.header.stamp) == when)
    assert seen.header.frame_id == "map" and seen.child_frame_id == f"vehicle_{car}"
    speed = float(np.linalg.norm(state["linear_velocity"]))
    v = seen.twist.twist.linear
    # The same velocity, in the vehicle's axes: forward (X) mostly.
    assert float(np.linalg.norm([v.x, v.y, v.z])) == pytest.approx(speed, rel=1e-4)
    assert v.x > 0.9 * speed
    x, y, z = state["position"]
    p = seen.pose.pose.position
    assert (p.x, p.y, p.z) == pytest.approx((x, -z, y), abs=1e-4)
    # Out of range: dropped, counted, named; the vehicle keeps full throttle.
    control.publish(Float32MultiArray(data=[2.0, 0.0, 0.0]))
    ticker.tick()
    dropped = adapter.wait_event("control_dropped", vehicle=car)
    assert "throttle 2" in dropped["reason"] and dropped["dropped"] == 1
    # A foreign publisher of another type on the same topic: DDS never
    # matches it, and the adapter goes on.
    other = rclpy.context.Context()
    rclpy.init(context=other, domain_id=ros.domain)
    stranger = Node("stranger", context=other)
    stranger.create_publisher(String, f"{base}/control", 10).publish(String(data="full throttle"))
    # Not CDR of the message at all: dropped too.
    control.publish(b"\x00\x01\x00\x00\xff\xff\xff\x7f")
    ticker.tick()
    garbled = adapter.wait_event("control_dropped", vehicle=car, dropped=2)
    assert "malformed" in garbled["reason"]
    before = speed
    for _ in range(10):
        frame = ticker.tick_and_read(client).copy()
    assert np.linalg.norm(actor(frame, car)["linear_velocity"]) > before
    stranger.destroy_node()
    rclpy.shutdown(context=other)
    ticker.release()


TICKING_NODE = """
import sys, time, rclpy
from rclpy.node import Node
from std_msgs.msg import Empty
rclpy.init(domain_id=int(sys.argv[1]))
node = Node("ros_ticker")
ticks = node.create_publisher(Empty, sys.argv[2], 10)
print("up", flush=True)
for line in sys.stdin:
    ticks.publish(Empty())
    rclpy.spin_once(node, timeout_sec=0)
    print("sent", flush=True)
"""


def test_a_ros_node_ticks_the_world_a_second_ticker_is_refused_and_killing_the_node_frees_it(server, ros):
    world = server()
    adapter = ros.adapter(world.world, "--tick-from-ros", "--delta-seconds", "0.1")
    assert adapter.wait_event("ready")["ticker"] is True
    clock = ros.collect(Clock, "/clock")
    wait_matched(ros, "/clock")
    node = subprocess.Popen(
        [sys.executable, "-c", TICKING_NODE, str(ros.domain), "/simbus/tick"],
        stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True, start_new_session=True,
    )
    try:
        assert node.stdout.readline() == "up\n"

        def tick():
            node.stdin.write("\n")
            node.stdin.flush()
            assert node.stdout.readline() == "sent\n"

        # Until the adapter's reader has matched the node: a tick that comes.
        for _ in range(10):
            seen = len(clock)
            tick()
            try:
                ros.spin_until(lambda: len(clock) > seen, timeout=0.5)
                break
            except AssertionError:
                continue
        assert clock, (adapter.lines, world.sim_client("status", stdout=subprocess.PIPE, text=True).communicate()[0])
        start = ns(clock[-1].clock)
        for i in range(1, 21):
            tick()
            ros.spin_until(lambda: ns(clock[-1].clock) == start + i * 100_000_000)
        # Exactly one frame per message: twenty ticks, twenty steps of 0.1 s.
        assert ns(clock[-1].clock) == start + 2_000_000_000
        second = world.sim_client("tick", "--count", "1", stdout=subprocess.PIPE,
                                  stderr=subprocess.PIPE, text=True)
        _, err = second.communicate(timeout=60)
        assert second.returncode != 0 and f"ros2-simbus_{world.world}".replace("-", "_") in err.replace("-", "_"), err
    finally:
        node.kill()
        node.wait()
    # The node is gone (killed: DDS notices when its lease runs out).
    assert "left" in adapter.wait_event("ticker_released", timeout=60)["reason"]
    third = world.sim_client("tick", "--count", "1", stdout=subprocess.PIPE,
                             stderr=subprocess.PIPE, text=True)
    out, err = third.communicate(timeout=60)
    assert third.returncode == 0, err
