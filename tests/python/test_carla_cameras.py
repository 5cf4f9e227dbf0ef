"""The RGB, semantic and instance segmentation cameras through the gateway,
with the real `carla==0.9.16` client: CARLA's own `synchronous_mode.py`'s
calls (an RGB and a semantic camera behind a car moved along waypoints,
every image of the frame just ticked, `CityScapesPalette`); `save_to_disk`
of every camera writes an image PIL reads at the camera's size; the
instance camera names the actor and its tag; the weather's sun shades
the RGB image; bad attributes are refused and change nothing."""

import queue

import carla
import numpy as np
import pytest
from PIL import Image

from test_carla_actors_sensors import blueprint, sync

TOWN = [["--scene", "town"]]
EMPTY = [["--scene", "empty"]]

# CARLA's CityScapes colours (carla/image/CityScapesPalette.h).
ROAD, ROAD_LINE, CAR, SKY = (128, 64, 128), (157, 234, 50), (0, 0, 142), (70, 130, 180)


def pixels(image):
    """`synchronous_mode.py`'s `draw_image`: the raw BGRA bytes as
    (height, width, 3) RGB."""
    array = np.frombuffer(image.raw_data, dtype=np.dtype("uint8"))
    array = np.reshape(array, (image.height, image.width, 4))
    return array[:, :, :3][:, :, ::-1]


def colours(rgb):
    return {tuple(int(c) for c in p) for p in rgb.reshape(-1, 3)}


@pytest.mark.parametrize("gateway", TOWN, indirect=True)
def test_synchronous_mode_py_calls_every_image_of_the_frame_ticked(gateway):
    """Mirrors PythonAPI/examples/synchronous_mode.py (CARLA 0.9.16; the
    script itself runs unchanged against the gateway, see the CARLA
    chapter): a vehicle on a spawn point with physics off, an RGB and a
    semantic camera 5.5 m behind it, 2.8 m up, pitched 15 degrees down;
    its `CarlaSyncMode` at 30 fps (on_tick and both listens into queues,
    each tick's data taken by frame); 100 ticks moving the car 1.5 m along
    the waypoints; the semantic image converted to CityScapes colours."""
    client = gateway.client(timeout=10.0)
    world = client.get_world()
    m = world.get_map()
    start_pose = m.get_spawn_points()[0]
    waypoint = m.get_waypoint(start_pose.location)
    library = world.get_blueprint_library()
    actor_list = []
    try:
        vehicle = world.spawn_actor(library.filter("vehicle.*")[0], start_pose)
        actor_list.append(vehicle)
        vehicle.set_simulate_physics(False)
        behind = carla.Transform(carla.Location(x=-5.5, z=2.8), carla.Rotation(pitch=-15))
        camera_rgb = world.spawn_actor(library.find("sensor.camera.rgb"), behind, attach_to=vehicle)
        actor_list.append(camera_rgb)
        camera_semseg = world.spawn_actor(
            library.find("sensor.camera.semantic_segmentation"), behind, attach_to=vehicle)
        actor_list.append(camera_semseg)

        original = world.get_settings()
        frame = world.apply_settings(carla.WorldSettings(
            no_rendering_mode=False, synchronous_mode=True, fixed_delta_seconds=1.0 / 30))
        queues = []
        for register in (world.on_tick, camera_rgb.listen, camera_semseg.listen):
            q = queue.Queue()
            register(q.put)
            queues.append(q)

        def retrieve(q):
            while True:
                data = q.get(timeout=10.0)
                if data.frame == frame:
                    return data

        seen = set()
        for _ in range(100):
            frame = world.tick()
            snapshot, image_rgb, image_semseg = [retrieve(q) for q in queues]
            assert snapshot.frame == image_rgb.frame == image_semseg.frame == frame
            waypoint = waypoint.next(1.5)[0]
            vehicle.set_transform(waypoint.transform)
            assert (image_rgb.width, image_rgb.height) == (800, 600)
            assert image_rgb.fov == pytest.approx(90.0)
            image_semseg.convert(carla.ColorConverter.CityScapesPalette)
            seen |= colours(pixels(image_semseg)[::20, ::20])
            rgb = pixels(image_rgb)
            # Lit, not blank: the road below, the sky above.
            assert rgb[-1].mean() < rgb[0].mean()
        assert round(1.0 / snapshot.timestamp.delta_seconds) == 30
        # The road, its marks, the car ahead and the sky, in CARLA's colours.
        assert {ROAD, ROAD_LINE, CAR, SKY} <= seen, seen
        world.apply_settings(original)
    finally:
        for actor in actor_list:
            actor.destroy()


@pytest.mark.parametrize("gateway", EMPTY, indirect=True)
def test_every_camera_saves_to_disk_an_image_pil_reads(gateway, tmp_path):
    client = gateway.client()
    world = client.get_world()
    sync(world)
    library = world.get_blueprint_library()
    box = world.spawn_actor(library.find("static.prop.box"),
                            carla.Transform(carla.Location(x=10, z=5)))
    box.set_enable_gravity(False)
    cameras = {}
    for kind in ["rgb", "depth", "semantic_segmentation", "instance_segmentation"]:
        bp = blueprint(library, "sensor.camera." + kind, image_size_x=96, image_size_y=64)
        camera = world.spawn_actor(bp, carla.Transform(carla.Location(z=5)))
        images = queue.Queue()
        camera.listen(images.put)
        cameras[kind] = (camera, images)
    frame = world.tick()
    for kind, (camera, images) in cameras.items():
        image = images.get(timeout=10)
        assert image.frame == frame
        assert isinstance(image, carla.Image)
        path = str(tmp_path / f"{kind}.png")
        if kind == "semantic_segmentation":
            image.save_to_disk(path, carla.ColorConverter.CityScapesPalette)
        else:
            image.save_to_disk(path)
        with Image.open(path) as saved:
            assert saved.size == (96, 64), kind
            centre = saved.convert("RGB").getpixel((48, 32))
        if kind == "semantic_segmentation":
            # The box, a dynamic prop: CARLA's "dynamic" colour.
            assert centre == (170, 120, 50)
        camera.stop()
        assert camera.destroy()
    assert box.destroy()


@pytest.mark.parametrize("gateway", EMPTY, indirect=True)
def test_the_instance_camera_names_the_actor_and_its_tag(gateway):
    client = gateway.client()
    world = client.get_world()
    sync(world)
    library = world.get_blueprint_library()
    box = world.spawn_actor(library.find("static.prop.box"),
                            carla.Transform(carla.Location(x=10, z=5)))
    box.set_enable_gravity(False)
    camera = world.spawn_actor(
        blueprint(library, "sensor.camera.instance_segmentation", image_size_x=64, image_size_y=48),
        carla.Transform(carla.Location(z=5)))
    images = queue.Queue()
    camera.listen(images.put)
    frame = world.tick()
    image = images.get(timeout=10)
    assert image.frame == frame
    bgra = np.frombuffer(image.raw_data, dtype=np.uint8).reshape(48, 64, 4)
    b, g, r = (int(v) for v in bgra[24, 32, :3])
    assert r == 21  # CARLA's Dynamic tag
    assert g | (b << 8) == box.id & 0xFFFF
    assert tuple(int(v) for v in bgra[0, 0, :3]) == (0, 0, 11)  # the sky: tag 11, no actor
    camera.stop()
    assert camera.destroy() and box.destroy()


@pytest.mark.parametrize("gateway", EMPTY, indirect=True)
def test_the_weather_s_sun_shades_the_rgb_image(gateway):
    client = gateway.client()
    world = client.get_world()
    sync(world)
    library = world.get_blueprint_library()
    box = world.spawn_actor(library.find("static.prop.box"),
                            carla.Transform(carla.Location(x=10, z=5)))
    box.set_enable_gravity(False)
    camera = world.spawn_actor(
        blueprint(library, "sensor.camera.rgb", image_size_x=64, image_size_y=48),
        carla.Transform(carla.Location(z=5)))
    images = queue.Queue()
    camera.listen(images.put)

    def red_at_centre(azimuth, altitude):
        weather = world.get_weather()
        weather.sun_azimuth_angle, weather.sun_altitude_angle = azimuth, altitude
        world.set_weather(weather)
        frame = world.tick()
        image = images.get(timeout=10)
        assert image.frame == frame
        return int(pixels(image)[24, 32, 0])

    # The box's face looks back at the camera (CARLA's -x): lit by a low sun
    # behind the camera, in its own shadow with the sun behind the box.
    lit, shadowed = red_at_centre(180.0, 5.0), red_at_centre(0.0, 5.0)
    assert lit > shadowed + 60, (lit, shadowed)
    weather = world.get_weather()
    assert (weather.sun_azimuth_angle, weather.sun_altitude_angle) == (0.0, 5.0)
    camera.stop()
    assert camera.destroy() and box.destroy()


@pytest.mark.parametrize("gateway", EMPTY, indirect=True)
def test_bad_camera_attributes_and_a_broken_weather_are_refused_changing_nothing(gateway):
    client = gateway.client()
    world = client.get_world()
    library = world.get_blueprint_library()
    before = len(world.get_actors().filter("sensor.*"))
    for name, value in [("image_size_x", "0"), ("image_size_x", "100000"), ("fov", "nan"),
                        ("fov", "180"), ("image_size_y", "1.5"), ("fov", "wide")]:
        bp = blueprint(library, "sensor.camera.rgb", **{name: value})
        with pytest.raises(RuntimeError, match="simbus"):
            world.spawn_actor(bp, carla.Transform(carla.Location(z=5)))
    assert len(world.get_actors().filter("sensor.*")) == before
    # CARLA's client sends set_weather without waiting for an answer: a
    # weather that is not 14 finite numbers is dropped, nothing changes.
    weather = world.get_weather()
    broken = world.get_weather()
    broken.sun_altitude_angle = float("nan")
    world.set_weather(broken)
    assert world.get_weather() == weather


def frames_of(world, camera, ticks):
    """`ticks` ticks' worth of `camera`'s data, each taken by its frame."""
    q = queue.Queue()
    camera.listen(q.put)
    out = []
    for _ in range(ticks):
        frame = world.tick()
        data = q.get(timeout=10)
        while data.frame < frame:
            data = q.get(timeout=10)
        out.append(data)
    camera.stop()
    return out


@pytest.mark.parametrize("gateway", TOWN, indirect=True)
def test_normals_optical_flow_dvs_and_cosmos_cameras_from_simbus_s_casts(gateway):
    """The cameras manual_control.py lists beside the usual ones, computed
    by the gateway from simbus's ray casts: `sensor.camera.normals` (the
    ground below a level camera faces up: blue), `optical_flow` (nothing
    moves: no flow; a camera driven forward: the ground streams down the
    screen), `dvs` (a still scene: no events; a moving one: events of
    both polarities, in time order) and `cosmos_visualization` (the road
    in Cosmos's lane colour, cars red)."""
    client = gateway.client(timeout=10.0)
    world = client.get_world()
    sync(world)
    library = world.get_blueprint_library()
    spawn = world.get_map().get_spawn_points()[0]
    car = world.spawn_actor(library.find("vehicle.tesla.model3"), spawn)
    ahead = world.spawn_actor(library.find("vehicle.tesla.model3"), carla.Transform(
        spawn.transform(carla.Location(x=12.0)), spawn.rotation))
    level = carla.Transform(carla.Location(x=1.5, z=1.6))
    small = dict(image_size_x=64, image_size_y=48)
    cameras = {name: world.spawn_actor(blueprint(library, f"sensor.camera.{name}", **small),
                                       level, attach_to=car)
               for name in ("normals", "optical_flow", "dvs", "cosmos_visualization")}
    # The cars settle on their springs.
    for _ in range(60):
        world.tick()

    [normals] = frames_of(world, cameras["normals"], 1)
    rgb = pixels(normals)
    assert (normals.width, normals.height) == (64, 48)
    # The bottom rows see the road: its normal is up (CARLA's z: blue).
    r, g, b = (int(c) for c in rgb[-2, 32])
    assert b > 240 and abs(r - 128) < 20 and abs(g - 128) < 20, (r, g, b)

    still = frames_of(world, cameras["optical_flow"], 2)[-1]
    assert isinstance(still, carla.OpticalFlowImage)
    flow = np.frombuffer(still.raw_data, dtype=np.float32).reshape(48, 64, 2)
    assert np.abs(flow).max() < 1e-3, "nothing moves: no flow"
    [events] = frames_of(world, cameras["dvs"], 2)[-1:]
    assert isinstance(events, carla.DVSEventArray) and len(events) == 0, "a still scene"

    [cosmos] = frames_of(world, cameras["cosmos_visualization"], 1)
    seen = colours(pixels(cosmos))
    assert (56, 103, 221) in seen, "the road in Cosmos's lane colour"
    assert (255, 0, 0) in seen, "the car ahead is red"

    # Driving on at 5 m/s: the ground streams down the screen, and the
    # changing image fires events.
    car.enable_constant_velocity(carla.Vector3D(5.0, 0.0, 0.0))
    for _ in range(3):
        world.tick()
    moving = frames_of(world, cameras["optical_flow"], 2)[-1]
    flow = np.frombuffer(moving.raw_data, dtype=np.float32).reshape(48, 64, 2)
    bottom = flow[-3:, 24:40]
    assert (bottom[:, :, 1] < -1e-3).all(), bottom[:, :, 1]
    dvs = frames_of(world, cameras["dvs"], 3)
    events = [e for batch in dvs[1:] for e in batch]
    assert events and {e.pol for e in events} == {True, False}
    times = [e.t for e in events[:len(dvs[1])]]
    assert times == sorted(times) and all(0 <= e.x < 64 and 0 <= e.y < 48 for e in events)
    for camera in cameras.values():
        camera.destroy()
    car.destroy()
    ahead.destroy()
