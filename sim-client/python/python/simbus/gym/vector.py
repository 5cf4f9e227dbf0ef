"""`VectorEnv`: N driving worlds as one `gymnasium.vector.VectorEnv`, their
observations written by the Rust steppers straight into one batch array
per key, every world's tick in flight at once, and an async mode that
returns whichever worlds finish first (EnvPool's design)."""

from __future__ import annotations

import os
import time
from typing import Any, Dict, List, Optional, Sequence, Union

import numpy as np
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode
from gymnasium.vector import VectorEnv as GymVectorEnv
from gymnasium.vector.utils import batch_space

from ._slot import REWARD_TERMS, WORLD_LOST, DrivingConfig, Slot, observation_views
from .driving import action_rows, driving_spaces, episode_seed

_MODES = {m.value: m for m in AutoresetMode}


class VectorEnv(GymVectorEnv):
    """N worlds of the driving task (`simbus.gym.DrivingEnv`'s, one ego each).

    ``VectorEnv("driving", num_envs=8, seed=0)`` starts 8 servers (reaped by
    ``close()``); ``worlds=[...]`` attaches to running ones instead.
    ``autoreset_mode`` is Gymnasium's (``"NextStep"``, ``"SameStep"``,
    ``"Disabled"`` or an ``AutoresetMode``) with Gymnasium's semantics.

    Sync: ``step(actions)`` sends every world its actions and tick, then
    collects every frame: the servers step at once. Async (``batch_size <
    num_envs``): ``send(actions, env_ids)`` and ``recv()``, which returns the
    first ``batch_size`` worlds to finish, ``info["env_id"]`` saying which.

    A world whose server dies or stops answering is restarted, its episode
    replayed from its seed and actions to where it was, and reported in
    ``info["restarted"]``; no call waits longer than ``timeout``.

    ``copy=False`` returns the batch arrays themselves (valid until the next
    call), the fastest way to read them.
    """

    def __init__(self, task: str = "driving", num_envs: int = 1, *, seed: Optional[int] = None,
                 worlds: Optional[Sequence[str]] = None, autoreset_mode: Union[str, AutoresetMode] = "NextStep",
                 batch_size: Optional[int] = None, copy: bool = True, **config: Any):
        if task != "driving":
            raise ValueError(f"unknown task {task!r}: VectorEnv has 'driving' (WorldEnv is for your own)")
        if worlds is not None:
            num_envs = len(worlds)
        if num_envs < 1:
            raise ValueError("num_envs must be at least 1")
        self.config = DrivingConfig(**config)
        self.num_envs = num_envs
        self.batch_size = num_envs if batch_size is None else int(batch_size)
        if not 1 <= self.batch_size <= num_envs:
            raise ValueError(f"batch_size must be 1..={num_envs}, not {batch_size}")
        mode = _MODES.get(autoreset_mode, autoreset_mode) if isinstance(autoreset_mode, str) else autoreset_mode
        if not isinstance(mode, AutoresetMode):
            raise ValueError(f"autoreset_mode must be one of {sorted(_MODES)}, not {autoreset_mode!r}")
        self.autoreset_mode = mode
        self.metadata = {"autoreset_mode": mode, "render_modes": []}
        self.copy = copy
        self.single_observation_space, self.single_action_space = driving_spaces(self.config)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        n, c = num_envs, self.config
        arrays = c.arrays(n)
        self._flat, self._camera, self._lidar, self._reward, self._terminated, self._truncated, self._terms = arrays
        self._views = observation_views(c, self._flat, self._camera, self._lidar)
        self._rngs: List[np.random.Generator] = [seeding.np_random(None)[0] for _ in range(n)]
        self._autoreset = np.zeros(n, np.bool_)
        self._pending: List[int] = []
        self.slots: List[Slot] = []
        try:
            for i in range(n):
                rows = tuple(None if a is None else a[i:i + 1] for a in arrays)
                self.slots.append(Slot(c, egos=1, arrays=rows, world=None if worlds is None else worlds[i]))
        except BaseException:
            self.close()
            raise
        self._initial_seed = seed

    # -- results ---------------------------------------------------------

    def _obs(self, ids: Optional[np.ndarray] = None) -> Dict[str, np.ndarray]:
        if ids is None:
            return {k: v.copy() for k, v in self._views.items()} if self.copy else dict(self._views)
        return {k: v[ids] for k, v in self._views.items()}

    def _reset_one(self, i: int, seed: Optional[int], restarted: Dict[int, str]) -> None:
        if seed is not None:
            self._rngs[i] = seeding.np_random(seed)[0]
        slot = self.slots[i]
        try:
            slot.reset(episode_seed(self._rngs[i]))
        except WORLD_LOST:
            restarted[i] = slot.recover()

    def _infos(self, restarted: Dict[int, str], ids: Optional[np.ndarray] = None) -> Dict[str, Any]:
        terms = self._terms if ids is None else self._terms[ids]
        count = len(terms)
        info: Dict[str, Any] = {"reward_terms": terms.copy(), "_reward_terms": np.ones(count, np.bool_)}
        if restarted:
            rows = list(range(self.num_envs)) if ids is None else list(ids)
            info["restarted"] = np.array([restarted.get(i, "") for i in rows], dtype=object)
            info["_restarted"] = np.array([i in restarted for i in rows], np.bool_)
        return info

    # -- Gymnasium's API -------------------------------------------------

    def reset(self, *, seed: Optional[Union[int, Sequence[Optional[int]]]] = None,
              options: Optional[Dict[str, Any]] = None):
        if seed is None and self._initial_seed is not None:
            seed, self._initial_seed = self._initial_seed, None
        if seed is None:
            seeds: List[Optional[int]] = [None] * self.num_envs
        elif isinstance(seed, (int, np.integer)):
            seeds = [int(seed) + i for i in range(self.num_envs)]
        else:
            seeds = list(seed)
            if len(seeds) != self.num_envs:
                raise ValueError(f"{len(seeds)} seeds for {self.num_envs} worlds")
        self._drain()
        mask = np.ones(self.num_envs, np.bool_)
        if options is not None and "reset_mask" in options:
            mask = options["reset_mask"]
            if not (isinstance(mask, np.ndarray) and mask.dtype == np.bool_ and mask.shape == (self.num_envs,)):
                raise ValueError(f"options['reset_mask'] must be a bool array of shape ({self.num_envs},)")
            if not mask.any():
                raise ValueError("options['reset_mask'] must reset at least one world")
        restarted: Dict[int, str] = {}
        for i in np.flatnonzero(mask):
            self._reset_one(int(i), seeds[i], restarted)
        self._reward[mask] = 0.0
        self._terminated[mask] = False
        self._truncated[mask] = False
        self._terms[mask] = 0.0
        self._autoreset[mask] = False
        return self._obs(), self._infos(restarted)

    def step(self, actions):
        self.step_async(actions)
        return self.step_wait()

    def step_async(self, actions) -> None:
        """Sends every world its action and tick (the servers step at once)."""
        self.send(actions)

    def step_wait(self, timeout: Optional[float] = None):
        """Collects every world's step (`timeout` is each world's own)."""
        if len(self._pending) != self.num_envs:
            raise RuntimeError("step_wait without step_async for every world")
        return self._collect(list(range(self.num_envs)), ids=None)

    # -- async (EnvPool's send / recv) -----------------------------------

    def send(self, actions, env_ids: Optional[Sequence[int]] = None) -> None:
        """Sends the worlds `env_ids` (all by default) their `actions` (one
        row each, in that order) and their ticks, without waiting."""
        ids = list(range(self.num_envs)) if env_ids is None else [int(i) for i in env_ids]
        rows = action_rows(self.config, actions, len(ids))
        for row, i in zip(rows, ids):
            if i in self._pending:
                raise RuntimeError(f"world {i} already has a step in flight")
            self._pending.append(i)
            if self._autoreset[i] and self.autoreset_mode == AutoresetMode.NEXT_STEP:
                continue  # its step is a reset, done when collected
            if self._autoreset[i] and self.autoreset_mode == AutoresetMode.DISABLED:
                raise RuntimeError(f"world {i}'s episode ended: reset it (options={{'reset_mask': ...}}) first")
            try:
                self.slots[i].send(row[None, :])
            except WORLD_LOST:
                pass  # found and recovered when collected

    def recv(self, timeout: Optional[float] = None):
        """The first `batch_size` worlds to finish their step: (obs, rewards,
        terminations, truncations, infos) of those worlds, ``infos["env_id"]``
        naming them."""
        if len(self._pending) < self.batch_size:
            raise RuntimeError(f"{len(self._pending)} steps in flight, fewer than batch_size={self.batch_size}")
        ready: List[int] = []
        deadline = time.monotonic() + (self.config.timeout if timeout is None else timeout)
        while len(ready) < self.batch_size:
            before = len(ready)
            for i in self._pending:
                if i in ready:
                    continue
                try:
                    if self._autoreset[i] or self.slots[i].ready():
                        ready.append(i)
                except WORLD_LOST:
                    ready.append(i)
                if len(ready) == self.batch_size:
                    break
            if len(ready) == before:
                # Nothing finished this sweep: let the servers have the CPU.
                os.sched_yield()
            if len(ready) < self.batch_size and time.monotonic() > deadline:
                # Never a hang: the oldest pending world is taken (its finish waits its own timeout).
                ready.extend(i for i in self._pending if i not in ready)
                ready = ready[: self.batch_size]
        ids = np.array(ready)
        obs, rew, term, trunc, info = self._collect(ready, ids=ids)
        info["env_id"] = ids
        return obs, rew, term, trunc, info

    # -- collecting ------------------------------------------------------

    def _collect(self, order: List[int], ids: Optional[np.ndarray]):
        restarted: Dict[int, str] = {}
        final: Dict[int, Any] = {}
        for i in order:
            self._pending.remove(i)
            slot = self.slots[i]
            if self._autoreset[i] and self.autoreset_mode == AutoresetMode.NEXT_STEP:
                self._reset_one(i, None, restarted)
                self._reward[i] = 0.0
                self._terminated[i] = False
                self._truncated[i] = False
                self._terms[i] = 0.0
                continue
            try:
                slot.finish()
            except WORLD_LOST:
                restarted[i] = slot.recover()
            if self.autoreset_mode == AutoresetMode.SAME_STEP and (self._terminated[i] or self._truncated[i]):
                final[i] = ({k: v[i].copy() for k, v in self._views.items()},
                            {"reward_terms": self._terms[i].copy()})
                terminated, truncated, reward = self._terminated[i], self._truncated[i], self._reward[i]
                self._reset_one(i, None, restarted)
                self._terminated[i], self._truncated[i], self._reward[i] = terminated, truncated, reward
        self._autoreset = np.logical_or(self._terminated, self._truncated)
        if self.autoreset_mode == AutoresetMode.SAME_STEP:
            self._autoreset[:] = False
        if ids is None:
            obs = self._obs()
            rew, term, trunc = self._reward.copy(), self._terminated.copy(), self._truncated.copy()
        else:
            obs = self._obs(ids)
            rew, term, trunc = self._reward[ids], self._terminated[ids], self._truncated[ids]
        info = self._infos(restarted, ids)
        if final:
            # As Gymnasium's vector envs lay them out (its own helper).
            rows = list(range(self.num_envs)) if ids is None else [int(i) for i in ids]
            for row, i in enumerate(rows):
                if i in final:
                    info = self._add_info(info, {"final_obs": final[i][0], "final_info": final[i][1]}, row)
        return obs, rew.astype(np.float64), term, trunc, info

    def _drain(self) -> None:
        """Collects steps still in flight (before a reset)."""
        for i in list(self._pending):
            self._pending.remove(i)
            if self._autoreset[i] and self.autoreset_mode == AutoresetMode.NEXT_STEP:
                continue
            try:
                self.slots[i].finish()
            except WORLD_LOST:
                self.slots[i].recover()

    @property
    def worlds(self) -> List[str]:
        """The worlds' names, in env order."""
        return [s.world_name for s in self.slots]

    def close_extras(self, **kwargs: Any) -> None:
        for slot in getattr(self, "slots", []):
            slot.close()
        self.slots = []
