"""The seeds' determinism example (docs `adv_synchrony_timestep`, the
traffic manager section), run as its own process against a gateway:

    client.load_world("Town10HD_Opt")
    settings: synchronous_mode = True, fixed_delta_seconds = 0.05
    client.reload_world(False)
    traffic_manager = client.get_trafficmanager(TM_PORT)
    traffic_manager.set_synchronous_mode(True)
    traffic_manager.set_random_device_seed(SEED)
    # spawn vehicles: generate_traffic.py's batch, SpawnActor.then(SetAutopilot)
    while ...: world.tick()

Prints one JSON object: per tick, every vehicle's (id, x, y, z, yaw)."""

import argparse
import json
import random

import carla


def main():
    parser = argparse.ArgumentParser()
    parser.add_argument("--port", type=int, required=True)
    parser.add_argument("--tm-port", type=int, required=True)
    parser.add_argument("--seed", type=int, default=42)
    parser.add_argument("--vehicles", type=int, default=30)
    parser.add_argument("--ticks", type=int, default=500)
    parser.add_argument("--map", default="Town10HD_Opt")
    parser.add_argument("--walkers", type=int, default=0)
    args = parser.parse_args()
    client = carla.Client("127.0.0.1", args.port)
    client.set_timeout(10.0)
    world = client.get_world()
    client.load_world(args.map)

    world = client.get_world()
    new_settings = world.get_settings()
    new_settings.synchronous_mode = True
    new_settings.fixed_delta_seconds = 0.05
    world.apply_settings(new_settings)

    client.reload_world(False)
    world = client.get_world()

    traffic_manager = client.get_trafficmanager(args.tm_port)
    traffic_manager.set_synchronous_mode(True)
    traffic_manager.set_random_device_seed(args.seed)
    traffic_manager.set_global_distance_to_leading_vehicle(2.5)
    traffic_manager.global_percentage_speed_difference(-20.0)
    random.seed(args.seed)

    blueprints = world.get_blueprint_library().filter("vehicle.*")
    blueprints = sorted(blueprints, key=lambda bp: bp.id)
    spawn_points = world.get_map().get_spawn_points()
    random.shuffle(spawn_points)
    batch = []
    for transform in spawn_points[: args.vehicles]:
        blueprint = random.choice(blueprints)
        blueprint.set_attribute("role_name", "autopilot")
        batch.append(
            carla.command.SpawnActor(blueprint, transform).then(
                carla.command.SetAutopilot(carla.command.FutureActor, True, traffic_manager.get_port())
            )
        )
    ids = []
    for response in client.apply_batch_sync(batch, True):
        if response.error:
            raise SystemExit(f"spawn failed: {response.error}")
        ids.append(response.actor_id)

    # generate_traffic.py's walkers: navigation points, AI controllers
    # (CARLA's client walks them), seeded.
    walkers = []
    if args.walkers:
        world.set_pedestrians_seed(args.seed)
        walker_bps = sorted(world.get_blueprint_library().filter("walker.pedestrian.*"),
                            key=lambda bp: bp.id)
        batch = [carla.command.SpawnActor(random.choice(walker_bps),
                                          carla.Transform(world.get_random_location_from_navigation()))
                 for _ in range(args.walkers)]
        walkers = [r.actor_id for r in client.apply_batch_sync(batch, True) if not r.error]
        controller = world.get_blueprint_library().find("controller.ai.walker")
        results = client.apply_batch_sync(
            [carla.command.SpawnActor(controller, carla.Transform(), w) for w in walkers], True)
        world.tick()
        world.set_pedestrians_cross_factor(0.0)
        for ai in world.get_actors([r.actor_id for r in results]):
            ai.start()
            ai.go_to_location(world.get_random_location_from_navigation())
            ai.set_max_speed(1.4)
    ticks = []
    for _ in range(args.ticks):
        world.tick()
        snapshot = world.get_snapshot()
        row = []
        for actor_id in ids + walkers:
            state = snapshot.find(actor_id)
            t = state.get_transform()
            row.append([actor_id, t.location.x, t.location.y, t.location.z, t.rotation.yaw])
        ticks.append(row)
    print(json.dumps({
        "map": world.get_map().name,
        "ids": ids,
        "walkers": walkers,
        "spawn_points": len(spawn_points),
        "ticks": ticks,
    }))


if __name__ == "__main__":
    main()
