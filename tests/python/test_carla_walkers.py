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
    # start() turns the walker's physics and collisions off (two calls the
    # gateway answers); the walker then goes where the AI puts its feet.
    controller.start()
    client.apply_batch_sync([carla.command.ApplyWalkerState(
        walker, carla.Transform(carla.Location(x=10.0, y=-4.0, z=0.0), carla.Rotation(yaw=-90.0)),
        1.2)])
    tick(world)
    placed = walker.get_transform()
    assert math.dist((placed.location.x, placed.location.y), (10.0, -4.0)) < 1e-3, placed
    assert abs(placed.location.z - 0.9375) < 1e-3, placed
    assert abs(placed.rotation.yaw + 90.0) < 0.5, placed
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
