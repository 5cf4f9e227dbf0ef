"""One world of the driving task as the environments hold it: its server
(started here, or attached), its Rust stepper, the arrays the stepper
writes into, and what it takes to bring the world back after its server
died (a fresh server, the episode's seed, its actions replayed)."""

from __future__ import annotations

from dataclasses import dataclass, field
from typing import Dict, List, Optional, Tuple

import numpy as np

from .. import _errors
from .._simbus import DRIVING_ACTOR_VALUES, DRIVING_EGO_VALUES, DRIVING_REWARD_TERMS, DrivingWorld
from ._servers import ServerProcess, unique_world

#: The reward terms, in the order of `info["reward_terms"]`' columns.
REWARD_TERMS: Tuple[str, ...] = tuple(DRIVING_REWARD_TERMS)

#: Default weight of each reward term.
DEFAULT_WEIGHTS: Dict[str, float] = {
    "progress": 1.0,     # per metre advanced along the route
    "collision": 10.0,   # once, on the step the ego hits something
    "lane": 0.1,         # per metre the ego's centre is outside its lane
    "off_road": 5.0,     # once, when the ego is 4 m off its route (ends the episode)
    "red_light": 5.0,    # once per red light the ego drives through
}

#: Errors that mean the world's server is gone or stuck.
WORLD_LOST = (_errors.ServerGone, _errors.TimeoutError, _errors.Restarted)


@dataclass
class DrivingConfig:
    """What a driving world holds and how its episodes go."""

    scene: str = "town"
    vehicles: int = 0
    walkers: int = 0
    cross_factor: float = 0.5
    delta_seconds: float = 0.1
    max_substep_delta_time: float = 0.02
    actors: int = 6
    route_points: int = 10
    route_length: float = 300.0
    weights: Dict[str, float] = field(default_factory=dict)
    end_on_collision: bool = True
    max_episode_steps: int = 1000
    camera: Optional[Tuple[int, int]] = None
    lidar: Optional[Tuple[int, int]] = None
    discrete: bool = False
    timeout: float = 10.0
    server_binary: Optional[str] = None

    def weight_list(self) -> List[float]:
        unknown = set(self.weights) - set(REWARD_TERMS)
        if unknown:
            raise ValueError(f"unknown reward terms {sorted(unknown)}; the terms are {REWARD_TERMS}")
        merged = {**DEFAULT_WEIGHTS, **self.weights}
        return [float(merged[t]) for t in REWARD_TERMS]

    @property
    def lidar_points(self) -> int:
        """Points in one lidar observation (channels x points per channel)."""
        return 0 if self.lidar is None else int(self.lidar[0]) * int(self.lidar[1])

    def arrays(self, rows: int):
        """Zeroed batch arrays for `rows` egos: flat observations, camera,
        lidar, reward, terminated, truncated, reward terms."""
        camera = lidar = None
        if self.camera is not None:
            camera = np.zeros((rows, self.camera[1], self.camera[0], 3), np.uint8)
        if self.lidar is not None:
            lidar = np.zeros((rows, self.lidar_points, 4), np.float32)
        return (np.zeros((rows, self.row), np.float32), camera, lidar, np.zeros(rows, np.float32),
                np.zeros(rows, np.bool_), np.zeros(rows, np.bool_), np.zeros((rows, len(REWARD_TERMS)), np.float32))

    @property
    def row(self) -> int:
        return DRIVING_EGO_VALUES + self.actors * DRIVING_ACTOR_VALUES + self.route_points * 2


def observation_views(config: DrivingConfig, flat: np.ndarray, camera: Optional[np.ndarray],
                      lidar: Optional[np.ndarray] = None) -> Dict[str, np.ndarray]:
    """The Dict observation over `flat` (rows x config.row float32): views, not copies."""
    n = flat.shape[0]
    a = DRIVING_EGO_VALUES
    b = a + config.actors * DRIVING_ACTOR_VALUES
    views = {
        "ego": flat[:, :a],
        "actors": flat[:, a:b].reshape(n, config.actors, DRIVING_ACTOR_VALUES),
        "route": flat[:, b:].reshape(n, config.route_points, 2),
    }
    if camera is not None:
        views["camera"] = camera
    if lidar is not None:
        views["lidar"] = lidar
    return views


class Slot:
    """One world: `egos` ego vehicles, observed into rows of the caller's arrays."""

    def __init__(self, config: DrivingConfig, *, egos: int, arrays, world: Optional[str] = None):
        """`arrays`: this world's rows of the batch arrays (`DrivingConfig.arrays`' order)."""
        self.config = config
        self.egos = egos
        flat, camera, lidar, reward, terminated, truncated, terms = arrays
        self.flat, self.camera, self.lidar = flat, camera, lidar
        self.reward, self.terminated, self.truncated, self.terms = reward, terminated, truncated, terms
        self.attached = world is not None
        self.server: Optional[ServerProcess] = None
        if world is None:
            world = unique_world()
            self.server = ServerProcess(world, scene=config.scene, binary=config.server_binary)
        self.world_name = world
        self.world: Optional[DrivingWorld] = None
        self.seed = 0
        self.actions: List[np.ndarray] = []
        self.restarts = 0
        try:
            self._connect()
        except BaseException:
            self.close()
            raise

    def _connect(self) -> None:
        c = self.config
        try:
            self.world = DrivingWorld(
                self.world_name, scene=c.scene, egos=self.egos, vehicles=c.vehicles, walkers=c.walkers,
                cross_factor=c.cross_factor,
                delta_seconds=c.delta_seconds, max_substep_delta_time=c.max_substep_delta_time,
                actors=c.actors, route_points=c.route_points, route_length=c.route_length,
                weights=c.weight_list(), end_on_collision=c.end_on_collision,
                max_episode_steps=c.max_episode_steps, camera=c.camera, lidar=c.lidar, discrete=c.discrete,
                timeout=c.timeout,
            )
        except _errors.TimeoutError as e:
            if self.server is not None and not self.server.alive():
                raise _errors.ServerGone(
                    f"the server of world '{self.world_name}' exited at start: {self.server.log_tail()}") from e
            raise

    def reset(self, seed: int) -> None:
        self.seed = int(seed)
        self.actions.clear()
        self.world.reset(self.seed, self.flat, self.camera, self.lidar)

    def send(self, actions: np.ndarray) -> None:
        """Sends a step; it joins the episode's log once sent, or when the
        world was lost on the way (a recovery replays it), not when refused."""
        step = np.array(actions, dtype=np.float32, copy=True)
        try:
            self.world.send(step)
        except WORLD_LOST:
            self.actions.append(step)
            raise
        self.actions.append(step)

    def ready(self) -> bool:
        return self.world.ready()

    def finish(self) -> int:
        return self.world.finish(self.flat, self.reward, self.terminated, self.truncated, self.terms,
                                 self.camera, self.lidar)

    def recover(self) -> str:
        """Brings the world back after its server died or stopped answering:
        a fresh server (or, attached, the one that came back), the episode
        restarted from its seed and its actions replayed, so the episode goes
        on exactly where it was. Returns what happened, for `info`."""
        self.restarts += 1
        self.world = None
        if self.server is not None:
            self.server.start()
        self._connect()
        replay = list(self.actions)
        self.reset(self.seed)
        for actions in replay:
            self.send(actions)
            self.finish()
        return f"world '{self.world_name}' restarted, {len(replay)} steps replayed"

    def close(self) -> None:
        if self.world is not None:
            self.world.close()
            self.world = None
        if self.server is not None:
            self.server.close()
            self.server = None
