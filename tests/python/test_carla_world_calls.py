"""World calls CARLA scripts make that once were silent no-ops, with the
real `carla` wheel: the weather is kept and answered back, and
`enable_constant_velocity` holds a vehicle at a velocity in its own axes."""

import math

import carla
import pytest

from conftest import synced


def test_the_weather_a_script_sets_is_the_weather_it_gets(gateway):
    world = gateway.client().get_world()
    assert world.get_weather() == carla.WeatherParameters.ClearNoon
    storm = carla.WeatherParameters(cloudiness=80.0, precipitation=30.0, sun_altitude_angle=10.0,
                                    sun_azimuth_angle=135.0, wind_intensity=40.0, fog_density=5.0)
    world.set_weather(storm)
    assert world.get_weather() == storm
    # Another client of the gateway sees the same sky.
    assert gateway.client().get_world().get_weather() == storm
    world.set_weather(carla.WeatherParameters.HardRainSunset)
    assert world.get_weather() == carla.WeatherParameters.HardRainSunset


@pytest.mark.parametrize("gateway", [["--scene", "flat"]], indirect=True)
def test_a_constant_velocity_holds_along_the_vehicles_heading(gateway):
    client, world = synced(gateway)
    blueprint = world.get_blueprint_library().find("vehicle.tesla.model3")
    # Facing +y (yaw 90): the velocity is in the vehicle's own axes.
    car = world.spawn_actor(blueprint, carla.Transform(carla.Location(x=10.0, y=0.0, z=0.6),
                                                       carla.Rotation(yaw=90.0)))
    for _ in range(10):
        world.tick()
    start = car.get_location()
    car.enable_constant_velocity(carla.Vector3D(5.0, 0.0, 0.0))
    for _ in range(20):
        world.tick()
    held = car.get_location()
    velocity = car.get_velocity()
    # One second at 5 m/s along +y; nothing sideways.
    assert abs((held.y - start.y) - 5.0) < 0.3, (start, held)
    assert abs(held.x - start.x) < 0.1, (start, held)
    assert abs(velocity.y - 5.0) < 0.1 and abs(velocity.x) < 0.1, velocity
    car.disable_constant_velocity()
    car.apply_control(carla.VehicleControl(brake=1.0))
    for _ in range(40):
        world.tick()
    assert car.get_velocity().length() < 1.0, "let go, the brakes stop it"
