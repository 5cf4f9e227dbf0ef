"""simbus-bench gym's Python side: environment steps per second of
simbus.gym beside Gymnasium's own vector envs and highway-env, one run."""

import argparse
import json
import os
import sys
import time

import numpy as np

import gymnasium as gym
import simbus.gym as sg
from gymnasium.vector import AsyncVectorEnv, SyncVectorEnv

DELTA = 0.1  # simbus: seconds of simulation per step
HIGHWAY_STEP = 1.0  # highway-env: a policy step is 1 s (five 0.2 s sub-steps)


def timed(step, steps):
    step()  # warm
    started = time.perf_counter()
    for _ in range(steps):
        step()
    return time.perf_counter() - started


def actions_for(n, camera=False):
    a = np.zeros((n, 2), np.float32)
    a[:, 1] = 0.3
    return a


def simbus_sync(n, steps, task, camera=None):
    envs = sg.VectorEnv("driving", num_envs=n, seed=0, copy=False, camera=camera, **task)
    try:
        envs.reset()
        a = actions_for(n)
        return n * steps / timed(lambda: envs.step(a), steps)
    finally:
        envs.close()


def simbus_async(n, steps, task):
    batch = max(1, n // 2)
    envs = sg.VectorEnv("driving", num_envs=n, seed=0, copy=False, batch_size=batch, **task)
    try:
        envs.reset()
        envs.send(actions_for(n))
        a = actions_for(batch)

        def step():
            _, _, _, _, info = envs.recv()
            envs.send(a, info["env_id"])

        rounds = max(1, steps * n // batch)
        return batch * rounds / timed(step, rounds)
    finally:
        envs.close()


def gym_vector(kind, n, steps, make):
    if kind == "async":
        envs = AsyncVectorEnv([make] * n, shared_memory=True)
    else:
        envs = SyncVectorEnv([make] * n)
    try:
        envs.reset(seed=0)
        a = envs.action_space.sample()
        if isinstance(a, np.ndarray) and a.dtype == np.float32:
            a = actions_for(n) if a.shape == (n, 2) else a
        return n * steps / timed(lambda: envs.step(a), steps)
    finally:
        envs.close()


def highway(kind, n, steps):
    import highway_env  # noqa: F401  registers the envs

    make = lambda: gym.make("highway-fast-v0")  # noqa: E731
    if kind == "alone":
        env = make()
        try:
            env.reset(seed=0)
            return steps / timed(lambda: env.step(env.action_space.sample()), steps)
        finally:
            env.close()
    return gym_vector(kind, n, steps, make)


def carla_driving(steps, vehicles, sub):
    """The same task as a CARLA user writes it today: CARLA's client through
    simbus's gateway (the fastest CARLA server there is here), synchronous,
    0.1 s steps, an ego and `vehicles` on the traffic manager's autopilot;
    per step: the ego's control, world.tick(), and what a driving env
    reads (the ego's transform and velocity, its waypoint, the vehicles)."""
    import json as _json
    import subprocess

    import carla

    bin_dir = os.environ["SIMBUS_BIN_DIR"]
    world_name = sg.unique_world("gym-carla")
    server = sg.ServerProcess(world_name)
    gateway = None
    try:
        subprocess.run([os.path.join(bin_dir, "sim-client"), "--world", world_name, "--timeout", "60", "status"],
                       capture_output=True, check=True, timeout=90)
        gateway = subprocess.Popen(
            [os.path.join(bin_dir, "sim-client"), "--world", world_name, "--timeout", "10",
             "carla-gateway", "--port", "0", "--json"],
            stdout=subprocess.PIPE, stderr=subprocess.DEVNULL, text=True)
        port = None
        while port is None:
            line = gateway.stdout.readline()
            if not line:
                raise RuntimeError("the gateway exited")
            if '"streaming_port"' in line:
                port = _json.loads(line)["port"]
        client = carla.Client("127.0.0.1", port)
        client.set_timeout(20.0)
        world = client.get_world()
        settings = world.get_settings()
        settings.synchronous_mode = True
        settings.fixed_delta_seconds = DELTA
        settings.max_substep_delta_time = sub
        settings.max_substeps = 16
        world.apply_settings(settings)
        tm = client.get_trafficmanager(8000 + os.getpid() % 1000)
        tm.set_synchronous_mode(True)
        blueprints = world.get_blueprint_library().filter("vehicle.*")
        points = world.get_map().get_spawn_points()
        ego = world.spawn_actor(blueprints[0], points[0])
        for k in range(vehicles):
            v = world.try_spawn_actor(blueprints[0], points[(k + 1) * 7 % len(points)])
            if v is not None:
                v.set_autopilot(True, tm.get_port())
        world.tick()
        carla_map = world.get_map()
        control = carla.VehicleControl(throttle=0.3)

        def step():
            ego.apply_control(control)
            world.tick()
            transform = ego.get_transform()
            ego.get_velocity()
            carla_map.get_waypoint(transform.location)
            for actor in world.get_actors().filter("vehicle.*"):
                actor.get_transform()

        return steps / timed(step, steps)
    finally:
        if gateway is not None:
            gateway.kill()
            gateway.wait()
        server.close()


def reset_p50(task, count=100):
    env = sg.DrivingEnv(**task)
    try:
        times = []
        for k in range(count):
            t = time.perf_counter()
            env.reset(seed=k)
            times.append(time.perf_counter() - t)
        return float(np.median(times)) * 1e3
    finally:
        env.close()


def python_overhead(n, steps, task):
    """The share of VectorEnv.step spent in Python: the step against the
    Rust calls it makes (send and finish per world) made directly."""
    envs = sg.VectorEnv("driving", num_envs=n, seed=0, copy=False, **task)
    try:
        envs.reset()
        a = actions_for(n)
        full = timed(lambda: envs.step(a), steps)
        worlds = [s.world for s in envs.slots]
        rows = [a[i:i + 1] for i in range(n)]
        args = [(s.flat, s.reward, s.terminated, s.truncated, s.terms) for s in envs.slots]

        def raw():
            for w, r in zip(worlds, rows):
                w.send(r)
            for w, x in zip(worlds, args):
                w.finish(*x)

        bare = timed(raw, steps)
        return max(0.0, (full - bare) / full)
    finally:
        envs.close()


def main():
    p = argparse.ArgumentParser()
    p.add_argument("--envs", default="1,2,4,8,16")
    p.add_argument("--steps", type=int, default=300)
    p.add_argument("--highway-steps", type=int, default=40)
    p.add_argument("--vehicles", type=int, default=10)
    p.add_argument("--max-substep-delta-time", type=float, default=0.02)
    p.add_argument("--skip-highway", action="store_true")
    p.add_argument("--skip-carla", action="store_true")
    p.add_argument("--json", action="store_true")
    args = p.parse_args()
    task = dict(vehicles=args.vehicles, max_episode_steps=100000,
                max_substep_delta_time=args.max_substep_delta_time)
    make = lambda: sg.DrivingEnv(**task)  # noqa: E731
    rows = []

    def row(name, n, rate, sim_step):
        rows.append({"row": name, "envs": n, "steps_per_s": rate, "sim_s_per_s": rate * sim_step})
        if not args.json:
            print(f"{name:<46} N={n:<3} {rate:>10.1f} steps/s {rate * sim_step:>10.1f} sim s/s", flush=True)

    for n in [int(x) for x in args.envs.split(",")]:
        s = args.steps
        if n == 1 and not args.skip_carla:
            row("CARLA's client through the gateway (same task)", 1,
                carla_driving(max(20, s // 3), args.vehicles, args.max_substep_delta_time), DELTA)
        row("simbus.gym VectorEnv (sync)", n, simbus_sync(n, s, task), DELTA)
        if n > 1:
            row("simbus.gym VectorEnv (async, batch N/2)", n, simbus_async(n, s, task), DELTA)
        row("simbus.gym VectorEnv, 84x84 camera", n, simbus_sync(n, max(20, s // 3), task, camera=(84, 84)), DELTA)
        row("Gymnasium SyncVectorEnv(DrivingEnv)", n, gym_vector("sync", n, max(20, s // 2), make), DELTA)
        row("Gymnasium AsyncVectorEnv(DrivingEnv, shm)", n, gym_vector("async", n, max(20, s // 2), make), DELTA)
        if not args.skip_highway:
            h = args.highway_steps
            if n == 1:
                row("highway-env highway-fast-v0 (alone)", 1, highway("alone", 1, h), HIGHWAY_STEP)
            row("highway-env SyncVectorEnv(highway-fast-v0)", n, highway("sync", n, h), HIGHWAY_STEP)
            row("highway-env AsyncVectorEnv(highway-fast-v0)", n, highway("async", n, h), HIGHWAY_STEP)
    extra = {
        "reset_p50_ms": reset_p50(task),
        "python_overhead_share_n4": python_overhead(4, args.steps, task),
        "max_substep_delta_time": args.max_substep_delta_time,
        "vehicles": args.vehicles,
        "cpus": os.cpu_count(),
        "load": os.getloadavg()[0],
    }
    if args.json:
        print(json.dumps({"rows": rows, **extra}))
    else:
        print(f"reset p50 {extra['reset_p50_ms']:.2f} ms; Python's share of a VectorEnv step (N=4) "
              f"{100 * extra['python_overhead_share_n4']:.1f} %; {extra['cpus']} CPUs, load {extra['load']:.2f}")


if __name__ == "__main__":
    sys.exit(main())
