"""`WorldEnv`: a Gymnasium environment over any simbus world for a task of
your own. You give the spaces and what an action does, what a frame is as
an observation, a reward and an ending; simbus ticks, resets (one snapshot
restored per episode) and seeds."""

from __future__ import annotations

from typing import Any, Callable, Dict, List, Optional, Sequence

import gymnasium as gym
import numpy as np

from .. import Command, Frame, connect
from ._servers import ServerProcess, unique_world
from ._slot import WORLD_LOST

Context = Dict[str, Any]


class WorldEnv(gym.Env):
    """Your task over a simbus world.

    - ``setup(client, context)`` spawns what the task needs, once per server
      (it may keep ids in `context`); the world then runs ``settle_frames``
      and is saved as every episode's start.
    - ``randomize(rng, context) -> commands`` (optional): what an episode
      changes from that start, drawn from the episode's seeded `rng`.
    - ``act(action, context) -> commands``: what an action does, applied
      before the step's tick.
    - ``observe(frame, context)``, ``reward(frame, context)``,
      ``terminated(frame, context)``: read the step's `simbus.Frame`
      (valid during the call only: copy what you keep).

    Episodes end on ``terminated`` or after ``max_episode_steps``
    (truncated). The same seed and actions give the same episode; a server
    that dies is restarted and the episode replayed to where it was
    (``info["restarted"]``).
    """

    metadata = {"render_modes": []}

    def __init__(self, *, observation_space: gym.Space, action_space: gym.Space,
                 setup: Callable[[Any, Context], None], act: Callable[[Any, Context], Sequence[Command]],
                 observe: Callable[[Frame, Context], Any], reward: Callable[[Frame, Context], float],
                 terminated: Optional[Callable[[Frame, Context], bool]] = None,
                 randomize: Optional[Callable[[np.random.Generator, Context], Sequence[Command]]] = None,
                 scene: str = "default", world: Optional[str] = None, delta_seconds: float = 0.05,
                 settle_frames: int = 10, max_episode_steps: int = 1000, timeout: float = 10.0,
                 server_binary: Optional[str] = None):
        self.observation_space, self.action_space = observation_space, action_space
        self._fns = (setup, act, observe, reward, terminated, randomize)
        self._scene, self._delta, self._settle = scene, delta_seconds, settle_frames
        self.max_episode_steps, self.timeout = max_episode_steps, timeout
        self.server: Optional[ServerProcess] = None
        if world is None:
            world = unique_world("gym-world")
            self.server = ServerProcess(world, scene=scene, binary=server_binary)
        self.world = world
        self.context: Context = {}
        self._actions: List[Any] = []
        self._episode_seed = 0
        self._steps = 0
        self._open()

    def _open(self) -> None:
        setup = self._fns[0]
        self.client = connect(self.world, timeout=self.timeout)
        self.ticker = self.client.ticker(delta_seconds=self._delta, timeout=self.timeout)
        self.client.load_world(self._scene)
        self.context = {}
        setup(self.client, self.context)
        for _ in range(self._settle):
            self.ticker.tick(self.timeout)
        self.snapshot = self.client.save_snapshot()

    def _restart(self) -> str:
        replay = list(self._actions)
        if self.server is not None:
            self.server.start()
        self._open()
        self._start_episode()
        for action in replay:
            self._advance(action)
        return f"world '{self.world}' restarted, {len(replay)} steps replayed"

    def _start_episode(self) -> Any:
        randomize, observe = self._fns[5], self._fns[2]
        self._actions.clear()
        self._steps = 0
        self.client.restore_snapshot(self.snapshot)
        if randomize is not None:
            rng = np.random.default_rng(self._episode_seed)
            self.client.apply_batch(list(randomize(rng, self.context)))
        with self.ticker.tick_and_read(self.client, self.timeout) as frame:
            return observe(frame, self.context)

    def _advance(self, action: Any):
        act, observe, reward, terminated = self._fns[1], self._fns[2], self._fns[3], self._fns[4]
        commands = list(act(action, self.context))  # the user's: may refuse the action
        self._actions.append(action)
        self._steps += 1
        if commands:
            self.client.apply_batch(commands)
        with self.ticker.tick_and_read(self.client, self.timeout) as frame:
            obs = observe(frame, self.context)
            r = float(reward(frame, self.context))
            done = bool(terminated(frame, self.context)) if terminated is not None else False
            info: Dict[str, Any] = {}
        return obs, r, done, info

    def reset(self, *, seed: Optional[int] = None, options: Optional[Dict[str, Any]] = None):
        super().reset(seed=seed)
        self._episode_seed = int(self.np_random.integers(2**63 - 1))
        info: Dict[str, Any] = {"episode_seed": self._episode_seed}
        try:
            obs = self._start_episode()
        except WORLD_LOST:
            info["restarted"] = self._restart()
            with self.client.wait_for_frame(self.timeout) as frame:
                obs = self._fns[2](frame, self.context)
        return obs, info

    def step(self, action):
        try:
            obs, r, done, info = self._advance(action)
        except WORLD_LOST:
            self._actions.pop()
            self._steps -= 1
            note = self._restart()
            obs, r, done, info = self._advance(action)
            info["restarted"] = note
        truncated = not done and self._steps >= self.max_episode_steps
        return obs, r, done, truncated, info

    def close(self):
        ticker = getattr(self, "ticker", None)
        if ticker is not None:
            try:
                ticker.release()
            except Exception:
                pass
            self.ticker = None
        if self.server is not None:
            self.server.close()
            self.server = None
        super().close()
