"""`RayVectorEnv`: the driving task's worlds spread over a Ray cluster. Each
Ray actor owns a few worlds on its node — their servers started there,
their shared memory staying node-local — and the driver sees one
`gymnasium.vector.VectorEnv`. A node that dies is noticed, its worlds are
started again on the nodes left and their episodes replayed from the
driver's log to where they were: no step is lost or repeated.

Needs ``ray`` (``pip install ray``), imported only here."""

from __future__ import annotations

import os
from typing import Any, Dict, List, Optional, Sequence, Tuple

import numpy as np
import ray
from gymnasium.utils import seeding
from gymnasium.vector import AutoresetMode
from gymnasium.vector import VectorEnv as GymVectorEnv
from gymnasium.vector.utils import batch_space

from ray.util.scheduling_strategies import NodeAffinitySchedulingStrategy

from ._slot import DrivingConfig
from .driving import action_rows, driving_spaces, episode_seed
from .vector import VectorEnv

#: Ray's errors that mean an actor (or its node) is gone or stuck.
RAY_LOST = (ray.exceptions.RayActorError, ray.exceptions.GetTimeoutError,
            ray.exceptions.WorkerCrashedError, ray.exceptions.NodeDiedError)
#: How many times a lost actor's worlds are started again elsewhere.
RECOVERY_ATTEMPTS = 3

#: What a step of one actor's worlds returns: the observation rows, rewards,
#: terminations, truncations, reward terms and each world's steps since its
#: episode began.
Batch = Tuple[Dict[str, np.ndarray], np.ndarray, np.ndarray, np.ndarray, np.ndarray, np.ndarray]


class NodeWorlds:
    """The worlds one Ray actor owns on its node (a `VectorEnv` whose
    episodes the driver starts: it draws no seed of its own)."""

    def __init__(self, count: int, config: Dict[str, Any], bin_dir: Optional[str]):
        if bin_dir:
            os.environ.setdefault("SIMBUS_BIN_DIR", bin_dir)
        self.envs = VectorEnv("driving", num_envs=count, autoreset_mode="Disabled", **config)

    def node(self) -> str:
        """The address of the node this actor runs on."""
        return ray.util.get_node_ip_address()

    def _batch(self) -> Batch:
        e = self.envs
        steps = np.array([s.world.episode_steps for s in e.slots], np.int64)
        return ({k: v.copy() for k, v in e._views.items()}, e._reward.copy(), e._terminated.copy(),
                e._truncated.copy(), e._terms.copy(), steps)

    def begin(self, seeds: Sequence[int]) -> Batch:
        """Starts every world's episode with its episode seed."""
        for slot, seed in zip(self.envs.slots, seeds):
            slot.reset(int(seed))
        self.envs._reward[:] = 0.0
        self.envs._terminated[:] = False
        self.envs._truncated[:] = False
        self.envs._terms[:] = 0.0
        return self._batch()

    def step(self, actions: np.ndarray, resets: Dict[int, int]) -> Batch:
        """Steps every world with its row of `actions`, except those in
        `resets` ({world: episode seed}), whose next episode starts instead."""
        slots = self.envs.slots
        for i, slot in enumerate(slots):
            if i not in resets:
                slot.send(actions[i:i + 1])
        for i, slot in enumerate(slots):
            if i in resets:
                slot.reset(resets[i])
                self.envs._reward[i] = 0.0
                self.envs._terminated[i] = False
                self.envs._truncated[i] = False
                self.envs._terms[i] = 0.0
            else:
                slot.finish()
        return self._batch()

    def replay(self, i: int, seed: int, actions: List[np.ndarray]) -> None:
        """Brings world `i` to where its episode was: started with `seed`,
        then `actions` stepped."""
        slot = self.envs.slots[i]
        slot.reset(int(seed))
        for a in actions:
            slot.send(a)
            slot.finish()

    def pids(self) -> List[int]:
        """The worlds' servers' process ids."""
        return [s.server.pid for s in self.envs.slots if s.server is not None]

    def close(self) -> None:
        self.envs.close()


class RayVectorEnv(GymVectorEnv):
    """`num_envs` driving worlds in Ray actors of `worlds_per_actor` worlds
    each, spread over the cluster's nodes (``ray.init`` is called with
    `address` unless Ray is already initialised). Gymnasium's ``NextStep``
    autoreset; `seed` as `VectorEnv`'s. ``info["restarted"]`` names the
    worlds brought back after their node died and ``info["nodes"]`` says
    where each world runs."""

    def __init__(self, num_envs: int, *, worlds_per_actor: int = 2, seed: Optional[int] = None,
                 address: Optional[str] = None, step_timeout: float = 120.0,
                 bin_dir: Optional[str] = None, **config: Any):
        if not ray.is_initialized():
            ray.init(address=address, log_to_driver=False)
        self.config = DrivingConfig(**config)
        self.task = dict(config)
        self.num_envs = num_envs
        self.metadata = {"autoreset_mode": AutoresetMode.NEXT_STEP, "render_modes": []}
        self.single_observation_space, self.single_action_space = driving_spaces(self.config)
        self.observation_space = batch_space(self.single_observation_space, num_envs)
        self.action_space = batch_space(self.single_action_space, num_envs)
        self.step_timeout = step_timeout
        self.bin_dir = bin_dir or os.environ.get("SIMBUS_BIN_DIR")
        self._remote = ray.remote(num_cpus=1, max_restarts=0)(NodeWorlds)
        self.ranges = [range(i, min(i + worlds_per_actor, num_envs)) for i in range(0, num_envs, worlds_per_actor)]
        self.actors = [self._start(len(r)) for r in self.ranges]
        self.nodes = ray.get([a.node.remote() for a in self.actors], timeout=step_timeout)
        self._rngs = [seeding.np_random(None)[0] for _ in range(num_envs)]
        self._seeds = [0] * num_envs
        self._log: List[List[np.ndarray]] = [[] for _ in range(num_envs)]
        self._autoreset = np.zeros(num_envs, np.bool_)
        self._initial_seed = seed

    def _start(self, count: int, node_id: Optional[str] = None):
        if node_id is None:
            strategy: Any = "SPREAD"
        else:
            strategy = NodeAffinitySchedulingStrategy(node_id=node_id, soft=False)
        return self._remote.options(scheduling_strategy=strategy).remote(count, self.task, self.bin_dir)

    def _gather(self, batches: List[Batch]):
        obs = {k: np.concatenate([b[0][k] for b in batches]) for k in batches[0][0]}
        return (obs, *[np.concatenate([b[j] for b in batches]) for j in range(1, 6)])

    def _live_node(self, lost: str) -> Optional[str]:
        """A node Ray says is alive, not at address `lost` (the one whose
        actor just failed: Ray may not have marked it dead yet), the one
        holding the fewest of these worlds."""
        load = {n: self.nodes.count(n) for n in self.nodes}
        alive = [n for n in ray.nodes() if n.get("Alive") and n.get("NodeManagerAddress") != lost]
        alive.sort(key=lambda n: load.get(n.get("NodeManagerAddress"), 0))
        return alive[0]["NodeID"] if alive else None

    def _recover(self, k: int) -> str:
        """Starts actor `k`'s worlds again on a live node and replays their
        episodes (the step that found it dead not included)."""
        old = self.nodes[k]
        try:
            ray.kill(self.actors[k])
        except Exception:
            pass
        for attempt in range(RECOVERY_ATTEMPTS):
            node = self._live_node(old)
            if node is None:
                raise RuntimeError(f"node {old} was lost and no other node is alive to take its worlds")
            self.actors[k] = self._start(len(self.ranges[k]), node)
            try:
                self.nodes[k] = ray.get(self.actors[k].node.remote(), timeout=self.step_timeout)
                ray.get([self.actors[k].replay.remote(j, self._seeds[i], self._log[i])
                         for j, i in enumerate(self.ranges[k])], timeout=self.step_timeout)
                return f"node {old} lost: its worlds restarted on {self.nodes[k]}, their episodes replayed"
            except RAY_LOST:
                if attempt + 1 == RECOVERY_ATTEMPTS:
                    raise
        raise AssertionError("unreachable")

    def _call(self, make) -> Tuple[List[Batch], Dict[int, str]]:
        """Runs `make(k)` (a remote call) on every actor; an actor that
        died is recovered and its call made again."""
        refs = [make(k) for k in range(len(self.actors))]
        batches: List[Optional[Batch]] = [None] * len(refs)
        restarted: Dict[int, str] = {}
        for k, ref in enumerate(refs):
            try:
                batches[k] = ray.get(ref, timeout=self.step_timeout)
            except RAY_LOST as e:
                note = self._recover(k)
                for i in self.ranges[k]:
                    restarted[i] = f"{note} ({type(e).__name__})"
                batches[k] = ray.get(make(k), timeout=self.step_timeout)
        return batches, restarted  # type: ignore[return-value]

    def _info(self, terms: np.ndarray, steps: np.ndarray, restarted: Dict[int, str]) -> Dict[str, Any]:
        info: Dict[str, Any] = {"reward_terms": terms, "_reward_terms": np.ones(self.num_envs, np.bool_),
                                "episode_steps": steps,
                                "nodes": np.array([self.nodes[k] for k, r in enumerate(self.ranges) for _ in r])}
        if restarted:
            info["restarted"] = np.array([restarted.get(i, "") for i in range(self.num_envs)], dtype=object)
            info["_restarted"] = np.array([i in restarted for i in range(self.num_envs)], np.bool_)
        return info

    def reset(self, *, seed: Optional[int] = None, options: Optional[Dict[str, Any]] = None):
        if seed is None and self._initial_seed is not None:
            seed, self._initial_seed = self._initial_seed, None
        for i in range(self.num_envs):
            if seed is not None:
                self._rngs[i] = seeding.np_random(int(seed) + i)[0]
            self._seeds[i] = episode_seed(self._rngs[i])
            self._log[i] = []
        self._autoreset[:] = False
        batches, restarted = self._call(
            lambda k: self.actors[k].begin.remote([self._seeds[i] for i in self.ranges[k]]))
        obs, _, _, _, terms, steps = self._gather(batches)
        return obs, self._info(terms, steps, restarted)

    def step(self, actions):
        rows = action_rows(self.config, actions, self.num_envs)
        resets: Dict[int, int] = {}
        for i in np.flatnonzero(self._autoreset):
            self._seeds[i] = episode_seed(self._rngs[i])
            self._log[i] = []
            resets[int(i)] = self._seeds[i]

        def call(k):
            r = self.ranges[k]
            local = {j: resets[i] for j, i in enumerate(r) if i in resets}
            return self.actors[k].step.remote(rows[r.start:r.stop], local)

        batches, restarted = self._call(call)
        for i in range(self.num_envs):
            if i not in resets:
                self._log[i].append(rows[i:i + 1].copy())
        obs, reward, terminated, truncated, terms, steps = self._gather(batches)
        self._autoreset = np.logical_or(terminated, truncated)
        return obs, reward.astype(np.float64), terminated, truncated, self._info(terms, steps, restarted)

    def close_extras(self, **kwargs: Any) -> None:
        for actor in getattr(self, "actors", []):
            try:
                ray.get(actor.close.remote(), timeout=30)
            except Exception:
                pass
            try:
                ray.kill(actor)
            except Exception:
                pass
        self.actors = []
