"""A PettingZoo ``ParallelEnv`` over an engine's run: each driven follower
is an agent (``follower_<id>``) whose action is its two wheel speeds; the
other robots fly their laws. Spaces and reward: gym.followers and
docs/learning.md. The episode ends with the run, for every agent at once:
terminated when the leader finished its path, truncated when the run's
duration is reached.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np
from gymnasium import spaces
from pettingzoo import ParallelEnv

from formation_swarm.engine.core import FaultLike
from formation_swarm.gym.followers import Followers

AGENT_PREFIX = "follower_"


class FollowersEnv(ParallelEnv):
    """``FollowersEnv(scenario, followers=None, seed=None, overrides=None,
    faults=())``: the followers ``followers`` (robot ids; None: all) of
    ``scenario`` driven, with formation_swarm.Engine's ``seed``,
    ``overrides`` and ``faults``. ``reset(seed)``: that seed's run; no
    seed, the engine's seed first, then one more each episode."""

    metadata = {"name": "formation_swarm_followers_v0", "render_modes": []}

    def __init__(
        self,
        scenario: str | Path,
        followers: Sequence[int] | None = None,
        *,
        seed: int | None = None,
        overrides: Mapping[str, Any] | None = None,
        faults: Sequence[FaultLike] | FaultLike = (),
    ) -> None:
        self.render_mode = None
        self.run = Followers(scenario, followers, seed=seed, overrides=overrides, faults=faults)
        self.possible_agents = [f"{AGENT_PREFIX}{rid}" for rid in self.run.ids]
        self.agents: list[str] = []
        self._ids = dict(zip(self.possible_agents, self.run.ids, strict=True))
        # One object per agent, the same at every call (PettingZoo's API test checks it).
        self.observation_spaces = {a: spaces.Box(*self.run.observation_bounds(), dtype=np.float32) for a in self._ids}
        self.action_spaces = {a: spaces.Box(*self.run.action_bounds(), dtype=np.float32) for a in self._ids}

    def observation_space(self, agent: str) -> spaces.Box:
        return self.observation_spaces[agent]

    def action_space(self, agent: str) -> spaces.Box:
        return self.action_spaces[agent]

    def reset(
        self, seed: int | None = None, options: dict[str, Any] | None = None
    ) -> tuple[dict[str, np.ndarray], dict[str, dict[str, Any]]]:
        """A new episode (``options`` are not used); every agent's first observation and info."""
        obs = self.run.reset(seed)
        self.agents = list(self.possible_agents)
        info = self.run.info()
        return {a: obs[self._ids[a]] for a in self.agents}, {a: dict(info[self._ids[a]]) for a in self.agents}

    def step(self, actions: Mapping[str, Any]) -> tuple[dict[str, Any], ...]:
        """One tick: observations, rewards, terminations, truncations, infos
        of the agents live before it; none is live after the run's last tick."""
        live = self.agents
        unknown = [a for a in actions if a not in live]
        if unknown:
            raise ValueError(f"actions for agents not live: {unknown}; live agents are {live}")
        obs, rewards, terminated, truncated, infos = self.run.step({self._ids[a]: act for a, act in actions.items()})
        out = (
            {a: obs[self._ids[a]] for a in live},
            {a: rewards[self._ids[a]] for a in live},
            dict.fromkeys(live, terminated),
            dict.fromkeys(live, truncated),
            {a: infos[self._ids[a]] for a in live},
        )
        if terminated or truncated:
            self.agents = []
        return out

    def render(self) -> None:
        """Nothing to draw here: a run's recording is ``swarm run``'s."""
        return None

    def close(self) -> None:
        """Nothing to release: the run is in this process."""
