"""The CARLA side of `simbus-bench carla`: CARLA 0.9.16's own client
against the gateway. Prints one JSON object on its last line.

    carla_bench.py tick PORT N     world.tick() round trips (this client ticks),
                                   and get_server_version() (no simbus) as the floor
    carla_bench.py wait PORT N     wait_for_tick: publish -> returned (another ticks)
    carla_bench.py sensor PORT N BLUEPRINT [NAME=VALUE ...]
                                   N captures of a sensor of BLUEPRINT (with
                                   those attributes) through sensor.listen
    carla_bench.py traffic PORT N VEHICLES TM_PORT WALKERS
                                   the traffic manager in synchronous mode on
                                   simbus's town: VEHICLES autopilot vehicles
                                   and WALKERS walkers with CARLA's AI
                                   controller, N world.tick() timed (the TM
                                   step included); a tick that takes 30 s is
                                   a deadlock (reported, the run ends)
    carla_bench.py map PORT N      world.get_map() + generate_waypoints(2.0)
                                   on the town, N times
    carla_bench.py capture PORT N W H
                                   a W x H depth camera through camera.listen:
                                   world.tick() returned -> the image in hand
                                   as a numpy array (np.frombuffer, no copy)
"""

import json
import queue
import sys
import time

import carla


def sync(world, on):
    settings = world.get_settings()
    settings.synchronous_mode = on
    settings.fixed_delta_seconds = 0.01
    world.apply_settings(settings)


def main():
    mode, port, n = sys.argv[1], int(sys.argv[2]), int(sys.argv[3])
    client = carla.Client("127.0.0.1", port)
    client.set_timeout(30.0)
    world = client.get_world()
    if mode == "tick":
        # The floor: a call the gateway answers without simbus.
        floor = []
        for _ in range(n):
            start = time.perf_counter_ns()
            client.get_server_version()
            floor.append(time.perf_counter_ns() - start)
        sync(world, True)
        for _ in range(n // 10):
            world.tick()
        samples = []
        for _ in range(n):
            start = time.perf_counter_ns()
            world.tick()
            samples.append(time.perf_counter_ns() - start)
        sync(world, False)
        print(json.dumps({"ns": samples, "floor_ns": floor}))
    elif mode == "wait":
        world.wait_for_tick(30.0)
        print("ready", flush=True)
        samples = []
        while len(samples) < n:
            snapshot = world.wait_for_tick(30.0)
            received = time.time_ns()
            samples.append(received - int(snapshot.timestamp.platform_timestamp * 1e9))
        print(json.dumps({"ns": samples}))
    elif mode == "sensor":
        sync(world, True)
        blueprint = world.get_blueprint_library().find(sys.argv[4])
        for attribute in sys.argv[5:]:
            name, value = attribute.split("=", 1)
            blueprint.set_attribute(name, value)
        sensor = world.spawn_actor(blueprint, carla.Transform(carla.Location(z=2.0)))
        captures = queue.Queue()
        sensor.listen(captures.put)
        for _ in range(5):
            frame = world.tick()
            assert captures.get(timeout=30).frame == frame
        start = time.perf_counter()
        for _ in range(n):
            frame = world.tick()
            capture = captures.get(timeout=30)
            assert capture.frame == frame
        elapsed = time.perf_counter() - start
        sensor.stop()
        sensor.destroy()
        sync(world, False)
        print(json.dumps({"fps": n / elapsed}))
    elif mode == "traffic":
        print(json.dumps(traffic(client, n, int(sys.argv[4]), int(sys.argv[5]), int(sys.argv[6]))))
    elif mode == "map":
        client.load_world("town")
        world = client.get_world()
        samples, waypoints = [], 0
        for _ in range(n):
            start = time.perf_counter_ns()
            waypoints = len(world.get_map().generate_waypoints(2.0))
            samples.append(time.perf_counter_ns() - start)
        print(json.dumps({"ns": samples, "waypoints": waypoints}))
    elif mode == "capture":
        width, height = int(sys.argv[4]), int(sys.argv[5])
        print(json.dumps({"ns": capture(world, n, width, height)}))
    else:
        raise SystemExit(f"unknown mode {mode}")


def traffic(client, n, vehicles, tm_port, walkers):
    """Ticks per second with `vehicles` autopilot vehicles and `walkers` AI
    walkers on the town, the traffic manager in synchronous mode (its step
    rides in each tick, or in the world's lockstep)."""
    import os
    import threading

    client.load_world("town")
    world = client.get_world()
    settings = world.get_settings()
    settings.synchronous_mode = True
    settings.fixed_delta_seconds = 0.05
    world.apply_settings(settings)
    tm = client.get_trafficmanager(tm_port)
    tm.set_synchronous_mode(True)
    tm.set_random_device_seed(1)
    library = world.get_blueprint_library()
    blueprints = library.filter("vehicle.*")
    points = world.get_map().get_spawn_points()
    if len(points) < vehicles:
        raise SystemExit(f"{vehicles} vehicles asked, {len(points)} spawn points")
    batch = [
        carla.command.SpawnActor(blueprints[i % len(blueprints)], point).then(
            carla.command.SetAutopilot(carla.command.FutureActor, True, tm_port))
        for i, point in enumerate(points[:vehicles])
    ]
    spawned = [r.actor_id for r in client.apply_batch_sync(batch, True) if not r.error]
    world.set_pedestrians_seed(1)
    walker_bps = library.filter("walker.pedestrian.*")
    batch = [carla.command.SpawnActor(walker_bps[i % len(walker_bps)],
                                      carla.Transform(world.get_random_location_from_navigation()))
             for i in range(walkers)]
    people = [r.actor_id for r in client.apply_batch_sync(batch, True) if not r.error]
    controller = library.find("controller.ai.walker")
    results = client.apply_batch_sync(
        [carla.command.SpawnActor(controller, carla.Transform(), w) for w in people], True)
    world.tick()
    for ai in world.get_actors([r.actor_id for r in results if not r.error]):
        ai.start()
        ai.go_to_location(world.get_random_location_from_navigation())
        ai.set_max_speed(1.4)
    # CARLA's own traffic manager can deadlock in synchronous mode
    # (carla-simulator/carla#9172): a tick that never returns is reported.
    done = [0]

    def watchdog():
        last = -1
        while True:
            time.sleep(30)
            if done[0] == last:
                print(json.dumps({"deadlocked_after": done[0], "vehicles": len(spawned),
                                  "walkers": len(people)}), flush=True)
                os._exit(0)
            last = done[0]

    threading.Thread(target=watchdog, daemon=True).start()
    for _ in range(20):
        world.tick()
    start = time.perf_counter()
    for _ in range(n):
        world.tick()
        done[0] += 1
    elapsed = time.perf_counter() - start
    return {"ticks_per_s": n / elapsed, "vehicles": len(spawned), "walkers": len(people)}


def capture(world, n, width, height):
    """World.tick() returned -> a W x H depth image in hand as a numpy array
    (its first and last byte read), n times after n // 10 to warm up."""
    import numpy as np

    sync(world, True)
    blueprint = world.get_blueprint_library().find("sensor.camera.depth")
    blueprint.set_attribute("image_size_x", str(width))
    blueprint.set_attribute("image_size_y", str(height))
    camera = world.spawn_actor(blueprint, carla.Transform(carla.Location(z=2.0)))
    images = queue.Queue()
    camera.listen(images.put)
    samples = []
    for i in range(n + n // 10):
        frame = world.tick()
        start = time.perf_counter_ns()
        image = images.get(timeout=30)
        array = np.frombuffer(image.raw_data, dtype=np.uint8)
        array[0], array[-1]
        elapsed = time.perf_counter_ns() - start
        assert image.frame == frame and array.size == width * height * 4
        if i >= n // 10:
            samples.append(elapsed)
    camera.stop()
    camera.destroy()
    sync(world, False)
    return samples


if __name__ == "__main__":
    main()
