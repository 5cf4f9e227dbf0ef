"""Roads and maps through the gateway, read by CARLA 0.9.16's own client:
the town's OpenDRIVE and spawn points (CARLA's client computes waypoints,
junctions and topology from them itself, as against CARLA), CARLA's towns
loaded as simbus's town (or refused with --strict-maps), worlds built on an
OpenDRIVE a script sends, and the default scene's ring road, on its ground
and clear of its bodies."""

import subprocess
import sys

import carla
import pytest

from conftest import kill_all, start, wait_line, world_name

TOWN = [["--scene", "town"]]

# A straight two-lane road, 100 m long, as a script would send it.
SMALL_XODR = """<?xml version="1.0" standalone="yes"?>
<OpenDRIVE>
  <header revMajor="1" revMinor="4" name="straight" version="1" north="0" south="0" east="0" west="0">
    <geoReference><![CDATA[+proj=tmerc +lat_0=0 +lon_0=0]]></geoReference>
  </header>
  <road name="straight" length="100.0" id="0" junction="-1">
    <link/>
    <planView><geometry s="0.0" x="0.0" y="0.0" hdg="0.0" length="100.0"><line/></geometry></planView>
    <lanes>
      <laneSection s="0.0">
        <left><lane id="1" type="driving" level="false"><link/><width sOffset="0.0" a="3.5" b="0" c="0" d="0"/></lane></left>
        <center><lane id="0" type="none" level="false"><link/></lane></center>
        <right><lane id="-1" type="driving" level="false"><link/><width sOffset="0.0" a="3.5" b="0" c="0" d="0"/></lane></right>
      </laneSection>
    </lanes>
  </road>
</OpenDRIVE>
"""


def start_logged(request, server_args, gateway_args, procs):
    """A sim-server and a gateway (with `gateway_args`, logging at info
    level into its stdout, for `wait_line`) on a world of this test's."""
    gateway = start(world_name(request), server_args, procs, gateway_args, log=subprocess.STDOUT,
                    env={"RUST_LOG": "simbus_carla=info", "NO_COLOR": "1"})
    return gateway, gateway.proc


@pytest.fixture
def logged(request):
    """A server on the default scene and a gateway whose log the test reads."""
    procs = []
    try:
        yield start_logged(request, [], getattr(request, "param", []), procs)
    finally:
        kill_all(procs)


def follow(waypoint, metres, step=2.0):
    """Follows the road from `waypoint` for `metres`, taking each fork in
    turn; the waypoints passed."""
    passed = [waypoint]
    for i in range(int(metres / step)):
        nexts = waypoint.next(step)
        assert nexts, f"a dead end at road {waypoint.road_id} lane {waypoint.lane_id} s {waypoint.s}"
        waypoint = nexts[i % len(nexts)]
        passed.append(waypoint)
    return passed


@pytest.mark.parametrize("gateway", TOWN, indirect=True)
def test_the_town_has_spawn_points_on_its_lanes_and_roads_across_junctions(gateway):
    town = gateway.client().get_world().get_map()
    assert town.name == "town"
    points = town.get_spawn_points()
    assert len(points) >= 100, len(points)
    for p in points:
        waypoint = town.get_waypoint(p.location, project_to_road=True, lane_type=carla.LaneType.Driving)
        assert waypoint is not None, p
        assert waypoint.lane_type == carla.LaneType.Driving
        assert waypoint.transform.location.distance(p.location) < 0.5 + 0.05, (p, waypoint.transform)
        turn = (waypoint.transform.rotation.yaw - p.rotation.yaw + 540.0) % 360.0 - 180.0
        assert abs(turn) < 1.0, (p, waypoint.transform)
    # Following the road from a few spawn points: on a driving lane all the
    # way, through junctions.
    for p in points[::37]:
        passed = follow(town.get_waypoint(p.location), 400.0)
        assert all(w.lane_type == carla.LaneType.Driving for w in passed)
        assert any(w.is_junction for w in passed), p
        junction = next(w for w in passed if w.is_junction).get_junction()
        assert junction is not None and junction.bounding_box.extent.x > 0.0
    assert len(town.generate_waypoints(2.0)) > 1000
    topology = town.get_topology()
    assert len(topology) > 100
    assert all(a.lane_type == b.lane_type == carla.LaneType.Driving for a, b in topology)


def test_the_default_scene_s_roads_stay_on_its_ground_and_clear_of_its_bodies(gateway):
    world = gateway.client().get_world()
    points = world.get_map().get_spawn_points()
    assert len(points) >= 8, len(points)
    bodies = [a.get_location() for a in world.get_actors() if a.type_id != "spectator"]
    assert len(bodies) > 5
    for p in points:
        assert abs(p.location.x) < 50.0 and abs(p.location.y) < 50.0, p
        assert all(p.location.distance(b) > 3.0 for b in bodies), p
    # The ring road leads on around the scene.
    passed = follow(world.get_map().get_waypoint(points[0].location), 300.0)
    assert all(abs(w.transform.location.x) < 45.0 for w in passed)


def test_the_map_has_a_geo_reference_so_carla_s_client_does_not_warn(gateway):
    script = (
        "import carla, sys\n"
        f"client = carla.Client('127.0.0.1', {gateway.port}); client.set_timeout(10.0)\n"
        "m = client.get_world().get_map()\n"
        "print(len(m.get_spawn_points()), m.transform_to_geolocation(carla.Location()).latitude)\n"
    )
    run = subprocess.run([sys.executable, "-c", script], capture_output=True, text=True, timeout=60)
    assert run.returncode == 0, run.stderr
    count, latitude = run.stdout.split()
    assert int(count) > 0 and float(latitude) == 0.0
    assert "georeference" not in run.stderr.lower(), run.stderr


def test_carla_s_towns_load_simbus_s_town_and_say_so(logged):
    gateway, log = logged
    client = gateway.client()
    assert "town" in client.get_available_maps()
    world = client.load_world("Town10HD_Opt")
    assert world.get_map().name == "simbus/town (for Town10HD_Opt)"
    assert len(world.get_map().get_spawn_points()) >= 100
    wait_line(log, "CARLA's map Town10HD_Opt is not in simbus: loading simbus's town instead")
    # A reload keeps the map; CARLA's folder is understood.
    assert client.reload_world(False).get_map().name == "simbus/town (for Town10HD_Opt)"
    world = client.load_world("/Game/Carla/Maps/Town01")
    assert world.get_map().name == "simbus/town (for Town01)"
    # Loading a scene by name (config.py -m town) gives it its own name.
    assert client.load_world("town").get_map().name == "town"
    # Someone else's load drops the substitute's name.
    client.load_world("Town03")
    assert gateway.sim_client("load", "town").returncode == 0
    assert client.get_world().get_map().name == "town"


@pytest.mark.parametrize("logged", [["--strict-maps"]], indirect=True)
def test_strict_maps_refuse_carla_s_towns(logged):
    gateway, _ = logged
    client = gateway.client()
    before = client.get_world()
    with pytest.raises(RuntimeError, match="CARLA's map Town10HD_Opt is not in simbus.*--strict-maps"):
        client.load_world("Town10HD_Opt")
    after = client.get_world()
    assert after.id == before.id and after.get_map().name == "default"
    assert client.load_world("town").get_map().name == "town"


def test_generate_opendrive_world_builds_a_flat_world_on_the_roads_given(gateway):
    client = gateway.client()
    before = client.get_world()
    with pytest.raises(RuntimeError, match="not XML|not an OpenDRIVE"):
        client.generate_opendrive_world("<OpenDRIVE><road>")
    assert client.get_world().id == before.id, "a refused OpenDRIVE changes nothing"
    world = client.generate_opendrive_world(SMALL_XODR, carla.OpendriveGenerationParameters())
    assert world.id != before.id
    opendrive = world.get_map()
    assert opendrive.name == "OpenDriveMap"
    assert opendrive.to_opendrive() == SMALL_XODR
    waypoint = opendrive.get_waypoint(carla.Location(50.0, 1.75, 0.0))
    assert (waypoint.road_id, waypoint.lane_id) == (0, -1)
    assert abs(waypoint.transform.location.y - 1.75) < 0.01
    # The flat world: a ground and nothing on it.
    assert [a.type_id for a in world.get_actors() if a.type_id != "spectator"] == ["static.prop.fixed"]
    assert gateway.sim_client("status").stdout.count("flat (1 actor)") == 1
