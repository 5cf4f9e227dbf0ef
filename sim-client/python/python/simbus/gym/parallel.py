"""`ParallelEnv`: several ego vehicles in one world, one agent each, as a
PettingZoo `ParallelEnv`: every agent acts, then one tick steps them all."""

from __future__ import annotations

from typing import Any, Dict, Optional

import numpy as np
from gymnasium.utils import seeding
from pettingzoo import ParallelEnv as PettingZooParallelEnv

from ._slot import REWARD_TERMS, WORLD_LOST, DrivingConfig, Slot, observation_views
from .driving import action_rows, driving_spaces, episode_seed


class ParallelEnv(PettingZooParallelEnv):
    """`agents` egos (``ego_0``, ``ego_1``, …) on one town, each with
    `simbus.gym.DrivingEnv`'s spaces, rewards and endings; an agent whose
    episode ended leaves ``agents`` (its car stays, braking). One `step` is
    one fixed step of the world for all of them."""

    metadata = {"name": "simbus_driving_v0", "render_modes": [], "is_parallelizable": True}

    def __init__(self, agents: int = 2, *, world: Optional[str] = None, **config: Any):
        if agents < 1:
            raise ValueError("agents must be at least 1")
        self.config = DrivingConfig(**config)
        self.possible_agents = [f"ego_{i}" for i in range(agents)]
        self.agents = []
        self._obs_space, self._act_space = driving_spaces(self.config)
        arrays = self.config.arrays(agents)
        self._flat, self._camera, lidar, self._reward, self._terminated, self._truncated, self._terms = arrays
        self._views = observation_views(self.config, self._flat, self._camera, lidar)
        self._rng = seeding.np_random(None)[0]
        self._slot = Slot(self.config, egos=agents, arrays=arrays, world=world)

    def observation_space(self, agent: str):
        return self._obs_space

    def action_space(self, agent: str):
        return self._act_space

    def _agent_obs(self, i: int) -> Dict[str, np.ndarray]:
        return {k: v[i].copy() for k, v in self._views.items()}

    def reset(self, seed: Optional[int] = None, options: Optional[Dict[str, Any]] = None):
        if seed is not None:
            self._rng = seeding.np_random(seed)[0]
        infos: Dict[str, Dict[str, Any]] = {a: {} for a in self.possible_agents}
        try:
            self._slot.reset(episode_seed(self._rng))
        except WORLD_LOST:
            note = self._slot.recover()
            for a in infos:
                infos[a]["restarted"] = note
        self.agents = list(self.possible_agents)
        return {a: self._agent_obs(i) for i, a in enumerate(self.possible_agents)}, infos

    def step(self, actions: Dict[str, Any]):
        rows = np.zeros((len(self.possible_agents), 1 if self.config.discrete else 2), np.float32)
        if not self.config.discrete:
            rows[:, 1] = -1.0  # agents that left brake
        else:
            rows[:, 0] = 8  # full brake
        for i, agent in enumerate(self.possible_agents):
            if agent in self.agents and agent in actions:
                rows[i] = action_rows(self.config, actions[agent], 1)[0]
        infos: Dict[str, Dict[str, Any]] = {a: {} for a in self.agents}
        try:
            self._slot.send(rows)
            self._slot.finish()
        except WORLD_LOST:
            note = self._slot.recover()
            for a in infos:
                infos[a]["restarted"] = note
        obs, rewards, terminations, truncations = {}, {}, {}, {}
        for i, agent in enumerate(self.possible_agents):
            if agent not in self.agents:
                continue
            obs[agent] = self._agent_obs(i)
            rewards[agent] = float(self._reward[i])
            terminations[agent] = bool(self._terminated[i])
            truncations[agent] = bool(self._truncated[i])
            infos[agent]["reward_terms"] = dict(zip(REWARD_TERMS, self._terms[i].tolist()))
        self.agents = [a for a in self.agents if not (terminations[a] or truncations[a])]
        return obs, rewards, terminations, truncations, infos

    def close(self):
        slot = getattr(self, "_slot", None)
        if slot is not None:
            slot.close()
            self._slot = None
