"""CARLA 0.9.16's example scripts, mirrored: each test makes the calls one
of CARLA's `PythonAPI/examples` (or `PythonAPI/util`) scripts makes, in
its order and with its arguments (its default run), and asserts what that
script shows a user: what it prints, what it leaves in the world, its exit.

CARLA's scripts are not copied here; each test is our own code, and its
docstring names the script it mirrors. Where a script sleeps to let the
world run, the mirror waits for frames (or sensor data) instead; where a
script starts a traffic manager (`set_autopilot`), the mirror runs as its
own process (a traffic manager keeps its port and threads until its
process ends) on a free traffic-manager port instead of CARLA's 8000."""

import math
import random
import os
import subprocess
import sys
import textwrap

import carla
import pytest

from test_carla_traffic_manager import free_port

# CARLA's `vehicle_physics.py` tests vehicles on this delta.
PHYSICS_DELTA = 0.1


def run_mirror(source, *args, timeout=300, cwd=None):
    """Runs a mirror script (our own text) as its own process, with a time
    limit; returns the finished process (stdout, stderr, exit status)."""
    return subprocess.run(
        [sys.executable, "-c", textwrap.dedent(source), *map(str, args)],
        capture_output=True, text=True, timeout=timeout, cwd=cwd,
    )


def vehicle_ids(world):
    return sorted(a.id for a in world.get_actors().filter("vehicle.*"))


def vehicles_after(world, before, frames=2000):
    """The world's vehicles once those a finished script destroyed have
    left: waits up to `frames` frames for the list to come back to
    `before` (the scene's own vehicles)."""
    now = vehicle_ids(world)
    for _ in range(frames):
        if now == before:
            break
        world.wait_for_tick()
        now = vehicle_ids(world)
    return now


TUTORIAL = """
import os, random, sys, threading, weakref
import carla

port, tm_port, out = int(sys.argv[1]), int(sys.argv[2]), sys.argv[3]
actor_list = []
frames = []
enough = threading.Event()


class OnDepth:
    def __call__(self, image):
        image.save_to_disk(os.path.join(out, "%06d.png" % image.frame),
                           carla.ColorConverter.LogarithmicDepth)
        frames.append(image.timestamp)
        if frames[-1] - frames[0] >= 5.0:
            enough.set()


# Ours, not the script's: CARLA's client lets go of a stopped sensor's
# callback on its io thread, taking the GIL; if Python is finalising by
# then the process aborts ("terminate called without an active
# exception"), as CARLA's own tutorial can. The mirror holds the callback
# only through CARLA and waits until CARLA has let go of it before it ends.
on_depth = OnDepth()
released = threading.Event()
weakref.finalize(on_depth, released.set)

try:
    client = carla.Client("127.0.0.1", port)
    client.set_timeout(2.0)
    world = client.get_world()
    library = world.get_blueprint_library()
    bp = random.choice(library.filter("vehicle"))
    if bp.has_attribute("color"):
        bp.set_attribute("color", random.choice(bp.get_attribute("color").recommended_values))
    transform = random.choice(world.get_map().get_spawn_points())
    vehicle = world.spawn_actor(bp, transform)
    actor_list.append(vehicle)
    print("created %s" % vehicle.type_id)
    vehicle.set_autopilot(True, tm_port)
    camera = world.spawn_actor(library.find("sensor.camera.depth"),
                               carla.Transform(carla.Location(x=1.5, z=2.4)),
                               attach_to=vehicle)
    actor_list.append(camera)
    print("created %s" % camera.type_id)
    camera.listen(on_depth)
    del on_depth
    location = vehicle.get_location()
    location.x += 40
    vehicle.set_location(location)
    print("moved vehicle to %s" % location)
    transform.location += carla.Location(x=40, y=-3.2)
    transform.rotation.yaw = -180.0
    for _ in range(10):
        transform.location.x += 8.0
        npc = world.try_spawn_actor(random.choice(library.filter("vehicle")), transform)
        if npc is not None:
            actor_list.append(npc)
            npc.set_autopilot(True, tm_port)
            print("created %s" % npc.type_id)
    # CARLA's script sleeps 5 s here; the mirror waits for 5 simulated
    # seconds of depth images.
    if not enough.wait(120):
        sys.exit("the depth camera delivered %d images" % len(frames))
finally:
    print("destroying actors")
    camera.destroy()
    client.apply_batch([carla.command.DestroyActor(x) for x in actor_list])
    print("done.")
    released.wait(30)
"""


def test_tutorial_spawns_drives_films_and_cleans_up(gateway, tmp_path):
    """Mirrors PythonAPI/examples/tutorial.py (CARLA 0.9.16): a random
    vehicle on a random spawn point on autopilot, a depth camera on it
    saving logarithmic-depth PNGs, the vehicle moved 40 m, ten NPCs tried
    8 m apart on the other lane, then everything destroyed."""
    world = gateway.client().get_world()
    world.wait_for_tick()
    before = vehicle_ids(world)
    done = run_mirror(TUTORIAL, gateway.port, free_port(), tmp_path)
    assert done.returncode == 0, done.stderr[-3000:]
    lines = done.stdout.splitlines()
    assert lines[0].startswith("created vehicle."), lines
    assert lines[1] == "created sensor.camera.depth", lines
    assert lines[2].startswith("moved vehicle to Location(x="), lines
    npcs = [l for l in lines[3:] if l.startswith("created vehicle.")]
    assert len(npcs) >= 5, lines
    assert lines[-2:] == ["destroying actors", "done."], lines
    pngs = sorted(p for p in os.listdir(tmp_path) if p.endswith(".png"))
    assert len(pngs) >= 10, pngs
    with open(tmp_path / pngs[0], "rb") as f:
        head = f.read(24)
    assert head[:8] == b"\x89PNG\r\n\x1a\n"
    # CARLA's depth camera default: 800 x 600.
    assert (int.from_bytes(head[16:20], "big"), int.from_bytes(head[20:24], "big")) == (800, 600)
    assert vehicles_after(world, before) == before, "the tutorial leaves no vehicle behind"
    assert not world.get_actors().filter("sensor.*")


def wait(world, frames=100):
    """`vehicle_physics.py`'s `wait`: `frames` ticks."""
    heights = []
    for _ in range(frames):
        world.tick()
        heights.append(world.get_snapshot())
    return heights


def highest(snapshots, actor_id):
    return max(s.find(actor_id).get_transform().location.z for s in snapshots)


def test_vehicle_physics_impulse_and_force_throw_the_model3_up(gateway):
    """Mirrors PythonAPI/examples/vehicle_physics.py (CARLA 0.9.16),
    default `--filter model3`: synchronous at 0.1 s, the first `model3`
    on the first spawn point 3 m up, its mass from `get_physics_control`,
    the spectator 20 m ahead looking back, then an upward impulse of
    10 x mass N s and a force of impulse / 0.1 N, 100 ticks each, the
    vehicle put back in between; the settings restored at the end."""
    client = gateway.client(timeout=2.0)
    world = client.get_world()
    world.wait_for_tick()
    before = vehicle_ids(world)
    original = world.get_settings()
    settings = world.get_settings()
    settings.fixed_delta_seconds = PHYSICS_DELTA
    settings.synchronous_mode = True
    world.apply_settings(settings)
    vehicle = None
    try:
        library = world.get_blueprint_library()
        vehicle_bp = library.filter("model3")[0]
        assert vehicle_bp.id == "vehicle.tesla.model3"
        spawn = world.get_map().get_spawn_points()[0]
        spawn.location.z += 3
        vehicle = world.spawn_actor(vehicle_bp, spawn)
        mass = vehicle.get_physics_control().mass
        assert mass > 1000.0, mass
        spectator_at = carla.Transform(spawn.location, spawn.rotation)
        spectator_at.location += spawn.get_forward_vector() * 20
        spectator_at.rotation.yaw += 180
        spectator = world.get_spectator()
        spectator.set_transform(spectator_at)

        wait(world)
        vehicle.set_target_velocity(carla.Vector3D(0, 0, 0))
        rest = vehicle.get_transform()
        wait(world)

        impulse = 10 * mass
        print("# Adding an Impulse of %f N s" % impulse)
        vehicle.add_impulse(carla.Vector3D(0, 0, impulse))
        # 10 m/s up: about 5 m of climb before it falls back.
        assert highest(wait(world), vehicle.id) > rest.location.z + 3.0
        vehicle.set_transform(rest)
        vehicle.set_target_velocity(carla.Vector3D(0, 0, 0))
        wait(world)

        print("# Adding a Force of %f N" % (impulse / PHYSICS_DELTA))
        vehicle.add_force(carla.Vector3D(0, 0, impulse / PHYSICS_DELTA))
        assert highest(wait(world), vehicle.id) > rest.location.z + 3.0
        vehicle.set_transform(rest)
        vehicle.set_target_velocity(carla.Vector3D(0, 0, 0))
        wait(world)

        wait(world, 500)
        at = vehicle.get_transform().location
        assert math.dist((at.x, at.y), (rest.location.x, rest.location.y)) < 1.0
    finally:
        world.apply_settings(original)
        if vehicle is not None:
            vehicle.destroy()
    assert world.get_settings().synchronous_mode is False
    assert vehicles_after(world, before) == before


def orbit(location, angle):
    """`vehicle_gallery.py`'s camera: 6.4 m out at `angle`, 2 m up,
    looking back at `location` 15 degrees down."""
    a = math.radians(angle)
    at = location + carla.Location(x=6.4 * math.cos(a), y=6.4 * math.sin(a), z=2.0)
    return carla.Transform(at, carla.Rotation(yaw=180 + angle, pitch=-15))


@pytest.mark.parametrize("gateway", [["--delta-seconds", "0.05"]], indirect=True)
def test_vehicle_gallery_shows_every_catalog_vehicle_with_the_spectator_circling(gateway):
    """Mirrors PythonAPI/examples/vehicle_gallery.py (CARLA 0.9.16): every
    `vehicle` blueprint in turn spawned on one random spawn point, yaw -45,
    the spectator circling it at 60 degrees per simulated second (one
    `wait_for_tick` each) until a full turn, then destroyed. The server
    steps 0.05 s frames as fast as it can, so the gallery takes seconds."""
    client = gateway.client(timeout=2.0)
    world = client.get_world()
    world.wait_for_tick()
    before = vehicle_ids(world)
    spectator = world.get_spectator()
    blueprints = world.get_blueprint_library().filter("vehicle")
    location = random.choice(world.get_map().get_spawn_points()).location
    shown = []
    for blueprint in blueprints:
        vehicle = world.spawn_actor(blueprint, carla.Transform(location, carla.Rotation(yaw=-45.0)))
        try:
            shown.append(vehicle.type_id)
            angle, turns = 0.0, 0
            while angle < 356:
                timestamp = world.wait_for_tick().timestamp
                angle += timestamp.delta_seconds * 60.0
                last = orbit(vehicle.get_location(), angle - 90)
                spectator.set_transform(last)
                turns += 1
            assert turns >= 2
        finally:
            vehicle.destroy()
    assert shown == [bp.id for bp in blueprints]
    assert len(shown) >= 30 and "vehicle.tesla.model3" in shown
    # The first state waited for may have left before the last move was
    # read; the one after it was built after.
    world.wait_for_tick()
    world.wait_for_tick()
    at = spectator.get_transform().location
    assert (at.x, at.y, at.z) == pytest.approx((last.location.x, last.location.y, last.location.z), abs=1e-2)
    assert vehicles_after(world, before) == before


def tick_weather(weather, t):
    """Our own moving weather at time `t`, written into `weather` (the
    eight fields `dynamic_weather.py` animates: the sun circles, a storm
    comes and goes)."""
    storm = max(0.0, 100 * math.sin(0.1 * t))
    weather.cloudiness = min(90.0, storm + 5)
    weather.precipitation = min(80.0, storm)
    weather.precipitation_deposits = min(85.0, storm)
    weather.wind_intensity = 5.0 if storm < 20 else 40.0
    weather.fog_density = min(30.0, storm / 4)
    weather.wetness = storm
    weather.sun_azimuth_angle = (weather.sun_azimuth_angle + 0.25 * t) % 360.0
    weather.sun_altitude_angle = 70 * math.sin(0.008 * t) - 20


def test_dynamic_weather_changes_the_weather_every_tenth_of_a_second(gateway):
    """Mirrors PythonAPI/examples/dynamic_weather.py (CARLA 0.9.16),
    default `--speed 1.0`: starts from `get_weather()`, then on every
    `wait_for_tick(seconds=30.0)` adds the frame's delta and, past 0.1 s,
    moves that weather on and sets it (the script runs until Ctrl-C; the
    mirror stops after 20 changes). `get_weather` then answers the last
    weather set, to this client and to another."""
    client = gateway.client(timeout=2.0)
    world = client.get_world()
    weather = world.get_weather()
    first = (weather.sun_altitude_angle, weather.sun_azimuth_angle, weather.precipitation)
    speed, elapsed, t, changes = 1.0, 0.0, 0.0, 0
    update_freq = 0.1 / speed
    while changes < 20:
        timestamp = world.wait_for_tick(seconds=30.0).timestamp
        elapsed += timestamp.delta_seconds
        if elapsed > update_freq:
            t += speed * elapsed
            tick_weather(weather, t)
            world.set_weather(weather)
            elapsed, changes = 0.0, changes + 1
    for now in (world.get_weather(), gateway.client().get_world().get_weather()):
        for field in ("sun_altitude_angle", "sun_azimuth_angle", "precipitation", "cloudiness",
                      "precipitation_deposits", "wind_intensity", "fog_density", "wetness"):
            assert getattr(now, field) == pytest.approx(getattr(weather, field), abs=1e-3), field
    assert (weather.sun_altitude_angle, weather.sun_azimuth_angle, weather.precipitation) != first


@pytest.mark.parametrize("gateway", [["--scene", "town"]], indirect=True)
def test_extract_spawn_points_writes_every_spawn_point_of_the_town(gateway, tmp_path):
    """Mirrors PythonAPI/util/extract_spawn_points.py (CARLA 0.9.16): a
    client with one worker thread, `get_map().get_spawn_points()`, one CSV
    line `index,x,y,z` per spawn point in `<output-dir>/spawn_points.csv`."""
    client = carla.Client("127.0.0.1", gateway.port, worker_threads=1)
    client.set_timeout(2.0)
    world = client.get_world()
    town = world.get_map()
    assert town.get_spawn_points(), "There are no spawn points available in your map/town."
    spawn_points = town.get_spawn_points()
    with open(tmp_path / "spawn_points.csv", "w", encoding="utf8") as f:
        for index, p in enumerate(spawn_points):
            f.write(f"{index},{p.location.x},{p.location.y},{p.location.z}\n")
    rows = (tmp_path / "spawn_points.csv").read_text().splitlines()
    assert len(rows) == len(spawn_points) >= 100
    parsed = [tuple(float(v) for v in row.split(",")) for row in rows]
    assert [int(r[0]) for r in parsed] == list(range(len(rows)))
    # Every spawn point stands 0.5 m above a lane of the flat town.
    assert all(r[3] == pytest.approx(0.5, abs=1e-3) for r in parsed), parsed[:5]
    assert len({(r[1], r[2]) for r in parsed}) == len(parsed), "no two spawn points coincide"
    for r in parsed[:: max(1, len(parsed) // 20)]:
        lane = town.get_waypoint(carla.Location(x=r[1], y=r[2], z=r[3]))
        assert lane.transform.location.distance(carla.Location(x=r[1], y=r[2], z=0.0)) < 0.5
