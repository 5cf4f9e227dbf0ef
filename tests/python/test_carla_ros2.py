"""CARLA's native ROS 2 through the gateway (`carla-gateway --ros2`, as
CARLA's server `--ros2`), read by a stock rclpy: the calls of CARLA 0.9.16's
PythonAPI/examples/ros2/ros2_native.py with its stack.json (a `hero`
vehicle, an RGB camera, a lidar, a GNSS and an IMU named by `ros_name`,
each `enable_for_ros()`), and the topics CARLA publishes for them, each
message stamped with its frame's simulation time."""

import os
import time

import carla
import pytest

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import rclpy  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy, DurabilityPolicy  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import CameraInfo, Image, Imu, NavSatFix, PointCloud2  # noqa: E402

pytestmark = pytest.mark.filterwarnings("ignore::DeprecationWarning")  # rclpy's lark

# A domain of this file's own (215..232: the Rust tests' range, never run
# at the same time as the Python groups; test_ros2.py takes 1..101).
DOMAIN = 215 + os.getpid() % 18
# CARLA's writers are reliable and transient local, as rviz2 reads them.
QOS = QoSProfile(depth=10, reliability=ReliabilityPolicy.RELIABLE,
                 durability=DurabilityPolicy.TRANSIENT_LOCAL)

# stack.json's sensors: (blueprint, ros_name, attributes, x, y, z, pitch).
STACK = [
    ("sensor.camera.rgb", "rgb", {"image_size_x": "600", "image_size_y": "400", "fov": "90.0"},
     -4.5, 0.0, 2.5, 20.0),
    ("sensor.lidar.ray_cast", "lidar", {"range": "85", "channels": "64", "points_per_second": "600000",
                                        "rotation_frequency": "20", "upper_fov": "10", "lower_fov": "-30"},
     0.0, 0.0, 2.4, 0.0),
    ("sensor.other.gnss", "gnss", {"noise_alt_stddev": "0.0"}, 1.0, 0.0, 2.0, 0.0),
    ("sensor.other.imu", "imu", {"noise_accel_stddev_x": "0.0"}, 2.0, 0.0, 2.0, 0.0),
]
TOPICS = {
    "/carla/hero/rgb/image": Image,
    "/carla/hero/rgb/camera_info": CameraInfo,
    "/carla/hero/lidar/point_cloud": PointCloud2,
    "/carla/hero/gnss": NavSatFix,
    "/carla/hero/imu": Imu,
}


@pytest.mark.parametrize(
    "gateway", [{"server": ["--scene", "town"], "gateway": ["--ros2", "--ros-domain-id", str(DOMAIN)]}],
    indirect=True)
def test_ros2_native_calls_publish_carla_topics_on_frame_stamps(gateway):
    context = rclpy.context.Context()
    rclpy.init(context=context, domain_id=DOMAIN)
    node = Node("ros2_native_reader", context=context)
    executor = rclpy.executors.SingleThreadedExecutor(context=context)
    executor.add_node(node)
    got = {topic: [] for topic in TOPICS}
    for topic, kind in TOPICS.items():
        node.create_subscription(kind, topic, got[topic].append, QOS)
    clock = []
    node.create_subscription(Clock, "/clock", clock.append, QOS)
    try:
        client = gateway.client()
        world = client.get_world()
        original = world.get_settings()
        settings = world.get_settings()
        settings.synchronous_mode = True
        settings.fixed_delta_seconds = 0.05
        world.apply_settings(settings)
        client.get_trafficmanager().set_synchronous_mode(True)
        library = world.get_blueprint_library()
        bp = library.filter("vehicle.lincoln.mkz_2017")[0]
        bp.set_attribute("role_name", "hero")
        bp.set_attribute("ros_name", "hero")
        vehicle = world.spawn_actor(bp, world.get_map().get_spawn_points()[0], attach_to=None)
        sensors = []
        for type_id, name, attributes, x, y, z, pitch in STACK:
            sbp = library.filter(type_id)[0]
            sbp.set_attribute("ros_name", name)
            sbp.set_attribute("role_name", name)
            for key, value in attributes.items():
                sbp.set_attribute(key, value)
            where = carla.Transform(carla.Location(x=x, y=-y, z=z), carla.Rotation(pitch=-pitch))
            sensors.append(world.spawn_actor(sbp, where, attach_to=vehicle))
            assert not sensors[-1].is_enabled_for_ros()
            sensors[-1].enable_for_ros()
            assert sensors[-1].is_enabled_for_ros()
        world.tick()
        vehicle.set_autopilot(True)
        # Ticks until every topic has a message of the frame just ticked
        # (DDS matches this reader in its own time; CARLA's writers keep
        # the last message, so a late reader gets the newest).
        def on_frame(elapsed):
            # /clock too: its reader may match later than the sensors' (DDS
            # discovery in its own time; a loaded machine once saw none yet).
            latest = {t: m[-1].header.stamp for t, m in got.items() if m}
            on_stamp = len(latest) == len(TOPICS) and all(
                abs(s.sec + s.nanosec * 1e-9 - elapsed) < 1e-6 for s in latest.values())
            return on_stamp and any(abs(m.clock.sec + m.clock.nanosec * 1e-9 - elapsed) < 1e-6 for m in clock)

        for _ in range(50):
            world.tick()
            elapsed = world.get_snapshot().timestamp.elapsed_seconds
            deadline = time.time() + 2
            while not on_frame(elapsed) and time.time() < deadline:
                executor.spin_once(timeout_sec=0.05)
            if on_frame(elapsed):
                break
        else:
            raise AssertionError("not every topic came on one frame's stamp: "
                                 f"{ {t: m[-1].header.stamp for t, m in got.items() if m} }")
        image = got["/carla/hero/rgb/image"][-1]
        assert (image.width, image.height, image.encoding) == (600, 400, "bgra8")
        assert image.header.frame_id == "rgb"
        info = got["/carla/hero/rgb/camera_info"][-1]
        assert info.k[0] == pytest.approx(300.0) and info.k[2] == pytest.approx(300.0)
        cloud = got["/carla/hero/lidar/point_cloud"][-1]
        assert [f.name for f in cloud.fields] == ["x", "y", "z", "intensity"] and cloud.width > 0
        assert got["/carla/hero/gnss"][-1].header.frame_id == "gnss"
        assert clock and any(abs(m.clock.sec + m.clock.nanosec * 1e-9 - elapsed) < 1e-6 for m in clock)
        # disable_for_ros(): the sensor's topic goes quiet.
        sensors[0].disable_for_ros()
        assert not sensors[0].is_enabled_for_ros()
        world.apply_settings(original)
        for sensor in sensors:
            sensor.destroy()
        vehicle.destroy()
    finally:
        node.destroy_node()
        rclpy.shutdown(context=context)
