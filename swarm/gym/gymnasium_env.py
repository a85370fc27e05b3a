"""A Gymnasium ``Env`` over an engine's run: one follower driven, its action
its two wheel speeds; the other robots fly their laws. Spaces and reward:
gym.followers and docs/learning.md. ``terminated`` when the leader finished
its path, ``truncated`` when the run's duration is reached.

Importing it registers :data:`ENV_ID` with Gymnasium, so that
``gymnasium.make(ENV_ID, scenario="fig11_obstacles", ...)`` builds one.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import gymnasium
import numpy as np
from gymnasium import spaces

from formation_swarm.engine.core import FaultLike
from formation_swarm.gym.followers import Followers

ENV_ID = "formation_swarm/Follower-v0"


class FollowerEnv(gymnasium.Env[np.ndarray, np.ndarray]):
    """``FollowerEnv(scenario, follower=None, seed=None, overrides=None,
    faults=())``: follower ``follower`` (a robot id; None: the first
    follower) of ``scenario`` driven, with formation_swarm.Engine's
    ``seed``, ``overrides`` and ``faults``. ``reset(seed=...)``: that
    seed's run; no seed, the engine's seed first, then one more each episode."""

    metadata = {"render_modes": []}

    def __init__(
        self,
        scenario: str | Path,
        follower: int | None = None,
        *,
        seed: int | None = None,
        overrides: Mapping[str, Any] | None = None,
        faults: Sequence[FaultLike] | FaultLike = (),
    ) -> None:
        self.render_mode = None
        self.run = Followers(
            scenario, None if follower is None else [follower], seed=seed, overrides=overrides, faults=faults
        )
        self.robot_id = self.run.ids[0]
        self.observation_space = spaces.Box(*self.run.observation_bounds(), dtype=np.float32)
        self.action_space = spaces.Box(*self.run.action_bounds(), dtype=np.float32)

    def reset(
        self, *, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[np.ndarray, dict[str, Any]]:
        """A new episode (``options`` are not used): the follower's first observation and info."""
        super().reset(seed=seed)
        obs = self.run.reset(seed)
        return obs[self.robot_id], dict(self.run.info()[self.robot_id])

    def step(self, action: Any) -> tuple[np.ndarray, float, bool, bool, dict[str, Any]]:
        obs, rewards, terminated, truncated, infos = self.run.step({self.robot_id: action})
        rid = self.robot_id
        return obs[rid], rewards[rid], terminated, truncated, infos[rid]


if ENV_ID not in gymnasium.registry:  # once per process, whoever imports this first
    gymnasium.register(ENV_ID, entry_point=FollowerEnv)
