"""`sensor.other.lane_invasion` through the gateway, with the real
`carla==0.9.16` client. In CARLA 0.9.16 this sensor is computed by the
client: on every world state it moves its parent's bounding-box corners
and asks the map (built from the OpenDRIVE the gateway serves) which lane
marks they crossed. The gateway lists the blueprint and keeps the sensor
as a pose-only actor on its parent; simbus has no sensor behind it."""

import carla
import pytest

from test_carla_actors_sensors import Raw, sync

TOWN = [["--scene", "town"]]


def car_with_lane_sensor(gateway):
    """The gateway's world, synchronous, and in it a model3 held still (no
    physics) on the town's first spawn point with a listening
    lane-invasion sensor; returns (world, car, sensor, the spawn point, its
    waypoint, the events heard)."""
    world = gateway.client().get_world()
    sync(world)
    town = world.get_map()
    library = world.get_blueprint_library()
    at = town.get_spawn_points()[0]
    car = world.spawn_actor(library.find("vehicle.tesla.model3"), at)
    car.set_simulate_physics(False)
    sensor = world.spawn_actor(library.find("sensor.other.lane_invasion"), carla.Transform(), attach_to=car)
    events = []
    sensor.listen(events.append)
    world.tick()
    return world, car, sensor, at, town.get_waypoint(at.location), events


@pytest.mark.parametrize("gateway", TOWN, indirect=True)
def test_crossing_the_centre_mark_fires_once_with_its_type(gateway):
    world, car, sensor, start, lane, events = car_with_lane_sensor(gateway)
    assert isinstance(sensor, carla.LaneInvasionSensor)
    assert sensor.type_id == "sensor.other.lane_invasion" and sensor.parent.id == car.id
    assert sensor.is_alive
    mark = lane.left_lane_marking
    assert (mark.type, mark.color) == (carla.LaneMarkingType.Solid, carla.LaneMarkingColor.Yellow)
    forward, right = start.get_forward_vector(), start.get_right_vector()
    # Along its lane: 10 ticks, 0.3 m each, no mark crossed.
    for step in range(1, 11):
        car.set_transform(carla.Transform(start.location + forward * (0.3 * step), start.rotation))
        world.tick()
    assert events == []
    # One move across the centre mark into the other lane: every corner
    # crosses it in the same tick.
    along = start.location + forward * 3.0
    car.set_transform(carla.Transform(along - right * lane.lane_width, start.rotation))
    crossed_at = world.tick()
    for _ in range(5):
        world.tick()
    assert [e.frame for e in events] == [crossed_at]
    (event,) = events
    assert len(event.crossed_lane_markings) == 4, "one crossing per corner"
    assert {(m.type, m.color) for m in event.crossed_lane_markings} == {
        (carla.LaneMarkingType.Solid, carla.LaneMarkingColor.Yellow)}
    sensor.stop()
    assert sensor.destroy()
    world.tick()
    assert sensor.id not in [a.id for a in world.get_actors()]
    assert car.destroy()


@pytest.mark.parametrize("gateway", TOWN, indirect=True)
def test_a_lane_sensor_goes_with_its_car_and_attaches_to_no_sensor(gateway):
    world, car, sensor, _, _, _ = car_with_lane_sensor(gateway)
    library = world.get_blueprint_library()
    with pytest.raises(RuntimeError, match="sensor"):
        world.spawn_actor(library.find("sensor.other.lane_invasion"), carla.Transform(), attach_to=sensor)
    # An actor the world does not have: refused, nothing spawned.
    before = len(world.get_actors())
    raw = Raw(gateway.port)
    answer = raw.call("spawn_actor_with_parent", [9, "sensor.other.lane_invasion", []],
                      [[0, 0, 0], [0, 0, 0]], 987654, 0)
    assert "987654" in str(answer), answer
    world.tick()
    assert len(world.get_actors()) == before
    sensor.stop()
    assert car.destroy()
    world.tick()
    assert not sensor.is_alive
    assert sensor.destroy()
    world.tick()
    assert sensor.id not in [a.id for a in world.get_actors()]
