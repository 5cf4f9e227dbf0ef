"""CARLA 0.9.16's vehicle catalogue through the gateway: every `vehicle.*`
blueprint is listed with CARLA's attributes and spawns as a simbus
ray-cast vehicle of that model's size and mass (`get_bounding_box`,
`get_physics_control`) that drives forward; walkers are listed and refused
at spawn; every actor reported (scene ones included) carries CARLA's
attributes (`role_name`, `number_of_wheels`)."""

import carla
import pytest

from conftest import synced

VEHICLE_ATTRIBUTES = [
    "base_type", "number_of_wheels", "generation", "object_type", "special_type",
    "has_dynamic_doors", "has_lights", "role_name", "sticky_control", "terramechanics",
]


def test_every_carla_vehicle_is_listed_with_carlas_attributes(gateway):
    library = gateway.client().get_world().get_blueprint_library()
    assert [bp.id for bp in library.filter("model3")] == ["vehicle.tesla.model3"]
    mkz = library.find("vehicle.lincoln.mkz_2020")
    assert mkz.has_tag("lincoln")
    assert {bp.id for bp in library.filter("tt")} == {"vehicle.audi.tt"}
    vehicles = library.filter("vehicle.*")
    # CARLA 0.9.16's 41 vehicles and simbus's own.
    assert len(vehicles) == 42
    # simbus's 3 props and 16 sensors, 51 walkers, the walker controller.
    assert len(library.filter("*")) == len(vehicles) + 3 + 16 + 51 + 1
    for bp in vehicles:
        for name in VEHICLE_ATTRIBUTES:
            assert bp.has_attribute(name), (bp.id, name)
        assert bp.get_attribute("generation").as_int() in (1, 2)
    model3 = library.find("vehicle.tesla.model3")
    assert model3.get_attribute("base_type").as_str() == "car"
    assert model3.get_attribute("number_of_wheels").as_int() == 4
    assert model3.get_attribute("role_name").as_str() == "autopilot"
    colors = model3.get_attribute("color").recommended_values
    assert len(colors) > 1
    model3.set_attribute("color", colors[2])
    assert library.find("vehicle.yamaha.yzf").get_attribute("number_of_wheels").as_int() == 2
    assert library.find("vehicle.yamaha.yzf").get_attribute("driver_id").recommended_values
    assert library.find("vehicle.carlamotors.firetruck").get_attribute("base_type").as_str() == "truck"
    with pytest.raises(ValueError, match="read-only"):
        model3.set_attribute("number_of_wheels", "3")
    # generate_traffic.py's filter: generation-2 walkers, even for none.
    walkers = [bp for bp in library.filter("walker.pedestrian.*")
               if bp.get_attribute("generation").as_int() == 2]
    assert walkers and all(bp.has_attribute("speed") for bp in walkers)
    assert library.find("walker.pedestrian.0001").get_attribute("is_invincible").as_bool()
    assert library.find("controller.ai.walker").id == "controller.ai.walker"


@pytest.mark.parametrize("gateway", [["--scene", "flat"]], indirect=True)
def test_catalog_vehicles_have_their_models_size_and_mass_and_drive(gateway):
    client, world = synced(gateway)
    library = world.get_blueprint_library()
    models = {
        "vehicle.tesla.model3": ((2.3959, 1.0817, 0.7438), 1850.0),
        "vehicle.carlamotors.firetruck": ((4.2340, 1.4455, 1.9137), 14000.0),
        "vehicle.kawasaki.ninja": ((1.0218, 0.3985, 0.7616), 280.0),
    }
    spawned = {}
    for i, type_id in enumerate(models):
        bp = library.find(type_id)
        bp.set_attribute("role_name", "hero")
        at = carla.Transform(carla.Location(x=-30 + 30 * i, y=10 * i, z=0.5))
        spawned[type_id] = world.spawn_actor(bp, at)
    for _ in range(20):
        world.tick()
    for type_id, ((x, y, z), mass) in models.items():
        vehicle = spawned[type_id]
        assert vehicle.type_id == type_id
        assert vehicle.attributes["role_name"] == "hero"
        extent = vehicle.bounding_box.extent
        assert (extent.x, extent.y, extent.z) == pytest.approx((x, y, z), abs=1e-4), type_id
        extent = world.get_actor(vehicle.id).bounding_box.extent
        assert abs(extent.x - x) < 1e-3, type_id
        physics = vehicle.get_physics_control()
        assert physics.mass == pytest.approx(mass)
        assert len(physics.wheels) == 4
        front, rear = physics.wheels[0], physics.wheels[2]
        # Wheels in the world, in centimetres: the front ahead of the rear.
        assert front.position.x > rear.position.x + 100 * x * 0.5, type_id
        assert front.max_steer_angle > 0 and rear.max_steer_angle == 0
    car = spawned["vehicle.tesla.model3"]
    # CARLA's client sends apply_physics_control without waiting for the
    # answer: simbus refuses it (and logs so), the vehicle keeps its mass.
    physics = car.get_physics_control()
    physics.mass = 1.0
    car.apply_physics_control(physics)
    world.tick()
    assert car.get_physics_control().mass == pytest.approx(1850.0)
    start = car.get_location()
    car.apply_control(carla.VehicleControl(throttle=1.0))
    for _ in range(20):
        world.tick()
    moved = car.get_location() - start
    # 1 s at full throttle: forward (+x, the way it faces), metres of it.
    assert moved.x > 1.0 and abs(moved.y) < 0.5 * moved.x
    vehicles = {a.id: a.type_id for a in world.get_actors().filter("vehicle.*")}
    assert vehicles == {v.id: t for t, v in spawned.items()}


@pytest.mark.parametrize("gateway", [["--scene", "flat"]], indirect=True)
def test_walkers_and_their_controllers_spawn_in_batches_as_generate_traffic_spawns_them(gateway):
    """generate_traffic.py's calls: walkers in one batch (its `speed`
    attribute read from the blueprint), then one `controller.ai.walker` per
    walker, attached to it, in a second batch; a box beside them."""
    client, world = synced(gateway)
    library = world.get_blueprint_library()
    walkers = [bp for bp in library.filter("walker.pedestrian.*")
               if int(bp.get_attribute("generation")) == 2][:3]
    speeds = [float(bp.get_attribute("speed").recommended_values[1]) for bp in walkers]
    assert speeds == [1.4, 1.4, 1.4]
    box = library.find("static.prop.box")
    responses = client.apply_batch_sync(
        [carla.command.SpawnActor(bp, carla.Transform(carla.Location(x=3.0 * i, y=4.0)))
         for i, bp in enumerate(walkers)]
        + [carla.command.SpawnActor(box, carla.Transform(carla.Location(x=5, y=-5, z=1)))], True)
    assert not any(r.has_error() for r in responses), [r.error for r in responses]
    walker_ids = [r.actor_id for r in responses[:3]]
    controller = library.find("controller.ai.walker")
    responses = client.apply_batch_sync(
        [carla.command.SpawnActor(controller, carla.Transform(), w) for w in walker_ids], True)
    assert not any(r.has_error() for r in responses), [r.error for r in responses]
    actors = world.get_actors(walker_ids + [r.actor_id for r in responses])
    by_id = {a.id: a for a in actors}
    assert sorted(by_id[w].type_id for w in walker_ids) == sorted(bp.id for bp in walkers)
    for walker, response in zip(walker_ids, responses):
        assert by_id[response.actor_id].type_id == "controller.ai.walker"
        assert by_id[response.actor_id].parent.id == walker
        assert abs(by_id[walker].get_location().z - 0.9375) < 0.05


def test_scene_and_spawned_actors_carry_carlas_attributes(gateway):
    client, world = synced(gateway)
    library = world.get_blueprint_library()
    bp = library.find("vehicle.audi.tt")
    bp.set_attribute("role_name", "hero")
    hero = world.spawn_actor(bp, carla.Transform(carla.Location(x=20, y=-20, z=0.5)))
    world.tick()
    actors = world.get_actors()
    boxes = actors.filter("static.prop.box")
    assert boxes, "the default scene has boxes"
    for box in boxes:
        assert box.attributes["role_name"] == ""
    vehicles = actors.filter("vehicle.*")
    scene = [v for v in vehicles if v.type_id == "vehicle.simbus.car"]
    assert scene, "the default scene has vehicles"
    for vehicle in vehicles:
        assert int(vehicle.attributes["number_of_wheels"]) == 4
        assert "role_name" in vehicle.attributes
    assert world.get_actor(hero.id).attributes["role_name"] == "hero"
    assert {v.type_id for v in vehicles} == {"vehicle.simbus.car", "vehicle.audi.tt"}


def test_every_sensor_attribute_a_script_may_set_recommends_its_default(gateway):
    """visualize_multiple_sensors.py and raycast_sensor_testing.py read
    `recommended_values[0]` of the lidar's attributes (as CARLA's sensor
    attributes recommend their default, so do simbus's)."""
    library = gateway.client().get_world().get_blueprint_library()
    lidar = library.find("sensor.lidar.ray_cast")
    rate = lidar.get_attribute("dropoff_general_rate")
    assert rate.recommended_values == ["0.45"] and abs(rate.as_float() - 0.45) < 1e-6
    lidar.set_attribute("dropoff_general_rate", rate.recommended_values[0])

    def value(attribute, text):
        kind = attribute.type
        if kind == carla.ActorAttributeType.Float:
            # as_float() reads the value as a C++ float.
            return round(float(text) if text is not None else attribute.as_float(), 5)
        if kind == carla.ActorAttributeType.Int:
            return int(text) if text is not None else attribute.as_int()
        if kind == carla.ActorAttributeType.Bool:
            return text in ("true", "True") if text is not None else attribute.as_bool()
        return text if text is not None else attribute.as_str()

    for bp in library.filter("sensor.*"):
        for attribute in bp:
            if attribute.is_modifiable:
                recommended = attribute.recommended_values
                assert recommended, (bp.id, attribute.id)
                assert value(attribute, recommended[0]) == value(attribute, None), (bp.id, attribute.id)
