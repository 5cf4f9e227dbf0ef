"""simbus for reinforcement learning: Gymnasium and PettingZoo environments
over simbus worlds (``pip install simbus[gym]``).

- `DrivingEnv`: an ego vehicle on the town, following a seeded route
  among traffic; `WorldEnv`: your own task over any world.
- `VectorEnv`: N worlds as one `gymnasium.vector.VectorEnv`, observations
  written straight into batch arrays, sync or async (`send`/`recv`).
- `ParallelEnv`: several egos in one world (PettingZoo).
- `RayVectorEnv`: the worlds spread over a Ray cluster's nodes.

>>> import simbus.gym
>>> envs = simbus.gym.VectorEnv("driving", num_envs=8, seed=0)  # doctest: +SKIP
>>> obs, info = envs.reset()                                    # doctest: +SKIP
"""

from ._servers import ServerProcess, find_server, unique_world
from ._slot import DEFAULT_WEIGHTS, REWARD_TERMS, DrivingConfig
from .driving import DrivingEnv, driving_spaces
from .vector import VectorEnv
from .world_env import WorldEnv

try:  # PettingZoo is optional
    from .parallel import ParallelEnv
except ImportError:  # pragma: no cover - without pettingzoo
    ParallelEnv = None  # type: ignore[assignment,misc]


def __getattr__(name):
    # Ray is optional and heavy: imported on first use only.
    if name == "RayVectorEnv":
        from .distributed import RayVectorEnv

        return RayVectorEnv
    raise AttributeError(name)

__all__ = [
    "DEFAULT_WEIGHTS",
    "REWARD_TERMS",
    "DrivingConfig",
    "DrivingEnv",
    "ParallelEnv",
    "RayVectorEnv",
    "ServerProcess",
    "VectorEnv",
    "WorldEnv",
    "driving_spaces",
    "find_server",
    "unique_world",
]
