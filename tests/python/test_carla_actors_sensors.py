"""CARLA 0.9.16's own client spawns, moves and destroys simbus actors,
batches commands, and listens to simbus sensors through the gateway: the
seeds' camera loop, a depth image decoded to a known distance, lidar and
IMU, the determinism recipe on two server + gateway pairs, and bad input
(CARLA's config.py calls: test_carla_config.py)."""

import math
import queue
import socket

import carla
import pytest

from conftest import Raw


def sync(world, delta=0.05):
    settings = world.get_settings()
    settings.synchronous_mode = True
    settings.fixed_delta_seconds = delta
    world.apply_settings(settings)


def synced(gateway):
    """A client of `gateway`, its world in synchronous mode with a 0.05 s
    step, and the world's blueprint library."""
    client = gateway.client()
    world = client.get_world()
    sync(world)
    return client, world, world.get_blueprint_library()


def settle(world, near, radius=5.0, ticks=200):
    """Ticks until no actor within `radius` of the location `near` moves
    (the scene's boxes dropped from height have landed), at most `ticks`
    ticks."""
    for _ in range(ticks):
        moving = [f"{a.type_id} at {a.get_location()}" for a in world.get_actors()
                  if a.get_location().distance(near) < radius and a.get_velocity().length() >= 0.01]
        if not moving:
            return
        world.tick()
    raise AssertionError(f"still moving after {ticks} ticks: {moving}")


def blueprint(library, type_id, **attributes):
    """The blueprint `type_id` of `library` with `attributes` set."""
    found = library.find(type_id)
    for name, value in attributes.items():
        found.set_attribute(name, str(value))
    return found


def small_camera(library, width=64, height=48):
    return blueprint(library, "sensor.camera.depth", image_size_x=width, image_size_y=height)


def test_the_blueprint_library_has_simbus_actors_and_sensors(gateway):
    library = gateway.client().get_world().get_blueprint_library()
    ids = {bp.id for bp in library}
    assert {
        "static.prop.box", "static.prop.sphere", "static.prop.capsule", "vehicle.simbus.car",
        "sensor.camera.depth", "sensor.lidar.ray_cast", "sensor.other.imu",
    } <= ids
    assert {bp.id for bp in library.filter("sensor.*")} == {
        "sensor.camera.depth", "sensor.camera.rgb", "sensor.camera.semantic_segmentation",
        "sensor.camera.instance_segmentation", "sensor.camera.normals",
        "sensor.camera.optical_flow", "sensor.camera.dvs", "sensor.camera.cosmos_visualization",
        "sensor.lidar.ray_cast",
        "sensor.lidar.ray_cast_semantic", "sensor.other.radar", "sensor.other.imu",
        "sensor.other.gnss", "sensor.other.lane_invasion", "sensor.other.collision",
        "sensor.other.obstacle"}
    camera = library.find("sensor.camera.depth")
    for name in ["image_size_x", "image_size_y", "fov", "sensor_tick"]:
        assert camera.has_attribute(name), name
    lidar = library.find("sensor.lidar.ray_cast")
    for name in ["channels", "points_per_second", "range", "upper_fov", "lower_fov",
                 "rotation_frequency", "sensor_tick"]:
        assert lidar.has_attribute(name), name
    camera.set_attribute("fov", "60")
    assert camera.get_attribute("fov").as_float() == 60.0
    car = library.find("vehicle.simbus.car")
    assert car.has_tag("vehicle")
    with pytest.raises(ValueError, match="read-only"):
        car.set_attribute("number_of_wheels", "3")  # not modifiable
    with pytest.raises(IndexError):
        library.find("vehicle.tesla.roadster")


@pytest.mark.parametrize("gateway", [["--scene", "empty"]], indirect=True)
def test_seed_synchronous_camera_queue_200_ticks_none_missing(gateway):
    client = gateway.client()
    world = client.get_world()
    blueprint = small_camera(world.get_blueprint_library())
    transform = carla.Transform(carla.Location(x=0.0, y=0.0, z=2.0), carla.Rotation(yaw=15.0))
    # The seed, as written (a timeout on get so a failure cannot hang).
    settings = world.get_settings()
    settings.synchronous_mode = True
    world.apply_settings(settings)

    camera = world.spawn_actor(blueprint, transform)
    image_queue = queue.Queue()
    camera.listen(image_queue.put)

    for _ in range(200):
        frame = world.tick()
        image = image_queue.get(timeout=10)
        assert image.frame == frame
        snapshot = world.get_snapshot()
        assert snapshot.frame == frame
        assert image.timestamp == snapshot.timestamp.elapsed_seconds
        assert (image.width, image.height) == (64, 48)
        assert len(image.raw_data) == 64 * 48 * 4
        assert abs(image.transform.location.z - 2.0) < 1e-5
        assert abs(image.transform.rotation.yaw - 15.0) < 1e-3
    assert image_queue.empty()
    camera.stop()
    assert not camera.is_listening()
    assert camera.destroy()


@pytest.mark.parametrize("gateway", [["--scene", "empty"]], indirect=True)
def test_a_depth_image_decodes_to_the_distance_of_a_known_box(gateway, tmp_path):
    client, world, library = synced(gateway)
    box = library.find("static.prop.box")
    # A 1 m cube whose near face is 9.5 m ahead of the camera (it falls
    # 1.2 cm in the one frame captured).
    world.spawn_actor(box, carla.Transform(carla.Location(x=10.0, y=0.0, z=5.0)))
    camera = world.spawn_actor(small_camera(library, 65, 49),
                               carla.Transform(carla.Location(x=0.0, y=0.0, z=5.0)))
    images = queue.Queue()
    camera.listen(images.put)
    frame = world.tick()
    image = images.get(timeout=10)
    assert image.frame == frame
    raw = bytes(image.raw_data)
    centre = (image.height // 2 * image.width + image.width // 2) * 4
    b, g, r, a = raw[centre:centre + 4]
    # CARLA's formula: (R + G*256 + B*256^2) / (256^3 - 1) * 1000 m.
    metres = (r + g * 256 + b * 65536) / (256 ** 3 - 1) * 1000.0
    assert abs(metres - 9.5) < 1e-3, metres
    # A corner sees nothing: CARLA's far plane, 1000 m.
    b, g, r, a = raw[0:4]
    assert (r + g * 256 + b * 65536) / (256 ** 3 - 1) * 1000.0 == pytest.approx(1000.0)
    # The client's own converter: grey = 255 * depth / 1000.
    image.convert(carla.ColorConverter.Depth)
    grey = bytes(image.raw_data)[centre]
    assert grey == int(255 * 9.5 / 1000), grey
    path = tmp_path / "depth.png"
    image.save_to_disk(str(path))
    assert path.stat().st_size > 0
    camera.stop()


@pytest.mark.parametrize("gateway", [["--scene", "empty"]], indirect=True)
def test_lidar_and_imu_measurements_arrive_as_carlas_types(gateway):
    client, world, library = synced(gateway)
    box = blueprint(library, "static.prop.box", extent_y=20, extent_z=20)
    world.spawn_actor(box, carla.Transform(carla.Location(x=5.5, z=0.0)))
    lidar_bp = blueprint(library, "sensor.lidar.ray_cast", channels=4, points_per_second=8000,
                         rotation_frequency=20, range=50, upper_fov=5, lower_fov=-5)
    # Fixed in the world: the lidar, an IMU; an IMU on a falling ball.
    lidar = world.spawn_actor(lidar_bp, carla.Transform())
    imu = world.spawn_actor(library.find("sensor.other.imu"), carla.Transform())
    ball = world.spawn_actor(library.find("static.prop.sphere"), carla.Transform(carla.Location(x=-5, z=10)))
    falling = world.spawn_actor(library.find("sensor.other.imu"), carla.Transform(), attach_to=ball)
    assert falling.parent.id == ball.id
    scans, readings, falls = queue.Queue(), queue.Queue(), queue.Queue()
    lidar.listen(scans.put)
    imu.listen(readings.put)
    falling.listen(falls.put)
    world.tick()
    for q in (scans, readings, falls):
        q.get(timeout=10)
    frame = world.tick()
    scan = scans.get(timeout=10)
    reading = readings.get(timeout=10)
    fall = falls.get(timeout=10)
    assert scan.frame == frame and reading.frame == frame and fall.frame == frame
    assert isinstance(scan, carla.LidarMeasurement)
    assert scan.channels == 4
    # 20 Hz for 0.05 s is one turn: 8000 / 20 / 4 = 100 rays per channel,
    # the forward ones hit the wall 5 m ahead.
    assert 0 < len(scan) <= 400
    assert sum(scan.get_point_count(c) for c in range(4)) == len(scan)
    ahead = [p for p in scan if abs(p.point.y) < 0.5]
    assert ahead and all(abs(p.point.x - 5.0) < 0.2 for p in ahead)
    assert all(0.0 <= p.intensity <= 1.0 for p in scan)
    assert 0.0 <= scan.horizontal_angle < 2 * math.pi
    assert isinstance(reading, carla.IMUMeasurement)
    # At rest the accelerometer reads gravity's reaction, up.
    assert abs(reading.accelerometer.z - 9.81) < 1e-3
    assert abs(reading.accelerometer.x) < 1e-3 and abs(reading.gyroscope.z) < 1e-3
    # In free fall it reads nothing, and it moves with its parent.
    assert abs(fall.accelerometer.z) < 0.05, fall.accelerometer
    assert fall.transform.location.z < 10.0
    assert abs(fall.transform.location.x + 5) < 1e-4
    for sensor in (lidar, imu, falling):
        sensor.stop()


@pytest.mark.parametrize("gateway", [["--scene", "empty"]], indirect=True)
def test_actors_spawn_move_and_are_destroyed(gateway):
    client, world, library = synced(gateway)
    box = blueprint(library, "static.prop.box", role_name="hero")
    actor = world.spawn_actor(box, carla.Transform(carla.Location(x=1, y=2, z=3), carla.Rotation(yaw=30)))
    assert actor.type_id == "static.prop.box"
    assert actor.attributes["role_name"] == "hero"
    world.tick()
    t = actor.get_transform()
    assert abs(t.location.x - 1) < 1e-4 and abs(t.location.y - 2) < 1e-4
    assert abs(t.rotation.yaw - 30) < 1e-2
    assert t.location.z < 3  # it falls
    actor.set_transform(carla.Transform(carla.Location(x=5, y=-2, z=10), carla.Rotation(yaw=-45)))
    world.tick()
    t = actor.get_transform()
    assert abs(t.location.x - 5) < 1e-3 and abs(t.location.y + 2) < 1e-3 and abs(t.rotation.yaw + 45) < 1e-2
    actor.set_target_velocity(carla.Vector3D(2, 0, 0))
    world.tick()
    assert abs(actor.get_velocity().x - 2) < 1e-3
    actor.add_impulse(carla.Vector3D(0, 1, 0))  # a 1 m cube of density 1 weighs 1 kg: +1 m/s
    world.tick()
    assert abs(actor.get_velocity().y - 1) < 1e-2
    actor.set_simulate_physics(False)
    world.tick()
    held = actor.get_transform().location
    world.tick()
    assert actor.get_transform().location == held
    car = world.spawn_actor(library.find("vehicle.simbus.car"), carla.Transform(carla.Location(x=-20, z=1)))
    assert isinstance(car, carla.Vehicle)
    car.apply_control(carla.VehicleControl(throttle=0.7, steer=-0.2, hand_brake=True))
    world.tick()
    control = car.get_control()
    assert (round(control.throttle, 3), round(control.steer, 3), control.hand_brake) == (0.7, -0.2, True)
    assert {a.id for a in world.get_actors().filter("vehicle.*")} == {car.id}
    with pytest.raises(RuntimeError, match="simbus attaches only sensors"):
        world.spawn_actor(box, carla.Transform(), attach_to=car)
    with pytest.raises(RuntimeError, match="not a number|sizes"):
        huge = library.find("static.prop.sphere")
        huge.set_attribute("radius", "5000")
        world.spawn_actor(huge, carla.Transform())
    assert actor.destroy() and car.destroy()
    world.tick()
    assert not [a for a in world.get_actors() if a.id in (actor.id, car.id)]


def test_a_lidar_drops_points_as_carla_by_default_and_keeps_them_with_the_recipe(gateway):
    """CARLA's lidar drops 45 % of its rays and some faint returns by
    default, its intensity exp(-0.004 d); CARLA's documented way to keep
    every point (general rate 0, intensity limit 1, nothing dropped at zero
    intensity) keeps them all; the same seed drops the same points; a
    share above 1 is refused, naming the attributes."""
    client, world, library = synced(gateway)
    wall = blueprint(library, "static.prop.box", extent_x=0.5, extent_y=30, extent_z=30)
    # Clear of the ground and of the scene's boxes once they have landed: a
    # spawn into them is refused, as CARLA refuses it (a young world's boxes
    # are still falling through the wall's place).
    # From the scene's start (a world too young for its boxes to have begun
    # falling is still too): their fall, then still.
    world = client.reload_world(False)
    for _ in range(60):
        world.tick()
    settle(world, carla.Location(x=12.0))
    world.spawn_actor(wall, carla.Transform(carla.Location(x=12.0, z=30.8))).set_enable_gravity(False)
    recipe = dict(dropoff_general_rate=0.0, dropoff_intensity_limit=1.0, dropoff_zero_intensity=0.0)
    shape = dict(channels=8, points_per_second=16000, rotation_frequency=20, upper_fov=5, lower_fov=-5,
                 range=50)
    lidars = [world.spawn_actor(blueprint(library, "sensor.lidar.ray_cast", **shape, **extra),
                                carla.Transform(carla.Location(z=2.0)))
              for extra in (recipe, {"noise_seed": 5}, {"noise_seed": 5}, {"noise_seed": 6})]
    scans = [queue.Queue() for _ in lidars]
    for lidar, q in zip(lidars, scans):
        lidar.listen(q.put)
    frame = world.tick()
    every, dropped, again, other = [q.get(timeout=10) for q in scans]
    assert all(isinstance(s, carla.LidarMeasurement) and s.frame == frame
               for s in (every, dropped, again, other))
    # 8 channels x 100 rays a turn; the wall fills most of the front half.
    assert 300 <= len(every) <= 800
    assert 0.4 * len(every) <= len(dropped) <= 0.6 * len(every)
    for p in dropped:
        assert p.intensity == pytest.approx(math.exp(-0.004 * p.point.length()), abs=1e-5)
    points = lambda scan: [(p.point.x, p.point.y, p.point.z) for p in scan]
    assert points(dropped) == points(again) != points(other)
    for lidar in lidars:
        lidar.stop()
        assert lidar.destroy()
    with pytest.raises(RuntimeError, match="dropoff_general_rate"):
        world.spawn_actor(blueprint(library, "sensor.lidar.ray_cast", dropoff_general_rate=1.5),
                          carla.Transform())


def test_a_sensor_goes_with_its_parent_and_is_destroyed_as_a_dying_actor(gateway):
    """A sensor ends with its parent (simbus ends it): from the frame the
    parent is gone, CARLA's client reads it as dying (`PendingKill`):
    `is_alive` false while the client still holds it, where it last was,
    and `destroy()` succeeds and removes it. (Absent from the world state,
    CARLA 0.9.16's client would read its state from uninitialised memory.)"""
    client, world, library = synced(gateway)
    car = world.spawn_actor(library.find("vehicle.tesla.model3"), carla.Transform(carla.Location(x=-20, z=1)))
    camera = world.spawn_actor(small_camera(library), carla.Transform(carla.Location(z=2)), attach_to=car)
    images = queue.Queue()
    camera.listen(images.put)
    frame = world.tick()
    assert images.get(timeout=10).frame == frame
    assert camera.is_alive and camera.parent.id == car.id
    last = camera.get_transform().location
    assert car.destroy()
    world.tick()
    assert not camera.is_alive
    assert camera.get_transform().location.distance(last) < 0.5
    assert camera.id in [a.id for a in world.get_actors()], "dying, still known"
    assert camera.destroy(), "destroying a dying sensor succeeds"
    world.tick()
    assert camera.id not in [a.id for a in world.get_actors()]


def test_a_sensor_destroyed_right_after_its_parent_is_destroyed(gateway):
    """Asynchronous mode, as after leaving synchronous mode: a sensor
    destroyed at once after its parent (before any world state says it
    went with it) is destroyed, ten times out of ten (it failed with
    "unknown sensor" when the server had ended it first)."""
    client = gateway.client()
    world = client.get_world()
    library = world.get_blueprint_library()
    for i in range(10):
        car = world.spawn_actor(library.find("vehicle.tesla.model3"),
                                carla.Transform(carla.Location(x=-20, y=5 * i, z=1)))
        gnss = world.spawn_actor(library.find("sensor.other.gnss"), carla.Transform(), attach_to=car)
        assert car.destroy()
        assert gnss.destroy(), i


@pytest.mark.parametrize("gateway", [["--scene", "empty"]], indirect=True)
def test_batches_answer_one_response_per_command_with_errors_per_command(gateway):
    client, world, library = synced(gateway)
    box = library.find("static.prop.box")
    SpawnActor, FutureActor = carla.command.SpawnActor, carla.command.FutureActor
    responses = client.apply_batch_sync([
        SpawnActor(box, carla.Transform(carla.Location(x=0, z=5))).then(
            carla.command.SetSimulatePhysics(FutureActor, False)),
        SpawnActor(box, carla.Transform(carla.Location(x=3, z=5))),
        carla.command.DestroyActor(424242),
        SpawnActor(library.find("vehicle.simbus.car"), carla.Transform(carla.Location(x=-10, z=1))),
    ], True)
    assert [bool(r.error) for r in responses] == [False, False, True, False]
    assert "424242" in responses[2].error and "unknown actor" in responses[2].error
    held, falling, car = responses[0].actor_id, responses[1].actor_id, responses[3].actor_id
    snapshot = world.get_snapshot()
    # `.then(SetSimulatePhysics(False))` held the first box where it spawned.
    assert snapshot.find(held).get_transform().location.z == pytest.approx(5.0)
    assert snapshot.find(falling).get_transform().location.z < 5.0
    responses = client.apply_batch_sync([
        carla.command.ApplyTransform(falling, carla.Transform(carla.Location(x=3, y=3, z=20))),
        carla.command.ApplyTargetVelocity(falling, carla.Vector3D(0, 0, 0)),
        carla.command.ApplyImpulse(falling, carla.Vector3D(0, 0, 1)),
        carla.command.ApplyVehicleControl(car, carla.VehicleControl(throttle=1.0)),
        carla.command.SetSimulatePhysics(held, True),
        carla.command.ApplyVehicleControl(held, carla.VehicleControl(throttle=1.0)),
        carla.command.ApplyWalkerControl(car, carla.WalkerControl()),
    ], True)
    errors = [r.error for r in responses]
    assert errors[:5] == ["", "", "", "", ""], errors
    assert "not a vehicle" in errors[5]
    assert "not a walker" in errors[6], errors[6]
    location = world.get_snapshot().find(falling).get_transform().location
    assert (round(location.x, 3), round(location.y, 3)) == (3.0, 3.0)
    # The asynchronous batch, with the tick it asks for (answered in order:
    # the next tick is the one after it).
    before = world.get_snapshot().frame
    client.apply_batch([carla.command.DestroyActor(falling)], True)
    assert world.tick() == before + 2
    assert world.get_snapshot().find(falling) is None


def actor_poses(world):
    return sorted(
        (a.id, a.get_transform().location.x, a.get_transform().location.y, a.get_transform().location.z,
         a.get_transform().rotation.pitch, a.get_transform().rotation.yaw, a.get_transform().rotation.roll)
        for a in world.get_actors())


def determinism_run(gateway):
    """The seeds' recipe: sync + fixed step, reload, apply_batch_sync."""
    client = gateway.client()
    world = client.get_world()
    sync(world)
    world = client.reload_world(False)
    library = world.get_blueprint_library()
    box = library.find("static.prop.box")
    sphere = library.find("static.prop.sphere")
    batch = [carla.command.SpawnActor(box if i % 2 else sphere,
                                      carla.Transform(carla.Location(x=i * 0.7, y=(i % 3) * 0.4, z=3 + i)))
             for i in range(12)]
    ids = [r.actor_id for r in client.apply_batch_sync(batch, True)]
    client.apply_batch_sync([carla.command.ApplyImpulse(i, carla.Vector3D(1.0, 0.5, 0.0)) for i in ids], True)
    for _ in range(100):
        world.tick()
    return world.get_snapshot().frame, actor_poses(world)


def test_the_determinism_recipe_gives_identical_transforms_on_two_servers(gateway_pair):
    a, b = gateway_pair
    frame_a, poses_a = determinism_run(a)
    frame_b, poses_b = determinism_run(b)
    assert frame_a == frame_b
    assert len(poses_a) > 12
    assert poses_a == poses_b


def error_of(result):
    """The message of CARLA's `Response<T>` error `[[0, [message]]]`."""
    assert result[0][0] == 0, result
    return result[0][1][0]


@pytest.mark.parametrize("gateway", [["--scene", "empty"]], indirect=True)
def test_bad_calls_get_errors_and_a_stream_reader_that_never_reads_is_dropped(gateway):
    raw = Raw(gateway.port)
    # Wrong argument types, an unknown blueprint, an unknown method, a
    # stream nobody has: each an error, and the connection goes on.
    assert "spawn_actor" in error_of(raw.call("spawn_actor", "not a description", 5))
    assert "vehicle.tesla.roadster" in error_of(
        raw.call("spawn_actor", [0, "vehicle.tesla.roadster", []], [[0, 0, 0], [0, 0, 0]]))
    assert "not supported by simbus" in error_of(raw.call("no_such_method"))
    assert "wrong shape" in error_of(raw.call("set_episode_settings", "fast please"))
    assert "no sensor" in error_of(raw.call("get_sensor_token", 1_000_000_999))
    # A batch answers per command (bare `[Response<ActorId>]`); a batch that
    # is not a list is an rpclib error (no result).
    walker = raw.call("apply_batch", [[[4, [1, [[0, 0, 0], 1.0, False]]]]], False)
    assert "unknown actor" in walker[0][0][1][0]
    assert raw.call("apply_batch", "not a list", False) is None
    # A spawn whose .then() holds another spawn: the first spawns, the
    # nested one is refused. Nesting 30 deep is past the gateway's depth
    # limit: that connection is dropped, the gateway lives on.
    def spawn_chain(depth):
        box = [0, "static.prop.box", []]
        place = [[0.0, 0.0, 50.0], [0.0, 0.0, 0.0]]
        chain = []
        for _ in range(depth):
            chain = [[[0, [box, place, [False], 0, "", chain]]]]
        return chain
    spawned = raw.call("apply_batch", spawn_chain(2), False)
    assert len(spawned) == 1 and spawned[0][0][0] == 1, spawned
    deep = Raw(gateway.port)
    with pytest.raises((AssertionError, ConnectionError)):
        deep.call("apply_batch", spawn_chain(30), False)
    assert raw.call("version") == [[1, "0.9.16"]]

    client = gateway.client()
    world = client.get_world()
    sync(world)
    camera = world.spawn_actor(small_camera(world.get_blueprint_library(), 640, 480), carla.Transform())
    images = queue.Queue()
    camera.listen(images.put)
    # A second reader of the camera's stream that never reads.
    token = raw.call("get_sensor_token", camera.id)[0][1][0]
    silent = socket.create_connection(("127.0.0.1", int.from_bytes(token[4:6], "little")))
    silent.sendall(camera.id.to_bytes(4, "little"))
    for _ in range(20):
        frame = world.tick()
        assert images.get(timeout=10).frame == frame
    # Its 1.2 MB images filled its socket: the gateway dropped it (the
    # buffered bytes, then the end of the stream).
    silent.settimeout(10)
    while silent.recv(1 << 20):
        pass
    camera.stop()


COLLISION = "Spawn failed because of collision at spawn position"


def test_a_spawn_into_another_body_fails_as_carla_says(gateway):
    """A vehicle spawned into the default scene's stack of boxes is refused
    with CARLA's own message (scripts such as generate_traffic.py skip an
    occupied spawn point by it): spawn_actor raises, try_spawn_actor
    answers None, a batch's SpawnActor answers the error for that command
    only, and nothing is spawned. (It was spawned inside the boxes.)"""
    client, world, library = synced(gateway)
    impala = library.find("vehicle.chevrolet.impala")
    inside = carla.Transform(carla.Location(x=5, y=0, z=0.2))
    before = sorted(a.id for a in world.get_actors())
    with pytest.raises(RuntimeError) as refused:
        world.spawn_actor(impala, inside)
    assert str(refused.value) == COLLISION
    assert world.try_spawn_actor(impala, inside) is None
    free = carla.Transform(carla.Location(x=-20, y=20, z=0.3))
    responses = client.apply_batch_sync([
        carla.command.SpawnActor(impala, inside),
        carla.command.SpawnActor(impala, free),
        carla.command.SpawnActor(impala, free),  # where the one before now is
    ], True)
    assert [r.error for r in responses] == [COLLISION, "", COLLISION]
    assert sorted(a.id for a in world.get_actors()) == sorted(before + [responses[1].actor_id])


def test_the_reverse_gear_drives_a_car_backwards(gateway):
    """`VehicleControl(reverse=True)`: the throttle drives backwards, and
    `get_control()` reads the gear back (manual_control.py's `Q` key)."""
    client, world, library = synced(gateway)
    car = world.spawn_actor(library.find("vehicle.tesla.model3"), carla.Transform(carla.Location(x=-20, z=1)))
    for _ in range(20):
        world.tick()
    start = car.get_location()
    car.apply_control(carla.VehicleControl(throttle=0.6, reverse=True))
    for _ in range(40):
        world.tick()
    assert car.get_control().reverse
    moved = car.get_location() - start
    forward = car.get_transform().get_forward_vector()
    assert moved.x * forward.x + moved.y * forward.y < -1.0, moved


def test_a_vehicles_lights_and_doors_answer_as_carla(gateway):
    """`set_light_state` / `get_light_state`, the batch's
    `SetVehicleLightState` (the traffic manager's `update_vehicle_lights`),
    `world.get_vehicles_light_states()`; `open_door` / `close_door`
    accepted."""
    client, world, library = synced(gateway)
    car = world.spawn_actor(library.find("vehicle.tesla.model3"), carla.Transform(carla.Location(x=-20, z=1)))
    other = world.spawn_actor(library.find("vehicle.audi.tt"), carla.Transform(carla.Location(x=-30, z=1)))
    world.tick()
    assert car.get_light_state() == carla.VehicleLightState.NONE
    beams = carla.VehicleLightState.LowBeam | carla.VehicleLightState.Position
    car.set_light_state(carla.VehicleLightState(beams))
    # (CARLA's binding turns the enum given into the flags it carries.)
    command = carla.command.SetVehicleLightState(other, carla.VehicleLightState.Brake)
    client.apply_batch_sync([command])
    world.tick()
    assert car.get_light_state() == carla.VehicleLightState(beams)
    states = dict(world.get_vehicles_light_states())
    assert states[car.id] == int(beams) and states[other.id] == command.light_state
    car.open_door(carla.VehicleDoor.FL)
    car.close_door(carla.VehicleDoor.All)
    world.tick()
    assert car.is_alive


def test_ackermann_control_drives_a_car_to_its_speed_and_steering(gateway):
    """`apply_ackermann_control(carla.VehicleAckermannControl(...))`: the
    car reaches the speed asked for at the acceleration asked for and
    turns its way (CARLA's steer: radians, positive right); the controller
    settings read back as set."""
    client, world, library = synced(gateway)
    # Clear of the scene's ramp and boxes for 40 m ahead.
    car = world.spawn_actor(library.find("vehicle.tesla.model3"),
                            carla.Transform(carla.Location(x=-40, y=25, z=1)))
    for _ in range(20):
        world.tick()
    car.apply_ackermann_control(carla.VehicleAckermannControl(speed=5.0, acceleration=2.0))
    for _ in range(100):
        world.tick()
    assert abs(car.get_velocity().length() - 5.0) < 0.5, car.get_velocity()
    yaw = car.get_transform().rotation.yaw
    car.apply_ackermann_control(carla.VehicleAckermannControl(steer=0.3, steer_speed=1.0, speed=5.0))
    for _ in range(40):
        world.tick()
    turned = car.get_transform().rotation.yaw - yaw
    assert 10.0 < (turned + 360.0) % 360.0 < 180.0, turned  # to the right
    settings = car.get_ackermann_controller_settings()
    assert abs(settings.speed_kp - 0.15) < 1e-6
    car.apply_ackermann_controller_settings(carla.AckermannControllerSettings(speed_kp=0.3))
    assert abs(car.get_ackermann_controller_settings().speed_kp - 0.3) < 1e-6
    client.apply_batch_sync([carla.command.ApplyVehicleAckermannControl(
        car, carla.VehicleAckermannControl(speed=0.0))])
    for _ in range(80):
        world.tick()
    assert car.get_velocity().length() < 0.2
