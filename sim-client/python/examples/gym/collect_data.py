"""Collect a driving dataset at the fixed step: every step of every world,
each ego camera's image as a PNG and its labels (the ego's state, the
nearby actors, the route ahead, the action, the reward terms) in a JSON
line, from simbus.gym's VectorEnv driven by a simple lane-keeping policy.

    SIMBUS_BIN_DIR=target/release python collect_data.py --out data --envs 4 --steps 200

Writes OUT/world<i>/<step>.png and OUT/labels.jsonl (one line per image)."""

import argparse
import json
import os

import numpy as np
import simbus.gym as sg
from PIL import Image


def keep_lane(obs):
    """Steer towards the route point 8 m ahead; hold about 6 m/s."""
    ahead = obs["route"][:, 1, :]  # (forward, left) of the second point, per world
    steer = np.clip(1.5 * np.arctan2(ahead[:, 1], np.maximum(ahead[:, 0], 1.0)), -1.0, 1.0)
    speed = obs["ego"][:, 0]
    pedal = np.clip(0.5 * (6.0 - speed), -1.0, 1.0)
    return np.stack([steer, pedal], axis=1).astype(np.float32)


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--out", required=True)
    p.add_argument("--envs", type=int, default=2)
    p.add_argument("--steps", type=int, default=100)
    p.add_argument("--width", type=int, default=160)
    p.add_argument("--height", type=int, default=120)
    p.add_argument("--seed", type=int, default=0)
    args = p.parse_args()
    envs = sg.VectorEnv("driving", num_envs=args.envs, seed=args.seed, vehicles=6, walkers=4,
                        camera=(args.width, args.height), autoreset_mode="SameStep")
    for i in range(args.envs):
        os.makedirs(os.path.join(args.out, f"world{i}"), exist_ok=True)
    written = 0
    try:
        obs, _ = envs.reset()
        with open(os.path.join(args.out, "labels.jsonl"), "w") as labels:
            for t in range(args.steps):
                action = keep_lane(obs)
                for i in range(args.envs):
                    path = os.path.join(f"world{i}", f"{t:06d}.png")
                    Image.fromarray(obs["camera"][i]).save(os.path.join(args.out, path))
                    actors = obs["actors"][i]
                    labels.write(json.dumps({
                        "image": path, "world": i, "step": t,
                        "simulated_seconds": round(t * envs.config.delta_seconds, 6),
                        "ego": dict(zip(["speed", "left_of_route", "heading_error", "last_steer", "last_pedal",
                                         "stop_line_distance", "stop_red", "speed_limit"],
                                        obs["ego"][i].tolist())),
                        "actors": [dict(zip(["forward", "left", "v_forward", "v_left", "walker"], a[:5].tolist()))
                                   for a in actors if a[5] > 0],
                        "route": obs["route"][i].tolist(),
                        "action": action[i].tolist(),
                    }) + "\n")
                    written += 1
                obs, _, _, _, _ = envs.step(action)
    finally:
        envs.close()
    print(json.dumps({"images": written, "out": args.out}))


if __name__ == "__main__":
    main()
