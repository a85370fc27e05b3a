"""The Gymnasium adapter (formation_swarm.gym.gymnasium_env): Gymnasium's
own checker passes as shipped, the env made by its id is the class, and its
actions are wheel speeds clipped to the wheels' limit."""

from __future__ import annotations

import subprocess
import sys
import warnings

import gymnasium
import numpy as np
import pytest
from gymnasium.utils.env_checker import check_env

from formation_swarm.gym.gymnasium_env import ENV_ID, FollowerEnv

SHORT = {"run.duration_s": 2.0}  # fig11's first 40 ticks


def test_gymnasiums_checker_passes_with_one_warning_said_in_the_docs() -> None:
    env = gymnasium.make(ENV_ID, scenario="fig11_obstacles", overrides=SHORT)
    with warnings.catch_warnings(record=True) as said:
        warnings.simplefilter("always")
        check_env(env.unwrapped)
    # The action is in m/s, not normalized to [-1, 1] (docs/learning.md: RescaleAction does it).
    assert [("symmetric and normalized" in str(w.message)) for w in said] == [True]
    env.close()


def test_an_episode_is_the_runs_and_its_reward_minus_the_formation_error() -> None:
    env = FollowerEnv("fig11_obstacles", 3, seed=2, overrides=SHORT)
    obs, info = env.reset()
    assert (env.robot_id, obs.shape, obs.dtype, info["tick"]) == (3, (6,), np.float32, 0)
    total, steps, done = 0.0, 0, False
    while not done:
        obs, reward, terminated, truncated, info = env.step(np.array([0.6, 0.6], dtype=np.float32))
        assert obs in env.observation_space
        assert reward == -info["formation_error_m"]
        total += reward
        steps += 1
        done = terminated or truncated
    assert (steps, terminated, truncated, info["tick"]) == (40, False, True, 40)
    assert -40 * 5.0 < total < 0.0


def test_an_action_beyond_the_wheels_limit_is_clipped_to_it() -> None:
    env = FollowerEnv("fig11_obstacles", overrides=SHORT)
    env.reset(seed=1)
    start = env.run.engine.poses[2]
    env.step(np.array([10.0, 10.0], dtype=np.float32))  # beyond the space: clipped to 3 m/s
    end = env.run.engine.poses[2]
    assert end.y_m - start.y_m == pytest.approx(3.0 * 0.05, abs=1e-12)  # fig11 heads up +y
    assert env.run.engine.run().world["clamped_commands"] == 0


def test_a_reset_without_a_seed_runs_the_next_seed() -> None:
    env = FollowerEnv("fig11_obstacles", overrides=SHORT)
    first, _ = env.reset(seed=123)
    second, _ = env.reset()
    assert env.run.engine.seed == 124
    np.testing.assert_array_equal(FollowerEnv("fig11_obstacles", overrides=SHORT).reset(seed=124)[0], second)
    assert not np.array_equal(first, second)


def test_importing_formation_swarm_and_its_engine_loads_neither_gymnasium_nor_pettingzoo() -> None:
    probe = (
        "import json, sys\nimport formation_swarm, formation_swarm.gym, formation_swarm.gym.followers\n"
        "from formation_swarm import Engine\nEngine('fig11_obstacles', overrides={'run.duration_s': 0.1}).run()\n"
        "print(json.dumps([m for m in ('gymnasium', 'pettingzoo') if m in sys.modules]))"
    )
    res = subprocess.run([sys.executable, "-c", probe], capture_output=True, text=True, timeout=60, check=False)
    assert res.returncode == 0, res.stderr
    assert res.stdout.strip() == "[]"
