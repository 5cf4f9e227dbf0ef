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


def test_debug_drawing_is_kept_for_its_life_time_in_simulation_time(gateway):
    """`world.debug.draw_*` as CARLA's scripts call them (`draw_point`,
    `draw_line`, `draw_arrow`, `draw_box`, `draw_string`, `draw_hud_point`):
    each shape is shown from the next frame, in simbus's axes, for its
    `life_time` in simulation time (below 0: one frame; 0: for good), then
    gone; what the Foxglove view and a recording's scene draw."""
    import simbus

    client, world = synced(gateway)
    native = simbus.connect(gateway.world, timeout=10.0)
    debug = world.debug
    green = carla.Color(0, 255, 0)
    debug.draw_point(carla.Location(10.0, 2.0, 1.0), 0.2, green, 1.0)
    debug.draw_line(carla.Location(0, 0, 0), carla.Location(5, 0, 0), 0.1, green, 0.0)
    debug.draw_arrow(carla.Location(0, 0, 1), carla.Location(0, 5, 1), 0.1, 0.2, green, -1.0)
    box = carla.BoundingBox(carla.Location(3, 0, 1), carla.Vector3D(1, 2, 0.5))
    debug.draw_box(box, carla.Rotation(0, 90, 0), 0.05, green, 2.0)
    debug.draw_string(carla.Location(0, 0, 3), "spawn 7", False, green, 1.0)
    debug.draw_hud_point(carla.Location(1, 1, 1), 0.1, green, 1.0)
    world.tick()
    kinds = sorted(s["kind"] for s in native.debug_shapes())
    assert kinds == ["arrow", "box", "line", "point", "point", "text"], kinds
    point = next(s for s in native.debug_shapes() if s["kind"] == "point" and s["size"] > 0.15)
    # CARLA (x, y, z) is simbus (x, z, y).
    assert point["a"] == [10.0, 1.0, 2.0] and point["color"] == [0, 255, 0, 255]
    assert [s["text"] for s in native.debug_shapes() if s["kind"] == "text"] == ["spawn 7"]
    world.tick()
    # The one-frame arrow is gone.
    assert sorted(s["kind"] for s in native.debug_shapes()) == ["box", "line", "point", "point", "text"]
    for _ in range(20):
        world.tick()
    # 1.05 s later: the 1 s shapes are gone, the 2 s box and the line stay.
    assert sorted(s["kind"] for s in native.debug_shapes()) == ["box", "line"]
    for _ in range(20):
        world.tick()
    assert [s["kind"] for s in native.debug_shapes()] == ["line"]
    native.clear_debug_shapes()
    world.tick()
    assert native.debug_shapes() == []
