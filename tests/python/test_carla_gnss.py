"""`sensor.other.gnss` through the gateway, with the real `carla==0.9.16`
client: a receiver on a vehicle reads, at every tick, the place CARLA's own
client computes for the sensor's location from the map's geographic
reference (`Map.transform_to_geolocation`, the same projection as CARLA's
GNSS sensor); its noise attributes work as CARLA's and repeat with
`noise_seed`; bad noise is refused."""

import queue

import carla
import pytest

from test_carla_actors_sensors import blueprint, sync

TOWN = [["--scene", "town"]]


def gnss_on_a_car(world, **attributes):
    """A model3 on the town's first spawn point, held still, with a GNSS
    receiver 1 m above it listening into a queue."""
    library = world.get_blueprint_library()
    car = world.spawn_actor(library.find("vehicle.tesla.model3"), world.get_map().get_spawn_points()[0])
    car.set_simulate_physics(False)
    receiver = world.spawn_actor(
        blueprint(library, "sensor.other.gnss", **attributes),
        carla.Transform(carla.Location(z=1.0)), attach_to=car)
    readings = queue.Queue()
    receiver.listen(readings.put)
    return car, receiver, readings


@pytest.mark.parametrize("gateway", TOWN, indirect=True)
def test_a_receiver_reads_what_the_maps_projection_says_frame_by_frame(gateway):
    client = gateway.client()
    world = client.get_world()
    sync(world)
    town = world.get_map()
    car, receiver, readings = gnss_on_a_car(world)
    start = town.get_spawn_points()[0]
    for step in range(5):
        # 25 m further along the road each tick.
        at = carla.Transform(start.location + start.get_forward_vector() * (25.0 * step), start.rotation)
        car.set_transform(at)
        frame = world.tick()
        reading = readings.get(timeout=10)
        assert isinstance(reading, carla.GnssMeasurement)
        assert reading.frame == frame
        where = receiver.get_transform().location
        expected = town.transform_to_geolocation(where)
        assert reading.latitude == pytest.approx(expected.latitude, abs=1e-7)
        assert reading.longitude == pytest.approx(expected.longitude, abs=1e-7)
        assert reading.altitude == pytest.approx(expected.altitude, abs=1e-3)
    receiver.stop()
    assert receiver.destroy() and car.destroy()


def noisy_run(gateway, seed):
    client = gateway.client()
    world = client.get_world()
    sync(world)
    car, receiver, readings = gnss_on_a_car(
        world, noise_lat_stddev=1e-5, noise_lon_stddev=1e-5, noise_alt_stddev=0.5,
        noise_alt_bias=10.0, noise_seed=seed)
    got = []
    for _ in range(10):
        world.tick()
        r = readings.get(timeout=10)
        got.append((r.latitude, r.longitude, r.altitude))
    receiver.stop()
    receiver.destroy()
    car.destroy()
    return got


@pytest.mark.parametrize("gateway", TOWN, indirect=True)
def test_noise_repeats_with_its_seed_and_bad_noise_is_refused(gateway):
    a, b, c = noisy_run(gateway, 7), noisy_run(gateway, 7), noisy_run(gateway, 8)
    assert a == b and a != c
    assert len({alt for _, _, alt in a}) > 1, "noisy altitudes"
    world = gateway.client().get_world()
    library = world.get_blueprint_library()
    for name, value in [("noise_lat_stddev", "-1"), ("noise_seed", "-3")]:
        with pytest.raises(RuntimeError, match="GNSS biases must be finite"):
            world.spawn_actor(blueprint(library, "sensor.other.gnss", **{name: value}), carla.Transform())
