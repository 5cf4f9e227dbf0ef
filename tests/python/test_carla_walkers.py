"""CARLA 0.9.16's own client spawns CARLA's pedestrians through the
gateway, as its scripts do: a `walker.pedestrian.*` blueprint at a point
on the ground stands on it with its blueprint's size, walks as
`walker.apply_control(carla.WalkerControl(...))` and
`carla.command.ApplyWalkerControl` say, goes where
`carla.command.ApplyWalkerState` (what CARLA's walker AI sends every tick)
puts its feet, and carries a `controller.ai.walker` whose `start()` and
`stop()` are answered; a controller on nothing or on a car is refused."""

import math

import carla
import pytest

from conftest import synced

FLAT = [["--scene", "flat"]]


def tick(world, n=1):
    for _ in range(n):
        frame = world.tick()
    return frame


@pytest.mark.parametrize("gateway", FLAT, indirect=True)
def test_a_pedestrian_stands_walks_and_carries_its_controller(gateway):
    client, world = synced(gateway)
    library = world.get_blueprint_library()
    adult = library.find("walker.pedestrian.0001")
    assert adult.get_attribute("speed").recommended_values[1:] == ["1.4", "2.5"]
    # Where CARLA's navigation puts walkers: on the ground (z = 0).
    walker = world.spawn_actor(adult, carla.Transform(carla.Location(x=2.0, y=3.0, z=0.0)))
    tick(world, 5)
    assert walker.type_id == "walker.pedestrian.0001"
    assert isinstance(walker, carla.Walker)
    standing = walker.get_location()
    assert abs(standing.z - 0.9375) < 0.05, standing
    assert abs(walker.bounding_box.extent.z - 0.9375) < 1e-3

    # 1.4 m/s along CARLA's +y for 1 s.
    walker.apply_control(carla.WalkerControl(carla.Vector3D(0.0, 1.0, 0.0), 1.4))
    tick(world, 20)
    walked = walker.get_location()
    assert abs(walked.y - standing.y - 1.4) < 0.12, walked
    assert abs(walked.x - standing.x) < 0.05 and abs(walked.z - standing.z) < 0.05
    assert abs(walker.get_transform().rotation.yaw - 90.0) < 1.0

    # The same through a batch, back along -y at 2 m/s for 0.5 s.
    client.apply_batch_sync([carla.command.ApplyWalkerControl(
        walker, carla.WalkerControl(carla.Vector3D(0.0, -1.0, 0.0), 2.0))])
    tick(world, 10)
    back = walker.get_location()
    assert abs(walked.y - back.y - 1.0) < 0.12, back

    controller = world.spawn_actor(
        library.find("controller.ai.walker"), carla.Transform(), walker)
    tick(world)
    assert controller.type_id == "controller.ai.walker"
    assert controller.parent.id == walker.id
    # What CARLA's walker AI sends every tick: where the walker's feet are
    # (the walker stopped first: its control holds).
    walker.apply_control(carla.WalkerControl(carla.Vector3D(0.0, -1.0, 0.0), 0.0))
    client.apply_batch_sync([carla.command.ApplyWalkerState(
        walker, carla.Transform(carla.Location(x=10.0, y=-4.0, z=0.0), carla.Rotation(yaw=-90.0)),
        1.2)])
    tick(world)
    placed = walker.get_transform()
    assert math.dist((placed.location.x, placed.location.y), (10.0, -4.0)) < 1e-3, placed
    assert abs(placed.location.z - 0.9375) < 0.02, placed
    assert abs(placed.rotation.yaw + 90.0) < 0.5, placed
    # start() turns the walker's physics and collisions off (two calls the
    # gateway answers) and hands it to the AI, which keeps it where it is
    # until told where to go.
    controller.start()
    tick(world, 5)
    held = walker.get_location()
    assert math.dist((held.x, held.y), (10.0, -4.0)) < 0.5, held
    controller.stop()
    assert controller.destroy()
    assert walker.destroy()
    tick(world)
    assert not [a for a in world.get_actors() if a.type_id.startswith("walker.")]


@pytest.mark.parametrize("gateway", FLAT, indirect=True)
def test_a_walker_controller_on_nothing_or_a_car_is_refused(gateway):
    client, world = synced(gateway)
    library = world.get_blueprint_library()
    controller = library.find("controller.ai.walker")
    with pytest.raises(RuntimeError, match="attached to its walker"):
        world.spawn_actor(controller, carla.Transform())
    car = world.spawn_actor(library.find("vehicle.simbus.car"), carla.Transform(carla.Location(z=1.0)))
    tick(world)
    with pytest.raises(RuntimeError, match=f"actor {car.id} is not one"):
        world.spawn_actor(controller, carla.Transform(), car)
    # A pedestrian where the car is: CARLA's collision refusal.
    with pytest.raises(RuntimeError, match="collision"):
        world.spawn_actor(library.find("walker.pedestrian.0002"), carla.Transform(carla.Location(z=1.0)))
    results = client.apply_batch_sync([carla.command.ApplyWalkerControl(
        car, carla.WalkerControl(carla.Vector3D(1.0, 0.0, 0.0), 1.0))])
    assert "not a walker" in results[0].error


TOWN = [["--scene", "town"]]


@pytest.mark.parametrize("gateway", TOWN, indirect=True)
def test_generate_traffics_walkers_find_sidewalks_and_walk_them(gateway):
    """generate_traffic.py's walker section (CARLA 0.9.16), its calls in
    its order: random locations from the navigation (the mesh the gateway
    serves from the town's roads), walkers spawned there in one batch and
    their AI controllers in another, a tick, the crossing factor, then
    each controller started, sent to another random location and given
    its walking speed; 200 ticks. Every location is on a sidewalk, and
    the walkers walk (CARLA's client walks them and sends their feet)."""
    client, world = synced(gateway)
    town = world.get_map()
    world.set_pedestrians_seed(7)
    library = world.get_blueprint_library()
    walker_bps = [bp for bp in library.filter("walker.pedestrian.*")
                  if int(bp.get_attribute("generation")) == 2]
    spawn_points = []
    for _ in range(10):
        location = world.get_random_location_from_navigation()
        assert location is not None, "the navigation answers a point"
        spawn_points.append(carla.Transform(location))
    for point in spawn_points:
        # On the ground, off the driving lanes.
        assert abs(point.location.z) < 0.01, point.location
        lane = town.get_waypoint(point.location, project_to_road=False,
                                 lane_type=carla.LaneType.Driving)
        assert lane is None, (point.location, lane)
    batch, speeds = [], []
    for i, point in enumerate(spawn_points):
        bp = walker_bps[i % len(walker_bps)]
        bp.set_attribute("is_invincible", "false")
        speeds.append(bp.get_attribute("speed").recommended_values[1])
        batch.append(carla.command.SpawnActor(bp, point))
    results = client.apply_batch_sync(batch, True)
    walkers = [r.actor_id for r in results if not r.error]
    assert len(walkers) >= 8, [r.error for r in results]
    controller_bp = library.find("controller.ai.walker")
    results = client.apply_batch_sync(
        [carla.command.SpawnActor(controller_bp, carla.Transform(), w) for w in walkers], True)
    controllers = [r.actor_id for r in results]
    assert all(not r.error for r in results), [r.error for r in results]
    world.tick()
    world.set_pedestrians_cross_factor(0.0)
    actors = world.get_actors(controllers + walkers)
    by_id = {a.id: a for a in actors}
    for controller, speed in zip(controllers, speeds):
        by_id[controller].start()
        by_id[controller].go_to_location(world.get_random_location_from_navigation())
        by_id[controller].set_max_speed(float(speed))
    start = {w: by_id[w].get_location() for w in walkers}
    for _ in range(200):
        world.tick()
    moved = [start[w].distance(by_id[w].get_location()) for w in walkers]
    assert sum(m > 2.0 for m in moved) >= len(walkers) - 1, moved
    for w in walkers:
        at = by_id[w].get_location()
        assert abs(at.z - by_id[w].bounding_box.extent.z) < 0.1, at
        assert town.get_waypoint(at, project_to_road=False,
                                 lane_type=carla.LaneType.Driving) is None, at
    for controller in controllers:
        by_id[controller].stop()
    client.apply_batch([carla.command.DestroyActor(x) for x in controllers + walkers])


SKELETON = [  # the bones draw_skeleton.py joins, by name
    "crl_hips__C", "crl_spine__C", "crl_spine01__C", "crl_neck__C", "crl_Head__C",
    "crl_eye__L", "crl_eye__R", *[f"crl_{b}__{s}" for s in "LR" for b in (
        "shoulder", "arm", "foreArm", "hand", "thigh", "leg", "foot", "toe", "toeEnd",
        *[f"hand{f}{j}" for f in ("Thumb", "Index", "Middle", "Ring", "Pinky")
          for j in ("", "01", "02", "End")])],
]


@pytest.mark.parametrize("gateway", [["--scene", "town"]], indirect=True)
def test_draw_skeleton_gets_a_walkers_bones_every_tick(gateway):
    """draw_skeleton.py's calls, in its order: a camera, a pedestrian at a
    navigation point with its AI controller walking it, then every tick
    (30 FPS, synchronous) `blend_pose`, the camera moved round the walker,
    and `get_bones()`: every bone it draws is there, on the walker (feet
    on the ground, head at its height), in front of the camera."""
    client = gateway.client()
    world = client.get_world()
    library = world.get_blueprint_library()
    camera_bp = library.find("sensor.camera.rgb")
    for name, value in (("image_size_x", "160"), ("image_size_y", "120"), ("fov", "60")):
        camera_bp.set_attribute(name, value)
    camera = world.spawn_actor(camera_bp, carla.Transform())
    world.set_pedestrians_seed(1235)
    ped_bp = library.find("walker.pedestrian.0001")
    trans = carla.Transform()
    trans.location = world.get_random_location_from_navigation()
    trans.location.z += 1
    ped = world.spawn_actor(ped_bp, trans)
    controller = world.spawn_actor(library.find("controller.ai.walker"), carla.Transform(), ped)
    controller.start()
    controller.go_to_location(world.get_random_location_from_navigation())
    controller.set_max_speed(1.7)
    settings = world.get_settings()
    world.apply_settings(carla.WorldSettings(
        no_rendering_mode=False, synchronous_mode=True, fixed_delta_seconds=1.0 / 30))
    try:
        blending, turning = 0.0, 0.0
        for _ in range(30):
            ped.blend_pose(math.sin(blending))
            blending += 0.015
            turning += 0.009
            view = ped.get_transform()
            view.location.x += math.cos(turning) * -3
            view.location.y += math.sin(turning) * 3
            view.location.z = 2
            view.rotation = carla.Rotation(pitch=-16, yaw=-360 * (turning / (math.pi * 2)))
            camera.set_transform(view)
            world.tick()
            bones = ped.get_bones()
            names = [bone.name for bone in bones.bone_transforms]
            assert set(SKELETON) <= set(names)
            world_points = {b.name: b.world.location for b in bones.bone_transforms}
            at = ped.get_location()
            feet, head = world_points["crl_foot__L"], world_points["crl_Head__C"]
            assert math.dist((feet.x, feet.y), (at.x, at.y)) < 0.5
            assert abs(feet.z - (at.z - 0.9375)) < 0.15 and head.z > at.z + 0.5
            # In front of the camera, as the script projects them.
            to_camera = camera.get_transform().get_inverse_matrix()
            ahead = [sum(r * c for r, c in zip(row, (p.x, p.y, p.z, 1.0)))
                     for p in world_points.values() for row in to_camera[:1]]
            assert min(ahead) > 0.5, min(ahead)
        ped.show_pose()
        ped.hide_pose()
        ped.get_pose_from_animation()
        ped.set_bones(carla.WalkerBoneControlIn([("crl_hand__R", carla.Transform())]))
    finally:
        world.apply_settings(settings)
        controller.stop()
