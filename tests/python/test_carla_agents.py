"""CARLA's `BehaviorAgent` (PythonAPI/carla/agents, as
`automatic_control.py --agent Behavior` drives with it), mirrored: its
traffic-light manager and its pedestrian manager make their calls in their
order with their arguments (`world.get_actors().filter("*traffic_light*")`,
the light's trigger volume through `get_trafficlight_trigger_location`,
`map.get_waypoint`, road ids and headings, `is_within_distance`; walkers
from `filter("*walker.pedestrian*")`, their lane from
`get_waypoint(..., lane_type=Any)`), and its emergency stop. A plain
lane-following controller stands in for its local planner. On simbus's
town the agent stops at a red light and goes on green, and brakes for a
walker on its lane."""

import math

import carla
import numpy as np
import pytest

from conftest import synced

TOWN = [["--scene", "town"]]


def trigger_location(light):
    """agents.tools.misc.get_trafficlight_trigger_location."""
    def rotate_point(point, radians):
        rotated_x = math.cos(radians) * point.x - math.sin(radians) * point.y
        rotated_y = math.sin(radians) * point.x - math.cos(radians) * point.y
        return carla.Vector3D(rotated_x, rotated_y, point.z)

    base_transform = light.get_transform()
    base_rot = base_transform.rotation.yaw
    area_loc = base_transform.transform(light.trigger_volume.location)
    area_ext = light.trigger_volume.extent
    point = rotate_point(carla.Vector3D(0, 0, area_ext.z), math.radians(base_rot))
    point_location = area_loc + carla.Location(x=point.x, y=point.y)
    return carla.Location(point_location.x, point_location.y, point_location.z)


def within(target, reference, max_distance, angles):
    """agents.tools.misc.is_within_distance."""
    v = np.array([target.location.x - reference.location.x,
                  target.location.y - reference.location.y])
    norm = np.linalg.norm(v)
    if norm < 0.001:
        return True
    if norm > max_distance:
        return False
    forward = reference.get_forward_vector()
    f = np.array([forward.x, forward.y])
    angle = math.degrees(math.acos(np.clip(np.dot(f, v) / norm, -1.0, 1.0)))
    return angles[0] < angle < angles[1]


class Agent:
    """The BehaviorAgent's managers for lights and walkers (behavior
    "normal": braking distance 6 m, proximity 10 m), over a lane follower."""

    def __init__(self, vehicle):
        self.vehicle = vehicle
        self.world = vehicle.get_world()
        self.map = self.world.get_map()
        self.lights_map = {}
        self.last_light = None

    def affected_by_traffic_light(self, lights, max_distance=5.0):
        if self.last_light:
            if self.last_light.state != carla.TrafficLightState.Red:
                self.last_light = None
            else:
                return True
        ego_location = self.vehicle.get_location()
        ego_wp = self.map.get_waypoint(ego_location)
        for light in lights:
            if light.id not in self.lights_map:
                self.lights_map[light.id] = self.map.get_waypoint(trigger_location(light))
            trigger_wp = self.lights_map[light.id]
            if trigger_wp.transform.location.distance(ego_location) > max_distance:
                continue
            if trigger_wp.road_id != ego_wp.road_id:
                continue
            ve = ego_wp.transform.get_forward_vector()
            wp = trigger_wp.transform.get_forward_vector()
            if ve.x * wp.x + ve.y * wp.y + ve.z * wp.z < 0:
                continue
            if light.state != carla.TrafficLightState.Red:
                continue
            if within(trigger_wp.transform, self.vehicle.get_transform(), max_distance, [0, 90]):
                self.last_light = light
                return True
        return False

    def walker_ahead(self, waypoint):
        walkers = self.world.get_actors().filter("*walker.pedestrian*")
        walkers = [w for w in walkers if w.get_location().distance(waypoint.transform.location) < 10]
        max_distance = max(10.0, self.vehicle.get_speed_limit() / 3)
        ego_transform = self.vehicle.get_transform()
        ego_wpt = self.map.get_waypoint(ego_transform.location)
        extent = self.vehicle.bounding_box.extent
        ego_front = carla.Transform(
            ego_transform.location + carla.Location(extent.x * ego_transform.get_forward_vector()),
            ego_transform.rotation)
        for walker in walkers:
            target = walker.get_transform()
            if target.location.distance(ego_transform.location) > max_distance:
                continue
            target_wpt = self.map.get_waypoint(target.location, lane_type=carla.LaneType.Any)
            if target_wpt.road_id != ego_wpt.road_id or target_wpt.lane_id != ego_wpt.lane_id:
                continue
            rear = carla.Transform(
                target.location - carla.Location(walker.bounding_box.extent.x * target.get_forward_vector()),
                target.rotation)
            if within(rear, ego_front, max_distance, [0, 60]):
                distance = walker.get_location().distance(ego_transform.location)
                return walker, distance
        return None, -1

    def run_step(self):
        """BehaviorAgent.run_step's order: lights, walkers, then drive."""
        location = self.vehicle.get_location()
        waypoint = self.map.get_waypoint(location)
        if self.affected_by_traffic_light(self.world.get_actors().filter("*traffic_light*")):
            return "light", carla.VehicleControl(throttle=0.0, brake=1.0)
        walker, distance = self.walker_ahead(waypoint)
        if walker is not None:
            gap = (distance - max(walker.bounding_box.extent.y, walker.bounding_box.extent.x)
                   - max(self.vehicle.bounding_box.extent.y, self.vehicle.bounding_box.extent.x))
            if gap < 6.0:
                return "walker", carla.VehicleControl(throttle=0.0, brake=1.0)
        # A lane follower at the speed limit (in place of the local planner).
        target = waypoint.next(5.0)[0].transform.location
        transform = self.vehicle.get_transform()
        heading = math.radians(transform.rotation.yaw)
        wanted = math.atan2(target.y - location.y, target.x - location.x)
        error = (wanted - heading + math.pi) % (2 * math.pi) - math.pi
        v = self.vehicle.get_velocity()
        speed = math.hypot(v.x, v.y)
        limit = self.vehicle.get_speed_limit() / 3.6
        throttle = min(max(0.8 * (limit - speed) + 0.2, 0.0), 0.75)
        brake = 0.3 if speed > limit + 1.0 else 0.0
        return "drive", carla.VehicleControl(throttle=throttle, steer=max(-1.0, min(1.0, 1.5 * error)),
                                             brake=brake)


def speed_of(actor):
    v = actor.get_velocity()
    return math.hypot(v.x, v.y)


def approach(world, metres):
    """A light, its stop waypoint, and the waypoint `metres` before it on
    its lane (the same road)."""
    town = world.get_map()
    for light in world.get_actors().filter("*traffic_light*"):
        for stop in light.get_stop_waypoints():
            back = stop.previous(metres)
            if back and back[0].road_id == stop.road_id:
                return light, stop, back[0]
    raise AssertionError("no light with a straight approach")


@pytest.mark.parametrize("gateway", TOWN, indirect=True)
def test_the_behavior_agent_stops_at_a_red_light_and_goes_on_green(gateway):
    client, world = synced(gateway)
    light, stop, start = approach(world, 35.0)
    world.freeze_all_traffic_lights(True)
    light.set_state(carla.TrafficLightState.Red)
    spawn = carla.Transform(start.transform.location + carla.Location(z=0.5), start.transform.rotation)
    car = world.spawn_actor(world.get_blueprint_library().find("vehicle.tesla.model3"), spawn)
    agent = Agent(car)
    stopped_at = None
    for _ in range(400):
        world.tick()
        why, control = agent.run_step()
        car.apply_control(control)
        if why == "light" and speed_of(car) < 0.05:
            stopped_at = car.get_location().distance(stop.transform.location)
            break
    assert stopped_at is not None, "the agent never stopped for the red light"
    # Before the stop line, and at the light (its trigger volume).
    assert 1.0 < stopped_at < 12.0, stopped_at
    for _ in range(40):
        world.tick()
        car.apply_control(agent.run_step()[1])
    assert speed_of(car) < 0.05 and car.is_at_traffic_light()
    assert car.get_traffic_light_state() == carla.TrafficLightState.Red
    light.set_state(carla.TrafficLightState.Green)
    start_location = car.get_location()
    for _ in range(200):
        world.tick()
        car.apply_control(agent.run_step()[1])
    assert car.get_location().distance(start_location) > 15.0, "it went on green"


@pytest.mark.parametrize("gateway", TOWN, indirect=True)
def test_the_behavior_agent_brakes_for_a_walker_on_its_lane(gateway):
    client, world = synced(gateway)
    world.freeze_all_traffic_lights(True)
    for light in world.get_actors().filter("*traffic_light*"):
        light.set_state(carla.TrafficLightState.Green)
    light, stop, start = approach(world, 45.0)
    library = world.get_blueprint_library()
    spawn = carla.Transform(start.transform.location + carla.Location(z=0.5), start.transform.rotation)
    car = world.spawn_actor(library.find("vehicle.tesla.model3"), spawn)
    ahead = start.next(25.0)[0]
    walker = world.spawn_actor(library.find("walker.pedestrian.0001"), carla.Transform(
        ahead.transform.location + carla.Location(z=1.0), ahead.transform.rotation))
    agent = Agent(car)
    braked, closest = False, float("inf")
    for _ in range(300):
        world.tick()
        why, control = agent.run_step()
        car.apply_control(control)
        braked |= why == "walker"
        closest = min(closest, car.get_location().distance(walker.get_location()))
    assert braked, "the agent saw the walker"
    assert speed_of(car) < 0.05, "and stopped for it"
    # Stopped short of it: more than the car's half length and the walker's
    # radius apart.
    assert closest > car.bounding_box.extent.x + walker.bounding_box.extent.x + 0.5, closest
