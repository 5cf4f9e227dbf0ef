"""Train stable-baselines3's PPO on simbus.gym's driving task (state
observations), N worlds at once, and plot the reward curve.

    pip install "simbus[gym]" stable-baselines3 matplotlib
    SIMBUS_BIN_DIR=target/release python train_ppo.py --envs 4 --steps 100000 --plot reward.png

simbus.gym's VectorEnv (Gymnasium's SameStep autoreset) is handed to
stable-baselines3 through its VecEnv interface (the adapter below); the
curve is each finished episode's return against environment steps,
smoothed over 20 episodes, with a random policy's returns for reference."""

import argparse
import json
import time

import numpy as np
import simbus.gym as sg
from stable_baselines3 import PPO
from stable_baselines3.common.vec_env import VecEnv


class SimbusVecEnv(VecEnv):
    """stable-baselines3's VecEnv over a simbus.gym.VectorEnv."""

    def __init__(self, envs: sg.VectorEnv):
        self.envs = envs
        super().__init__(envs.num_envs, envs.single_observation_space, envs.single_action_space)
        self.returns = np.zeros(envs.num_envs)
        self.episodes = []  # (environment steps so far, return)
        self.steps = 0

    def reset(self):
        obs, _ = self.envs.reset(seed=self._seeds[0] if any(s is not None for s in self._seeds) else None)
        self._reset_seeds()
        return obs

    def step_async(self, actions):
        self._actions = actions

    def step_wait(self):
        obs, reward, terminated, truncated, info = self.envs.step(self._actions)
        self.steps += self.num_envs
        self.returns += reward
        dones = terminated | truncated
        infos = [{} for _ in range(self.num_envs)]
        for i in np.flatnonzero(dones):
            infos[i]["terminal_observation"] = info["final_obs"][i]
            infos[i]["TimeLimit.truncated"] = bool(truncated[i] and not terminated[i])
            self.episodes.append((self.steps, float(self.returns[i])))
            self.returns[i] = 0.0
        return obs, reward.astype(np.float32), dones, infos

    def close(self):
        self.envs.close()

    def get_attr(self, attr_name, indices=None):
        return [getattr(self.envs, attr_name)] * len(self._indices(indices))

    def set_attr(self, attr_name, value, indices=None):
        setattr(self.envs, attr_name, value)

    def env_method(self, method_name, *args, indices=None, **kwargs):
        raise NotImplementedError(method_name)

    def env_is_wrapped(self, wrapper_class, indices=None):
        return [False] * len(self._indices(indices))

    def _indices(self, indices):
        if indices is None:
            return range(self.num_envs)
        return [indices] if isinstance(indices, int) else indices


def random_returns(task, episodes, seed):
    env = sg.DrivingEnv(**task)
    env.action_space.seed(seed)
    returns = []
    try:
        for k in range(episodes):
            env.reset(seed=seed + k)
            total, done = 0.0, False
            while not done:
                _, r, term, trunc, _ = env.step(env.action_space.sample())
                total += r
                done = term or trunc
            returns.append(total)
    finally:
        env.close()
    return returns


def main():
    p = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    p.add_argument("--envs", type=int, default=4)
    p.add_argument("--steps", type=int, default=100_000)
    p.add_argument("--seed", type=int, default=0)
    p.add_argument("--plot", default=None, help="write the reward curve to this PNG")
    p.add_argument("--json", default=None, help="write the curve's points to this JSON file")
    args = p.parse_args()
    task = dict(vehicles=4, route_length=200.0, max_episode_steps=300)
    envs = SimbusVecEnv(sg.VectorEnv("driving", num_envs=args.envs, seed=args.seed,
                                     autoreset_mode="SameStep", **task))
    model = PPO("MultiInputPolicy", envs, n_steps=256, batch_size=256, learning_rate=3e-4,
                gamma=0.98, seed=args.seed, verbose=0, device="cpu")
    started = time.monotonic()
    model.learn(total_timesteps=args.steps)
    seconds = time.monotonic() - started
    envs.close()
    baseline = random_returns(task, 20, 1000 + args.seed)
    steps, returns = zip(*envs.episodes) if envs.episodes else ((), ())
    window = 20
    smooth = [float(np.mean(returns[max(0, i - window + 1):i + 1])) for i in range(len(returns))]
    first = float(np.mean(returns[:window])) if returns else float("nan")
    last = float(np.mean(returns[-window:])) if returns else float("nan")
    summary = {"environment_steps": args.steps, "worlds": args.envs, "seconds": round(seconds, 1),
               "steps_per_second": round(args.steps / seconds, 1), "episodes": len(returns),
               "first_20_mean_return": round(first, 2), "last_20_mean_return": round(last, 2),
               "random_policy_mean_return": round(float(np.mean(baseline)), 2)}
    print(json.dumps(summary))
    if args.json:
        with open(args.json, "w") as f:
            json.dump({**summary, "curve": list(zip(steps, smooth))}, f)
    if args.plot:
        import matplotlib

        matplotlib.use("Agg")
        import matplotlib.pyplot as plt

        fig, ax = plt.subplots(figsize=(7, 4))
        ax.plot(steps, returns, ".", alpha=0.25, label="episode return")
        ax.plot(steps, smooth, label=f"mean of {window} episodes")
        ax.axhline(np.mean(baseline), color="gray", linestyle="--", label="random policy")
        ax.set_xlabel("environment steps")
        ax.set_ylabel("return")
        ax.set_title(f"PPO on simbus.gym DrivingEnv, {args.envs} worlds, {seconds / 60:.1f} min on this machine")
        ax.legend()
        fig.tight_layout()
        fig.savefig(args.plot, dpi=100)


if __name__ == "__main__":
    main()
