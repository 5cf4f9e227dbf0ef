"""`DrivingEnv`: drive an ego vehicle along a route on simbus's town, as a
Gymnasium environment, one fixed step of simulation per `step`."""

from __future__ import annotations

from typing import Any, Dict, Optional, Tuple

import gymnasium as gym
import numpy as np
from gymnasium import spaces

from ._slot import WORLD_LOST, DrivingConfig, Slot, observation_views

SEED_BOUND = 2**63 - 1
#: Every state value is within this (metres, m/s, radians).
OBSERVATION_BOUND = 1.0e4


def driving_spaces(config: DrivingConfig) -> Tuple[spaces.Dict, spaces.Space]:
    """One ego's observation and action spaces under `config`."""
    inf = np.float32(OBSERVATION_BOUND)
    obs = {
        "ego": spaces.Box(-inf, inf, (8,), np.float32),
        "actors": spaces.Box(-inf, inf, (config.actors, 6), np.float32),
        "route": spaces.Box(-inf, inf, (config.route_points, 2), np.float32),
    }
    if config.camera is not None:
        w, h = config.camera
        obs["camera"] = spaces.Box(0, 255, (h, w, 3), np.uint8)
    if config.lidar is not None:
        obs["lidar"] = spaces.Box(-inf, inf, (config.lidar_points, 4), np.float32)
    if config.discrete:
        action: spaces.Space = spaces.Discrete(9)
    else:
        action = spaces.Box(np.float32(-1.0), np.float32(1.0), (2,), np.float32)
    return spaces.Dict(obs), action


def episode_seed(rng: np.random.Generator) -> int:
    """The seed of the next episode, drawn from an environment's generator."""
    return int(rng.integers(SEED_BOUND))


def action_rows(config: DrivingConfig, action: Any, rows: int) -> np.ndarray:
    """`action` (one per ego) as the float32 rows the world takes."""
    if config.discrete:
        a = np.asarray(action, dtype=np.float32).reshape(rows, 1)
    else:
        a = np.asarray(action, dtype=np.float32).reshape(rows, 2)
    return np.ascontiguousarray(a)


class DrivingEnv(gym.Env):
    """An ego vehicle on simbus's town, following a seeded route among
    traffic that drives itself.

    - **Action**: ``Box(-1, 1, (2,))`` — steer (positive left) and pedal
      (positive throttle, negative brake); with ``discrete=True``,
      ``Discrete(9)`` (coast, throttle, brake, gentle and hard turns each
      way, full throttle, full brake).
    - **Observation**: a ``Dict`` — ``ego`` (speed m/s, metres left of the
      route, heading error rad, last steer, last pedal, metres to the next
      stop line (50: none near), whether it is red or a stop sign, the speed
      limit m/s), ``actors`` (the nearest moving actors within 50 m: forward
      and left offsets, relative velocity forward and left, walker,
      present), ``route`` (the route's next points every 4 m, forward and
      left, metres), with ``camera=(w, h)`` an RGB image from the roof, and
      with ``lidar=(channels, points)`` the lidar's points (x forward, y up,
      z right, intensity; unused rows 0).
    - **Reward**: the weighted sum of ``progress`` (metres advanced),
      ``collision``, ``lane`` (metres outside the lane), ``off_road`` and
      ``red_light``; ``info["reward_terms"]`` has each term, ``weights``
      changes them.
    - **terminated**: a collision (``end_on_collision``), 4 m off the
      route, or the route's end; **truncated**: ``max_episode_steps``.
    - ``reset(seed=s)`` restores the episode's snapshot and puts the ego,
      the traffic and the walkers where `s` says: the same seed and actions
      give the same episode, bit for bit, even across a server crash.

    ``scene`` is any simbus scene (its roads: the town's streets, a ring
    road elsewhere). The env starts its own ``sim-server`` (found as
    `simbus.gym.find_server` says) unless ``world=`` names a running one.
    """

    metadata = {"render_modes": ["rgb_array"], "render_fps": 10}

    def __init__(self, *, world: Optional[str] = None, render_mode: Optional[str] = None, **config: Any):
        self.config = DrivingConfig(**config)
        if render_mode not in (None, "rgb_array"):
            raise ValueError(f"render_mode must be None or 'rgb_array', not {render_mode!r}")
        if render_mode == "rgb_array" and self.config.camera is None:
            self.config.camera = (160, 120)
        self.render_mode = render_mode
        self.metadata = {**self.metadata, "render_fps": round(1.0 / self.config.delta_seconds)}
        self.observation_space, self.action_space = driving_spaces(self.config)
        arrays = self.config.arrays(1)
        self._flat, self._camera, lidar, self._reward, self._terminated, self._truncated, self._terms = arrays
        self._views = observation_views(self.config, self._flat, self._camera, lidar)
        self._slot = Slot(self.config, egos=1, arrays=arrays, world=world)

    @property
    def world(self) -> str:
        """The name of the world this env drives."""
        return self._slot.world_name

    @property
    def server_pid(self) -> Optional[int]:
        return self._slot.world.server_pid if self._slot.world else None

    def _obs(self) -> Dict[str, np.ndarray]:
        return {k: v[0].copy() for k, v in self._views.items()}

    def reset(self, *, seed: Optional[int] = None, options: Optional[Dict[str, Any]] = None):
        super().reset(seed=seed)
        info: Dict[str, Any] = {}
        try:
            self._slot.reset(episode_seed(self.np_random))
        except WORLD_LOST:
            info["restarted"] = self._slot.recover()
        info["episode_seed"] = self._slot.seed
        return self._obs(), info

    def step(self, action: Any):
        rows = action_rows(self.config, action, 1)
        info: Dict[str, Any] = {}
        try:
            self._slot.send(rows)
            self._slot.finish()
        except WORLD_LOST:
            info["restarted"] = self._slot.recover()
        info["reward_terms"] = dict(zip(("progress", "collision", "lane", "off_road", "red_light"),
                                        self._terms[0].tolist()))
        return (self._obs(), float(self._reward[0]), bool(self._terminated[0]), bool(self._truncated[0]), info)

    def render(self):
        if self.render_mode != "rgb_array":
            return None
        return self._camera[0].copy()

    def close(self):
        slot = getattr(self, "_slot", None)
        if slot is not None:
            slot.close()
            self._slot = None
        super().close()
