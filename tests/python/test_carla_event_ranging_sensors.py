"""The collision sensor, the obstacle detector, the semantic lidar and the
radar through the gateway, with the real `carla==0.9.16` client: each
arrives as CARLA's type through `listen`, on the frame just ticked; a car
driven into a wall reports one `CollisionEvent` naming the wall; a
detector sees the box ahead at its distance; the semantic lidar's points
on a box carry its id and tag; a radar sees a box coming at 5 m/s closing
at -5 m/s; bad attributes are refused and spawn nothing."""

import queue

import carla
import pytest

from test_carla_actors_sensors import blueprint, synced

FLAT = [["--scene", "flat"]]

# CARLA's tag of a dynamic thing (simbus's boxes).
DYNAMIC = 21


def floating_box(world, library, x, **extent):
    """A box with its centre `x` m ahead of the origin, 3 m up, held there
    (gravity off)."""
    box = world.spawn_actor(blueprint(library, "static.prop.box", **extent),
                            carla.Transform(carla.Location(x=x, z=3.0)))
    box.set_enable_gravity(False)
    return box


def listened(sensor):
    q = queue.Queue()
    sensor.listen(q.put)
    return q


def frame_of(q, frame):
    """The data of `frame` from `q`: nothing of an earlier frame may be
    left in it, nothing of a later one come first."""
    data = q.get(timeout=10)
    assert data.frame == frame, (data.frame, frame)
    return data


@pytest.mark.parametrize("gateway", FLAT, indirect=True)
def test_a_semantic_lidar_names_the_box_it_meets(gateway):
    _, world, library = synced(gateway)
    box = floating_box(world, library, 10.0, extent_x=1, extent_y=1, extent_z=1)
    lidar = world.spawn_actor(
        blueprint(library, "sensor.lidar.ray_cast_semantic", channels=16, points_per_second=57600,
                  rotation_frequency=20, range=40, upper_fov=10, lower_fov=-30),
        carla.Transform(carla.Location(z=3.0)))
    scans = listened(lidar)
    for _ in range(2):
        frame = world.tick()
        scan = frame_of(scans, frame)
        assert isinstance(scan, carla.SemanticLidarMeasurement)
        assert scan.channels == 16
        assert sum(scan.get_point_count(c) for c in range(16)) == len(scan) > 0
        on_box = [d for d in scan if d.object_idx == box.id]
        assert len(on_box) > 10
        for d in on_box:
            assert d.object_tag == DYNAMIC
            assert 9.0 - 1e-3 <= d.point.x <= 11.0 + 1e-3, d.point
            assert 0.0 < d.cos_inc_angle <= 1.0
        # The rest is the ground, 3 m below.
        rest = [d for d in scan if d.object_idx != box.id]
        assert rest and all(abs(d.point.z + 3.0) < 1e-3 for d in rest)
    lidar.stop()
    assert lidar.destroy()


@pytest.mark.parametrize("gateway", FLAT, indirect=True)
def test_a_radar_sees_a_box_coming_at_five_metres_a_second(gateway):
    _, world, library = synced(gateway)
    box = floating_box(world, library, 20.0, extent_x=1, extent_y=1, extent_z=1)
    box.enable_constant_velocity(carla.Vector3D(x=-5.0))
    radar = world.spawn_actor(
        blueprint(library, "sensor.other.radar", horizontal_fov=20, vertical_fov=10, range=30,
                  points_per_second=1500),
        carla.Transform(carla.Location(z=3.0)))
    echoes = listened(radar)
    seen = 0
    for _ in range(10):
        frame = world.tick()
        measurement = frame_of(echoes, frame)
        assert isinstance(measurement, carla.RadarMeasurement)
        # 1500 points a second for 0.05 s: at most 75 rays.
        assert measurement.get_detection_count() == len(measurement) <= 75
        for d in measurement:
            assert d.velocity == pytest.approx(-5.0, abs=0.1)
            assert abs(d.azimuth) <= 0.1746 and abs(d.altitude) <= 0.0873
            assert 14.0 <= d.depth <= 20.0
        seen += len(measurement)
    assert seen > 300
    radar.stop()
    assert radar.destroy()


@pytest.mark.parametrize("gateway", FLAT, indirect=True)
def test_a_car_driven_into_a_wall_reports_one_collision_naming_it(gateway):
    _, world, library = synced(gateway)
    car = world.spawn_actor(library.find("vehicle.simbus.car"), carla.Transform(carla.Location(z=0.5)))
    # A wall of a box, 4 m thick, its near face 8 m ahead: too heavy for
    # the car to push away and meet again.
    wall = world.spawn_actor(blueprint(library, "static.prop.box", extent_x=2, extent_y=5, extent_z=2),
                             carla.Transform(carla.Location(x=10.0, z=2.0)))
    sensor = world.spawn_actor(library.find("sensor.other.collision"), carla.Transform(), attach_to=car)
    hits = listened(sensor)
    for _ in range(40):
        world.tick()
    assert hits.empty(), "standing still, nothing starts"
    car.apply_control(carla.VehicleControl(throttle=0.6))
    events, ticked = [], []

    def take(event):
        # Events arrive on CARLA's stream thread, each with the frame its
        # contact started in: one the script ticked.
        assert isinstance(event, carla.CollisionEvent)
        assert event.frame in ticked, (event.frame, ticked[-3:])
        if event.other_actor.id == wall.id:
            events.append(event)

    for _ in range(300):
        ticked.append(world.tick())
        while not hits.empty():
            take(hits.get())
        # Coast the last metre into the wall (its event may come a few
        # ticks after the contact on a busy machine, and a car still
        # driving would bounce and meet the wall again), then brake.
        if car.get_location().x > 6.0:
            car.apply_control(carla.VehicleControl(throttle=0.0, brake=1.0 if events else 0.0))
    # What the last ticks sent is not lost.
    try:
        while True:
            take(hits.get(timeout=1.0))
    except queue.Empty:
        pass
    assert len(events) == 1, [(e.frame, e.normal_impulse) for e in events]
    assert events[0].actor.id == car.id
    assert events[0].normal_impulse.x < 0.0
    sensor.stop()
    assert sensor.destroy()


@pytest.mark.parametrize("gateway", FLAT, indirect=True)
def test_an_obstacle_detector_sees_the_box_ahead_at_its_distance(gateway):
    _, world, library = synced(gateway)
    car = world.spawn_actor(library.find("vehicle.simbus.car"), carla.Transform(carla.Location(z=0.5)))
    car.set_simulate_physics(False)
    detector = world.spawn_actor(
        blueprint(library, "sensor.other.obstacle", distance=20, hit_radius=0.01, only_dynamics=True),
        carla.Transform(carla.Location(z=2.5)), attach_to=car)
    seen = listened(detector)
    world.tick()
    assert seen.empty(), "nothing ahead: no event"
    box = floating_box(world, library, 10.0, extent_x=0.5, extent_y=1, extent_z=1)
    frame = world.tick()
    event = frame_of(seen, frame)
    assert isinstance(event, carla.ObstacleDetectionEvent)
    assert event.actor.id == car.id and event.other_actor.id == box.id
    # The box's near face is 9.5 m ahead of the detector.
    assert event.distance == pytest.approx(9.5, abs=0.1)
    detector.stop()
    assert detector.destroy()


@pytest.mark.parametrize("gateway", FLAT, indirect=True)
def test_bad_radar_and_semantic_lidar_attributes_are_refused(gateway):
    _, world, library = synced(gateway)
    before = len(world.get_actors())
    for type_id, attributes in [
        ("sensor.other.radar", {"points_per_second": 0}),
        ("sensor.other.radar", {"horizontal_fov": 180}),
        ("sensor.other.radar", {"range": -1}),
        ("sensor.other.radar", {"noise_seed": -1}),
        ("sensor.lidar.ray_cast_semantic", {"channels": 0}),
        ("sensor.lidar.ray_cast_semantic", {"range": 0}),
        ("sensor.lidar.ray_cast_semantic", {"upper_fov": -40}),
    ]:
        with pytest.raises(RuntimeError):
            world.spawn_actor(blueprint(library, type_id, **attributes), carla.Transform())
    world.tick()
    assert len(world.get_actors()) == before


@pytest.mark.parametrize("gateway", [["--scene", "town"]], indirect=True)
def test_sensor_synchronization_py_calls_every_sensor_of_every_frame(gateway):
    """Mirrors PythonAPI/examples/sensor_synchronization.py (CARLA 0.9.16;
    the script itself runs unchanged against the gateway, see the CARLA
    chapter): synchronous mode with 0.2 s steps; an RGB camera, a lidar of
    100 000 and one of 1 000 000 points per second, and two radars, all at
    the world's origin, each listening into one queue of (frame, name);
    after each tick the world's snapshot frame, and every sensor's data of
    that frame, none missed; the settings put back and the sensors
    destroyed."""
    client = gateway.client(timeout=10.0)
    world = client.get_world()
    original_settings = world.get_settings()
    settings = world.get_settings()
    settings.fixed_delta_seconds = 0.2
    settings.synchronous_mode = True
    world.apply_settings(settings)
    sensor_queue = queue.Queue()
    library = world.get_blueprint_library()
    cam_bp = library.find("sensor.camera.rgb")
    lidar_bp = library.find("sensor.lidar.ray_cast")
    radar_bp = library.find("sensor.other.radar")
    sensor_list = []
    try:
        def add(bp, name):
            sensor = world.spawn_actor(bp, carla.Transform())
            sensor.listen(lambda data: sensor_queue.put((data.frame, name)))
            sensor_list.append(sensor)

        add(cam_bp, "camera01")
        lidar_bp.set_attribute("points_per_second", "100000")
        add(lidar_bp, "lidar01")
        lidar_bp.set_attribute("points_per_second", "1000000")
        add(lidar_bp, "lidar02")
        add(radar_bp, "radar01")
        add(radar_bp, "radar02")
        for _ in range(10):
            world.tick()
            w_frame = world.get_snapshot().frame
            got = sorted(sensor_queue.get(True, 1.0) for _ in sensor_list)
            assert got == sorted((w_frame, name) for name in
                                 ("camera01", "lidar01", "lidar02", "radar01", "radar02"))
    finally:
        world.apply_settings(original_settings)
        for sensor in sensor_list:
            sensor.destroy()
    assert not world.get_settings().synchronous_mode
    # Gone from the world states that follow (the one in flight when the
    # destroys were applied may still hold them).
    for _ in range(20):
        world.wait_for_tick()
        left = world.get_actors().filter("sensor.*")
        if not left:
            break
    assert not left, [(a.id, a.type_id, a.is_alive) for a in left]
