"""CARLA 0.9.16's own client finds the town's traffic lights and signs as
CARLA's scripts do: as actors (`traffic.traffic_light`, `traffic.stop`,
`traffic.speed_limit.30`) and as the map's landmarks, one to one by their
OpenDRIVE ids; a junction's lights are a group that turns them green in
turn (10 s green, 3 s yellow, 2 s all red: CARLA's times) in simulation
time, identically run after run; `set_state`, the times, `freeze` and
`reset_group` act as in CARLA; and a vehicle in a light's trigger volume
is at that light (`is_at_traffic_light`, `get_traffic_light`), in a stop
sign's sees red without a light (what makes CARLA's traffic manager
stop there)."""

import re

import carla
import pytest

from conftest import synced

TOWN = [["--scene", "town"]]
RED, YELLOW, GREEN = (carla.TrafficLightState.Red, carla.TrafficLightState.Yellow,
                      carla.TrafficLightState.Green)


def tick(world, n=1):
    for _ in range(n):
        frame = world.tick()
    return frame


def lights_by_junction(world, town_map):
    """The lights of each junction, in pole order."""
    groups = {}
    for light in world.get_actors().filter("traffic.traffic_light"):
        group = tuple(sorted(l.id for l in light.get_group_traffic_lights()))
        groups.setdefault(group, []).append(light)
    return [sorted(g, key=lambda l: l.get_pole_index()) for g in groups.values()]


@pytest.mark.parametrize("gateway", TOWN, indirect=True)
def test_the_towns_lights_and_signs_are_actors_and_landmarks_one_to_one(gateway):
    client, world = synced(gateway)
    tick(world)
    town_map = world.get_map()
    lights = world.get_actors().filter("*traffic_light*")
    assert len(lights) == 16
    assert len(world.get_actors().filter("traffic.stop")) == 8
    assert len(world.get_actors().filter("traffic.speed_limit.30")) == 8
    landmarks = town_map.get_all_landmarks_of_type("1000001")
    assert sorted(l.id for l in landmarks) == sorted(l.get_opendrive_id() for l in lights)
    for landmark in landmarks:
        light = world.get_traffic_light(landmark)
        assert light is not None and light.get_opendrive_id() == landmark.id
        # Its trigger volume lies on the lane the landmark speaks to,
        # before the junction.
        trigger = light.get_transform().transform(light.trigger_volume.location)
        lane = town_map.get_waypoint(trigger)
        assert (lane.road_id, lane.lane_id) == (landmark.road_id, landmark.get_lane_validities()[0][0])
        assert not lane.is_junction
        assert len(light.get_stop_waypoints()) == 1
        affected = light.get_affected_lane_waypoints()
        assert [(w.road_id, w.lane_id) for w in affected] == [(landmark.road_id, lane.lane_id)]
        assert len(light.get_light_boxes()) == 1
    assert len(town_map.get_all_landmarks_of_type("206")) == 8
    limits = town_map.get_all_landmarks_of_type("274")
    assert len(limits) == 8 and {l.value for l in limits} == {30.0}
    # Four junctions of four lights; each junction's lights are its
    # group, and the junction lists them.
    groups = lights_by_junction(world, town_map)
    assert sorted(len(g) for g in groups) == [4, 4, 4, 4]
    for group in groups:
        assert [l.get_pole_index() for l in group] == [0, 1, 2, 3]
        lane = town_map.get_waypoint(group[0].get_transform().transform(
            group[0].trigger_volume.location))
        junction = lane.next(10.0)[0].get_junction()
        found = world.get_traffic_lights_in_junction(junction.id)
        assert sorted(l.id for l in found) == sorted(l.id for l in group)


@pytest.mark.parametrize("gateway", TOWN, indirect=True)
def test_a_junctions_lights_take_turns_in_simulation_time_the_same_every_run(gateway):
    client, world = synced(gateway)

    def run(frames):
        groups = lights_by_junction(world, world.get_map())
        states = []
        for _ in range(frames):
            tick(world)
            seconds = round(world.get_snapshot().timestamp.elapsed_seconds, 3)
            states.append((seconds, tuple(l.state for g in groups for l in g)))
        return groups, states

    # A reload starts every cycle at the episode's start (the world ran
    # asynchronously, lights and all, before the script took it).
    world = client.reload_world(False)
    groups, first = run(1200)
    group = groups[0]
    # From the episode's start: pole 0 green for 10 s, yellow for 3 s,
    # then all red for 2 s, then pole 1 green.
    by_time = dict(first)

    def at(seconds):
        return by_time[round(seconds, 3)][:4]
    assert at(0.1) == (GREEN, RED, RED, RED)
    assert at(9.95) == (GREEN, RED, RED, RED)
    assert at(10.0) == (YELLOW, RED, RED, RED)
    assert at(13.0) == (RED, RED, RED, RED)
    assert at(15.0) == (RED, GREEN, RED, RED)
    assert at(45.0) == (RED, RED, RED, GREEN)
    assert at(60.0) == (GREEN, RED, RED, RED)
    assert [round(t, 3) for t in (group[0].get_green_time(), group[0].get_yellow_time(),
                                  group[0].get_red_time())] == [10.0, 3.0, 2.0]
    # Again: the same states, frame by frame.
    world = client.reload_world(False)
    _, second = run(1200)
    assert second == first

    # Scripts' calls: a state shown holds until the cycle reaches the
    # light; frozen, it holds; a reset starts the group again.
    groups = lights_by_junction(world, world.get_map())
    light = groups[0][2]
    light.set_state(GREEN)
    tick(world)
    assert light.state == GREEN and light.get_elapsed_time() == 0.0
    light.freeze(True)
    tick(world, 400)
    assert light.is_frozen() and light.state == GREEN
    assert all(l.is_frozen() for g in groups for l in g)
    light.reset_group()
    tick(world)
    assert [l.state for l in groups[0]] == [GREEN, RED, RED, RED]
    world.freeze_all_traffic_lights(False)
    light.set_green_time(1.0)
    groups[0][0].set_green_time(0.5)
    tick(world, 10)
    assert groups[0][0].state == YELLOW
    assert round(groups[0][0].get_green_time(), 3) == 0.5
    world.reset_all_traffic_lights()
    tick(world)
    assert [l.state for l in groups[0]] == [GREEN, RED, RED, RED]


@pytest.mark.parametrize("gateway", TOWN, indirect=True)
def test_a_vehicle_in_a_lights_trigger_volume_is_at_that_light_and_at_a_stop_sees_red(gateway):
    client, world = synced(gateway)
    tick(world)
    town_map = world.get_map()
    library = world.get_blueprint_library()
    light = lights_by_junction(world, town_map)[0][0]
    trigger = town_map.get_waypoint(light.get_transform().transform(
        light.trigger_volume.location))
    car = world.spawn_actor(library.find("vehicle.tesla.model3"),
                            carla.Transform(trigger.transform.location + carla.Location(z=0.5),
                                            trigger.transform.rotation))
    tick(world, 5)
    assert car.is_at_traffic_light()
    assert car.get_traffic_light().id == light.id
    assert car.get_traffic_light_state() == light.state == GREEN
    assert car.get_speed_limit() == 30.0
    light.set_state(RED)
    light.freeze(True)
    tick(world)
    assert car.get_traffic_light_state() == RED

    # Well back from the junction: at no light, green (CARLA's state away
    # from one).
    back = trigger.previous(25.0)[0].transform
    car.set_transform(carla.Transform(back.location + carla.Location(z=0.5), back.rotation))
    tick(world, 5)
    assert not car.is_at_traffic_light()
    assert car.get_traffic_light() is None
    assert car.get_traffic_light_state() == GREEN

    # At a stop sign: red, and no light.
    stop = world.get_actors().filter("traffic.stop")[0]
    at_stop = town_map.get_waypoint(stop.get_transform().transform(
        stop.trigger_volume.location)).transform
    car.set_transform(carla.Transform(at_stop.location + carla.Location(z=0.5), at_stop.rotation))
    tick(world, 5)
    assert not car.is_at_traffic_light()
    assert car.get_traffic_light_state() == RED


@pytest.mark.parametrize("gateway", TOWN, indirect=True)
def test_a_recording_lists_the_lights_state_changes_as_carlas_file_info(gateway, tmp_path):
    """`show_recorder_file_info(name, True)` on a recording of the town:
    the first frame lists every light's state (CARLA's `State traffic
    lights: N`, then `Id: .. state: .. frozen: .. elapsedTime: ..`, the
    state as CARLA's digit: 0 red, 1 yellow, 2 green), and later frames
    only the lights that changed: 10 s in, the first green ones turn
    yellow."""
    client, world = synced(gateway)
    path = str(tmp_path / "lights.log")
    client.start_recorder(path)
    for _ in range(240):
        world.tick()
    client.stop_recorder()
    info = client.show_recorder_file_info(path, True)
    blocks = re.findall(r"^ State traffic lights: (\d+)\n((?:  Id: .*\n)+)", info, re.M)
    assert blocks, info[:2000]
    first_count, first = blocks[0]
    rows = re.findall(r"^  Id: (\d+) state: (\d) frozen: (\d) elapsedTime: (\S+)$", first, re.M)
    assert int(first_count) == len(rows) == 16
    assert {state for _, state, _, _ in rows} == {"0", "2"}, "green in turn, the others red"
    later = [re.findall(r"state: (\d)", rows) for _, rows in blocks[1:]]
    assert any("1" in states for states in later), "a green light turned yellow"
    assert all(0 < len(states) < 16 for states in later), "only the lights that changed"
