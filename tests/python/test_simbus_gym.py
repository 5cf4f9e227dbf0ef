"""simbus.gym: Gymnasium's and PettingZoo's own checkers pass; rollouts
repeat bit for bit per seed (across separate servers, and across a server
killed mid-run); VectorEnv's autoreset modes batch what Gymnasium's own
SyncVectorEnv gives over the same worlds; async recv returns only the worlds
that finished; a killed world is reported and recovered.

Every env starts its own sim-server (a unique world) and reaps it on close."""

import hashlib
import os
import signal

import numpy as np
import pytest

gymnasium = pytest.importorskip("gymnasium")
import simbus  # noqa: E402
import simbus.gym as sg  # noqa: E402
from gymnasium.vector import SyncVectorEnv  # noqa: E402

# A short, busy episode: traffic, walkers, a step of 0.1 s.
TASK = dict(vehicles=6, walkers=3, max_episode_steps=40)


def policy(steps, rng_seed=7):
    """A fixed sequence of actions: mostly forward, some turning."""
    rng = np.random.default_rng(rng_seed)
    actions = rng.uniform(-1.0, 1.0, size=(steps, 2)).astype(np.float32)
    actions[:, 1] = np.abs(actions[:, 1]) * 0.8
    actions[:, 0] *= 0.3
    return actions


def digest(hasher, obs, reward):
    for key in sorted(obs):
        hasher.update(np.ascontiguousarray(obs[key]).tobytes())
    hasher.update(np.float64(reward).tobytes())


def rollout(env, seed, actions, kill_at=None):
    """Hash of every observation and reward of `actions` from reset(seed),
    resetting (seed-less, from the env's generator) when an episode ends."""
    hasher = hashlib.sha256()
    obs, _ = env.reset(seed=seed)
    digest(hasher, obs, 0.0)
    restarted = []
    for i, action in enumerate(actions):
        if i == kill_at:
            os.kill(env.server_pid, signal.SIGKILL)
        obs, reward, terminated, truncated, info = env.step(action)
        if "restarted" in info:
            restarted.append((i, info["restarted"]))
        digest(hasher, obs, reward)
        if terminated or truncated:
            obs, _ = env.reset()
            digest(hasher, obs, 0.0)
    return hasher.hexdigest(), restarted


def test_driving_env_passes_gymnasiums_checker_and_renders():
    from gymnasium.utils.env_checker import check_env

    env = sg.DrivingEnv(vehicles=3, render_mode="rgb_array", camera=(32, 24))
    try:
        check_env(env, skip_render_check=False)
        obs, _ = env.reset(seed=1)
        assert obs["camera"].shape == (24, 32, 3) and obs["camera"].dtype == np.uint8
        image = env.render()
        assert image.shape == (24, 32, 3) and image.any(), "the camera saw nothing"
        assert env.observation_space.contains(obs)
    finally:
        env.close()


def test_a_lidar_on_another_scenes_roads_sees_the_world():
    from gymnasium.utils.env_checker import check_env

    env = sg.DrivingEnv(scene="default", vehicles=2, lidar=(8, 90))
    try:
        check_env(env, skip_render_check=True)
        obs, _ = env.reset(seed=2)
        cloud = obs["lidar"]
        assert cloud.shape == (720, 4) and cloud.dtype == np.float32
        hits = cloud[cloud[:, 3] > 0]
        assert len(hits) > 50, "the lidar hit nothing"
        assert (np.linalg.norm(hits[:, :3], axis=1) <= 50.01).all()
        # The ego follows the scene's ring road: its route is ahead of it.
        assert obs["route"][0][0] > 0 and abs(obs["ego"][1]) < 1.0
    finally:
        env.close()


def test_walkers_cross_the_road_as_often_as_the_cross_factor_says():
    braking = np.array([0.0, -1.0], np.float32)
    counts = {}
    for factor in (0.0, 1.0):
        env = sg.DrivingEnv(walkers=12, cross_factor=factor, max_episode_steps=1000)
        try:
            env.reset(seed=3)
            client = simbus.connect(env.world)
            _, walkers = env._slot.world.traffic
            with client.wait_for_frame() as frame:
                start = {int(a["id"]): a["position"].copy() for a in frame.actors if a["id"] in walkers}
            for _ in range(300):
                env.step(braking)
            with client.wait_for_frame() as frame:
                end = {int(a["id"]): a["position"].copy() for a in frame.actors if a["id"] in walkers}
            counts[factor] = env._slot.world.crossings
            walked = [np.linalg.norm(end[w][[0, 2]] - start[w][[0, 2]]) for w in walkers]
            assert max(walked) > 10.0, f"the walkers did not walk: {walked}"
            assert all(0.5 < end[w][1] < 3.0 for w in walkers), "a walker left the ground"
        finally:
            env.close()
    assert counts[0.0] == 0 and counts[1.0] >= 3, counts
    with pytest.raises(ValueError, match="cross_factor"):
        sg.DrivingEnv(walkers=1, cross_factor=1.5)


def test_a_seed_gives_the_same_episode_bit_for_bit_and_another_seed_another():
    actions = policy(500)
    first = sg.DrivingEnv(**TASK)
    second = sg.DrivingEnv(**TASK)
    try:
        assert first.world != second.world
        a, _ = rollout(first, 11, actions)
        b, _ = rollout(second, 11, actions)
        c, _ = rollout(first, 12, actions)
    finally:
        first.close()
        second.close()
    assert a == b, "two servers, one seed, the same actions: different rollouts"
    assert a != c, "another seed gave the same rollout"


def test_a_server_killed_mid_rollout_is_restarted_and_the_rollout_is_unchanged():
    actions = policy(500)
    env = sg.DrivingEnv(**TASK)
    try:
        clean, none = rollout(env, 5, actions)
        pid = env.server_pid
        crashed, restarted = rollout(env, 5, actions, kill_at=250)
        assert env.server_pid != pid
    finally:
        env.close()
    assert none == []
    assert len(restarted) == 1 and restarted[0][0] == 250, restarted
    assert "replayed" in restarted[0][1]
    assert crashed == clean, "the rollout through a server crash differs from the uninterrupted one"


def test_a_bad_action_or_config_is_refused_and_changes_nothing():
    with pytest.raises(ValueError, match="reward terms"):
        sg.DrivingEnv(weights={"speeding": 1.0})
    env = sg.DrivingEnv(vehicles=1)
    try:
        obs, _ = env.reset(seed=3)
        with pytest.raises(ValueError, match="finite"):
            env.step(np.array([np.nan, 0.0], np.float32))
        again, _ = env.reset(seed=3)
        for key in obs:
            np.testing.assert_array_equal(obs[key], again[key])
    finally:
        env.close()


def test_world_env_runs_a_task_of_the_users_own_and_passes_the_checker():
    from gymnasium import spaces
    from gymnasium.utils.env_checker import check_env

    def setup(client, context):
        context["box"] = client.spawn("box", at=(0.0, 0.5, 0.0), half_extents=(0.5, 0.5, 0.5))

    def act(action, context):
        return [simbus.ApplyForce(context["box"], (float(action[0]) * 200.0, 0.0, 0.0))]

    def where(frame, context):
        actors = frame.actors
        box = actors[actors["id"] == context["box"]][0]
        return np.array([box["position"][0], box["linear_velocity"][0]], np.float32)

    def randomize(rng, context):
        return [simbus.SetTransform(context["box"], (float(rng.uniform(-3, 3)), 0.5, 0.0))]

    env = sg.WorldEnv(
        observation_space=spaces.Box(-1e3, 1e3, (2,), np.float32),
        action_space=spaces.Box(-1.0, 1.0, (1,), np.float32),
        setup=setup, act=act, observe=where,
        reward=lambda frame, ctx: float(where(frame, ctx)[0]),
        terminated=lambda frame, ctx: bool(where(frame, ctx)[0] > 10.0),
        randomize=randomize, scene="flat", max_episode_steps=30,
    )
    try:
        check_env(env, skip_render_check=True)
        first, _ = env.reset(seed=4)
        for _ in range(20):
            obs, reward, terminated, truncated, _ = env.step(np.array([1.0], np.float32))
        assert obs[0] > first[0] + 0.5, "pushing the box forward did not move it"
        again, _ = env.reset(seed=4)
        np.testing.assert_array_equal(first, again)
    finally:
        env.close()


def test_parallel_env_passes_pettingzoos_api_test():
    pettingzoo_test = pytest.importorskip("pettingzoo.test")
    env = sg.ParallelEnv(agents=3, vehicles=2, max_episode_steps=25)
    try:
        pettingzoo_test.parallel_api_test(env, num_cycles=60)
        obs, _ = env.reset(seed=2)
        assert sorted(obs) == ["ego_0", "ego_1", "ego_2"]
        # One tick moves every agent's car.
        for _ in range(10):
            obs, _, _, _, _ = env.step({a: np.array([0.0, 0.6], np.float32) for a in env.agents})
        assert all(o["ego"][0] > 0.5 for o in obs.values()), {a: o["ego"][0] for a, o in obs.items()}
    finally:
        env.close()


def batches(envs, steps, actions, seed, disabled=False):
    """Every batch of `steps` steps from reset(seed)."""
    out = []
    obs, _ = envs.reset(seed=seed)
    out.append(("reset", obs))
    for t in range(steps):
        obs, reward, terminated, truncated, info = envs.step(actions[t])
        out.append((obs, reward, terminated, truncated, info.get("final_obs")))
        if disabled and (terminated | truncated).any():
            obs, _ = envs.reset(options={"reset_mask": terminated | truncated})
            out.append(("reset", obs))
    return out


def same(a, b):
    if isinstance(a, dict):
        return sorted(a) == sorted(b) and all(same(a[k], b[k]) for k in a)
    if isinstance(a, np.ndarray) and a.dtype == object:
        return all(same(x, y) for x, y in zip(a, b))
    if a is None or isinstance(a, str):
        return a == b
    return np.array_equal(np.asarray(a), np.asarray(b))


@pytest.mark.parametrize("mode", ["NextStep", "SameStep", "Disabled"])
def test_vector_env_batches_what_gymnasiums_sync_vector_env_gives(mode):
    task = dict(vehicles=4, max_episode_steps=12)
    steps, n = 40, 4
    actions = policy(steps * n).reshape(steps, n, 2)
    ours = sg.VectorEnv("driving", num_envs=n, autoreset_mode=mode, **task)
    theirs = SyncVectorEnv([lambda: sg.DrivingEnv(**task) for _ in range(n)], autoreset_mode=mode)
    try:
        a = batches(ours, steps, actions, seed=21, disabled=mode == "Disabled")
        b = batches(theirs, steps, actions, seed=21, disabled=mode == "Disabled")
    finally:
        ours.close()
        theirs.close()
    assert len(a) == len(b) > steps
    ended = 0
    for t, (x, y) in enumerate(zip(a, b)):
        assert len(x) == len(y)
        for u, v in zip(x, y):
            assert same(u, v), f"batch {t} differs ({mode})"
        if x[0] != "reset":
            ended += int((x[2] | x[3]).sum())
    assert ended >= n, "no episode ended: the modes were not exercised"


def test_async_recv_returns_only_the_worlds_that_finished():
    envs = sg.VectorEnv("driving", num_envs=4, seed=0, batch_size=2, vehicles=2, timeout=5.0)
    try:
        envs.reset()
        stopped = envs.slots[3].server.pid
        os.kill(stopped, signal.SIGSTOP)
        try:
            envs.send(np.zeros((4, 2), np.float32))
            seen = set()
            for _ in range(6):
                obs, reward, terminated, truncated, info = envs.recv()
                ids = info["env_id"]
                assert len(ids) == 2 and obs["ego"].shape == (2, 8)
                assert 3 not in ids, "a stopped world was returned as finished"
                seen.update(int(i) for i in ids)
                envs.send(np.zeros((2, 2), np.float32), ids)
            assert seen == {0, 1, 2}
        finally:
            os.kill(stopped, signal.SIGCONT)
        # Once it runs again, its step comes in.
        got = set()
        for _ in range(10):
            _, _, _, _, info = envs.recv()
            got.update(int(i) for i in info["env_id"])
            envs.send(np.zeros((2, 2), np.float32), info["env_id"])
            if 3 in got:
                break
        assert 3 in got
    finally:
        envs.close()


def test_a_killed_world_is_reported_and_recovered_without_changing_the_batches():
    steps, n = 30, 4
    actions = policy(steps * n).reshape(steps, n, 2)
    task = dict(vehicles=3, max_episode_steps=20)
    clean = sg.VectorEnv("driving", num_envs=n, **task)
    killed = sg.VectorEnv("driving", num_envs=n, **task)
    try:
        a = batches(clean, steps, actions, seed=3)
        obs, _ = killed.reset(seed=3)
        b = [("reset", obs)]
        reported = []
        for t in range(steps):
            if t == 15:
                killed.slots[1].server.kill()
            obs, reward, terminated, truncated, info = killed.step(actions[t])
            if "restarted" in info:
                reported.append((t, np.flatnonzero(info["_restarted"]).tolist()))
            b.append((obs, reward, terminated, truncated, info.get("final_obs")))
    finally:
        clean.close()
        killed.close()
    assert reported == [(15, [1])], reported
    for t, (x, y) in enumerate(zip(a, b)):
        for u, v in zip(x, y):
            assert same(u, v), f"batch {t} differs after the world was restarted"


def test_the_data_collection_example_writes_images_and_labels_at_the_fixed_step(tmp_path):
    import json
    import subprocess
    import sys

    from PIL import Image

    example = os.path.join(os.path.dirname(__file__), "..", "..", "sim-client", "python", "examples", "gym",
                           "collect_data.py")
    done = subprocess.run([sys.executable, example, "--out", str(tmp_path), "--envs", "2", "--steps", "5",
                           "--width", "64", "--height", "48"], capture_output=True, text=True, timeout=300)
    assert done.returncode == 0, done.stderr
    lines = [json.loads(line) for line in (tmp_path / "labels.jsonl").read_text().splitlines()]
    assert len(lines) == 10
    assert [x["simulated_seconds"] for x in lines if x["world"] == 0] == [0.0, 0.1, 0.2, 0.3, 0.4]
    for label in lines:
        image = Image.open(tmp_path / label["image"])
        assert image.size == (64, 48)
        assert set(label["ego"]) >= {"speed", "left_of_route", "heading_error"}
        assert len(label["route"]) == 10
