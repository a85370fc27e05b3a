"""Followers of an engine's run driven from outside, what both learning
adapters (pettingzoo_env, gymnasium_env) are made of: each driven
follower's observation, reward and action as arrays, the episodes' seeds,
and the end of an episode. No PettingZoo or Gymnasium here.

An observation is :data:`OBSERVATION`'s six numbers (float32), what the
follower's controller gets at the tick (agents.controller.FollowerInput):
the reading of its reference's marker (zeros when none is seen: ``seen``
0) and its slot in the formation it flies. A tick where the robot gets no
observation (a lost one, its agent killed or frozen) shows as nothing seen.
The reward is minus the follower's formation error after the tick, in m
(Engine.formation_errors: what world.metrics records for that tick).
"""

from __future__ import annotations

import math
from collections.abc import Mapping, Sequence
from pathlib import Path
from typing import Any

import numpy as np

from formation_swarm.agents.controller import FollowerInput
from formation_swarm.agents.inbox import RHO_SIGMAS
from formation_swarm.common.checks import SEED_MAX
from formation_swarm.engine.core import Engine, FaultLike
from formation_swarm.runtime.summary import LEADER_FINISHED

# The observation's entries, in order.
OBSERVATION = ("seen", "rho_m", "phi_rad", "beta_rad", "slot_x_m", "slot_y_m")
ACTION = ("left_mps", "right_mps")


class Followers:
    """The followers ``followers`` (robot ids; None: every follower) of one
    engine's run, driven tick by tick; the other robots fly their laws.
    ``scenario``, ``seed``, ``overrides`` and ``faults`` are the engine's
    (formation_swarm.Engine)."""

    def __init__(
        self,
        scenario: str | Path,
        followers: Sequence[int] | None = None,
        *,
        seed: int | None = None,
        overrides: Mapping[str, Any] | None = None,
        faults: Sequence[FaultLike] | FaultLike = (),
    ) -> None:
        self.engine = Engine(scenario, seed=seed, overrides=overrides, faults=faults)
        sc = self.engine.scenario
        self.ids = _driven(followers, sc.follower_ids)
        self.max_wheel_mps = sc.max_wheel_mps
        self.max_rho_m = sc.camera.range_m + RHO_SIGMAS * sc.camera.sigma_rho_m  # the inbox refuses farther
        formations = [sc.formation_by_code(c) for c in range(len(sc.formation_names))]
        self._start_slots = {rid: formations[sc.code_of(sc.leader.formation)].slots[rid].offset for rid in self.ids}
        # Any slot of the run, either way: a follower's slot changes with the formation.
        self.max_offset_m = max(abs(v) for f in formations for slot in f.slots.values() for v in slot.offset)
        self._low, self._high = self.observation_bounds()
        self._seed: int | None = None  # the episode's; None before the first
        self._last: dict[int, np.ndarray] = {}

    # -- spaces -----------------------------------------------------------------------
    def observation_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) of an observation: a reading the inbox takes, a slot of the run's formations."""
        m = self.max_offset_m
        low = [0.0, 0.0, -math.pi, -math.pi, -m, -m]
        high = [1.0, self.max_rho_m, math.pi, math.pi, m, m]
        return np.array(low, dtype=np.float32), np.array(high, dtype=np.float32)

    def action_bounds(self) -> tuple[np.ndarray, np.ndarray]:
        """(low, high) of an action: each wheel within robot.max_wheel_mps, either way."""
        m = self.max_wheel_mps
        return np.full(2, -m, dtype=np.float32), np.full(2, m, dtype=np.float32)

    # -- episodes ---------------------------------------------------------------------
    def reset(self, seed: int | None) -> dict[int, np.ndarray]:
        """A new episode, with ``seed``; None: the engine's seed for the first
        episode, then one more than the last one's. Each follower's first observation."""
        if seed is None:
            seed = self.engine.seed if self._seed is None else (self._seed + 1) % (SEED_MAX + 1)
        self.engine.reset(seed)
        self._seed = seed
        self.engine.observe()
        self._last = {rid: self._observation(rid) for rid in self.ids}
        return {rid: obs.copy() for rid, obs in self._last.items()}

    def step(
        self, actions: Mapping[int, Any]
    ) -> tuple[dict[int, np.ndarray], dict[int, float], bool, bool, dict[int, dict[str, Any]]]:
        """One tick with ``actions`` ({robot id: (left_mps, right_mps)}, clipped
        to the wheels' limit; a follower without one flies its law this tick):
        observations, rewards, terminated (the leader finished its path),
        truncated (the run's duration reached) and infos, by robot id."""
        engine = self.engine
        wheels = {rid: self._wheels(rid, a) for rid, a in actions.items()}
        engine.step(wheels)
        engine.observe()  # the next tick's inputs: what the observations show
        self._last = {rid: self._observation(rid) for rid in self.ids}
        obs = {rid: o.copy() for rid, o in self._last.items()}
        infos = self.info()
        rewards = {rid: -info["formation_error_m"] for rid, info in infos.items()}
        ended = engine.end_reason
        return obs, rewards, ended == LEADER_FINISHED, ended is not None and ended != LEADER_FINISHED, infos

    def _wheels(self, rid: int, action: Any) -> tuple[float, float]:
        if rid not in self.ids:
            raise ValueError(f"robot {rid!r} is not driven here; the driven followers are {list(self.ids)}")
        a = np.asarray(action, dtype=np.float64)
        if a.shape != (2,):
            raise ValueError(f"follower {rid}'s action must be {ACTION}, got shape {a.shape}")
        m = self.max_wheel_mps
        left, right = np.clip(a, -m, m).tolist()  # NaN stays NaN: the engine refuses it
        return left, right

    def _observation(self, rid: int) -> np.ndarray:
        """Follower ``rid``'s observation of the tick observed last."""
        inp: FollowerInput | None = self.engine.inputs.get(rid)
        if inp is None:  # no observation this tick: nothing seen, in the slot it last had
            last = self._last.get(rid)
            slot = self._start_slots[rid] if last is None else (float(last[4]), float(last[5]))
            return np.array([0.0, 0.0, 0.0, 0.0, *slot], dtype=np.float32)
        r = inp.reading
        seen = [0.0, 0.0, 0.0, 0.0] if r is None else [1.0, r.rho_m, r.phi_rad, r.beta_rad]
        out = np.array([*seen, inp.slot.offset[0], inp.slot.offset[1]], dtype=np.float32)
        return np.clip(out, self._low, self._high)  # in bounds already (the inbox checks), but for float32 rounding

    def info(self) -> dict[int, dict[str, Any]]:
        """Each driven follower's info now: the ticks run, the sim time (s) and its formation error (m)."""
        engine = self.engine
        errors = engine.formation_errors()
        return {
            rid: {"tick": engine.tick, "time_s": engine.time_s, "formation_error_m": errors[rid]} for rid in self.ids
        }


def _driven(followers: Sequence[int] | None, ids: Sequence[int]) -> tuple[int, ...]:
    """The followers to drive: ``followers`` checked against the run's ``ids``."""
    if followers is None:
        return tuple(ids)
    if isinstance(followers, (str, bytes)) or not isinstance(followers, Sequence):
        raise ValueError(f"followers must be a list of follower ids, got {followers!r}")
    out = tuple(followers)
    bad = [f for f in out if isinstance(f, bool) or not isinstance(f, int) or f not in ids]
    if bad or not out or len(set(out)) != len(out):
        raise ValueError(f"followers must be distinct follower ids of the run ({list(ids)}), got {list(out)}")
    return out
