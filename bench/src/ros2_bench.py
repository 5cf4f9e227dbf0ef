"""The rclpy side of `simbus-bench ros2` (ROS 2 Kilted's wheels):

  sub DOMAIN KIND TOPIC... : subscribe (KIND clock: reliable, depth 5000;
      image: sensor data, best effort; image_reliable: reliable, depth 100), print "ready" once every topic has
      a publisher, then record (topic, stamp ns, wall ns at the callback)
      until stdin closes; print them as one JSON line.
  pub DOMAIN KIND TOPIC COUNT PERIOD : the floor, rclpy to rclpy: publish
      COUNT messages of KIND (a Clock, or an 800x600 bgra8 Image), each
      stamped with the wall time it is published, PERIOD s apart, once a
      subscriber is there; print "done".
"""

import json
import os
import sys
import threading
import time

os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import rclpy  # noqa: E402
from rclpy.executors import SingleThreadedExecutor  # noqa: E402
from rclpy.node import Node  # noqa: E402
from rclpy.qos import QoSProfile, ReliabilityPolicy, qos_profile_sensor_data  # noqa: E402
from rosgraph_msgs.msg import Clock  # noqa: E402
from sensor_msgs.msg import Image  # noqa: E402

CLOCK_QOS = QoSProfile(depth=5000, reliability=ReliabilityPolicy.RELIABLE)


IMAGE_RELIABLE = QoSProfile(depth=100, reliability=ReliabilityPolicy.RELIABLE)


def kind_of(kind):
    if kind == "clock":
        return Clock, CLOCK_QOS
    return Image, IMAGE_RELIABLE if kind == "image_reliable" else qos_profile_sensor_data


def stamp_of(message):
    t = message.clock if isinstance(message, Clock) else message.header.stamp
    return t.sec * 1_000_000_000 + t.nanosec


def sub(domain, kind, topics):
    rclpy.init(domain_id=domain)
    node = Node("simbus_bench_sub")
    msg_type, qos = kind_of(kind)
    seen = []
    for i, topic in enumerate(topics):
        node.create_subscription(
            msg_type, topic, lambda m, i=i: seen.append((i, stamp_of(m), time.time_ns())), qos)
    executor = SingleThreadedExecutor()
    executor.add_node(node)
    while not all(node.count_publishers(t) for t in topics):
        executor.spin_once(timeout_sec=0.05)
    print("ready", flush=True)
    done = threading.Event()
    threading.Thread(target=lambda: (sys.stdin.read(), done.set()), daemon=True).start()
    while not done.is_set():
        executor.spin_once(timeout_sec=0.01)
    # What is still on its way (a reliable writer's repairs too): until
    # a second passes with nothing new.
    quiet = time.time()
    while time.time() - quiet < 1.0:
        before = len(seen)
        executor.spin_once(timeout_sec=0.01)
        if len(seen) != before:
            quiet = time.time()
    print(json.dumps({"samples": seen}), flush=True)


def pub(domain, kind, topic, count, period):
    rclpy.init(domain_id=domain)
    node = Node("simbus_bench_pub")
    msg_type, qos = kind_of(kind)
    publisher = node.create_publisher(msg_type, topic, qos)
    while publisher.get_subscription_count() == 0:
        rclpy.spin_once(node, timeout_sec=0.05)
    time.sleep(1.0)  # the subscriber's side of the match
    image = None
    if kind != "clock":
        image = Image(height=600, width=800, encoding="bgra8", step=3200, data=bytes(800 * 600 * 4))
    for _ in range(count):
        now = time.time_ns()
        t = (now // 1_000_000_000, now % 1_000_000_000)
        if image is None:
            message = Clock()
            message.clock.sec, message.clock.nanosec = t
        else:
            message = image
            message.header.stamp.sec, message.header.stamp.nanosec = t
        publisher.publish(message)
        time.sleep(period)
    print("done", flush=True)


if __name__ == "__main__":
    mode, domain, kind = sys.argv[1], int(sys.argv[2]), sys.argv[3]
    if mode == "sub":
        sub(domain, kind, sys.argv[4:])
    else:
        pub(domain, kind, sys.argv[4], int(sys.argv[5]), float(sys.argv[6]))
