"""The PettingZoo adapter (formation_swarm.gym.pettingzoo_env): PettingZoo's
own API and seed tests pass as shipped, an episode is the engine's run
tick for tick, and its agents leave together when the run ends."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pettingzoo.test import parallel_api_test, parallel_seed_test

from formation_swarm import Engine
from formation_swarm.gym.followers import OBSERVATION
from formation_swarm.gym.pettingzoo_env import FollowersEnv

SHORT = {"run.duration_s": 2.0}  # fig11's first 40 ticks


def _env(**kwargs: object) -> FollowersEnv:
    return FollowersEnv("fig11_obstacles", overrides=SHORT, **kwargs)  # type: ignore[arg-type]


def test_pettingzoos_api_test_passes() -> None:
    env = _env()
    parallel_api_test(env, num_cycles=1000)  # raises on the first breach
    assert env.run.engine.tick == 40
    assert env.possible_agents == ["follower_2", "follower_3"]
    assert env.agents == []  # the last episode ran to its end


def test_pettingzoos_seed_test_passes() -> None:
    parallel_seed_test(lambda: _env(followers=[3]))


def test_an_episode_is_the_runs_ticks_and_ends_for_every_agent_at_once() -> None:
    env = _env(followers=[2, 3], seed=4)
    obs, infos = env.reset()
    assert set(obs) == set(infos) == {"follower_2", "follower_3"}
    assert infos["follower_2"] == {"tick": 0, "time_s": 0.0, "formation_error_m": pytest.approx(0.0, abs=1e-12)}
    steps = 0
    while env.agents:
        space = env.action_space("follower_2")
        actions = {a: np.array([0.4, 0.5], dtype=np.float32) for a in env.agents}
        obs, rewards, terminated, truncated, infos = env.step(actions)
        steps += 1
        for a, o in obs.items():
            assert o in env.observation_space(a)
            assert rewards[a] == -infos[a]["formation_error_m"] <= 0.0
            assert infos[a]["tick"] == steps
        assert space is env.action_space("follower_2")
    assert steps == 40
    assert (terminated, truncated) == (dict.fromkeys(obs, False), dict.fromkeys(obs, True))
    res = env.run.engine.run()
    assert (res.end_reason, res.ticks, res.summary["seed"]) == ("duration_reached", 40, 4)


def test_observations_are_the_followers_inputs() -> None:
    env = _env(followers=[2])
    obs, _ = env.reset(seed=1)
    engine = Engine("fig11_obstacles", seed=1, overrides=SHORT)
    engine.observe()
    inp = engine.inputs[2]
    assert inp.reading is not None
    expected = [1.0, inp.reading.rho_m, inp.reading.phi_rad, inp.reading.beta_rad, *inp.slot.offset]
    assert obs["follower_2"].dtype == np.float32
    assert obs["follower_2"].tolist() == pytest.approx(expected, rel=1e-6)
    assert len(OBSERVATION) == len(expected) == 6
    low, high = env.observation_space("follower_2").low, env.observation_space("follower_2").high
    assert low.tolist() == pytest.approx([0.0, 0.0, -math.pi, -math.pi, -3.0, -3.0])
    assert high.tolist() == pytest.approx([1.0, 10.0 + 8 * 0.05, math.pi, math.pi, 3.0, 3.0])


def test_a_reset_without_a_seed_runs_the_next_seed() -> None:
    env = _env(seed=7)
    first = env.reset()[0]
    second = env.reset()[0]
    assert env.run.engine.seed == 8
    assert not np.array_equal(first["follower_2"], second["follower_2"])  # other camera noise
    np.testing.assert_array_equal(env.reset(seed=8)[0]["follower_2"], second["follower_2"])
    np.testing.assert_array_equal(_env(seed=7).reset()[0]["follower_2"], first["follower_2"])


def test_two_envs_seeded_alike_run_alike_to_the_end() -> None:
    a, b = _env(), _env()
    for env in (a, b):
        env.reset(seed=3)
        for agent in env.possible_agents:
            env.action_space(agent).seed(11)
    rewards = {"a": 0.0, "b": 0.0}
    while a.agents:
        acts = {agent: a.action_space(agent).sample() for agent in a.agents}
        acts_b = {agent: b.action_space(agent).sample() for agent in b.agents}
        oa, ra, *_ = a.step(acts)
        ob, rb, *_ = b.step(acts_b)
        for agent in oa:
            np.testing.assert_array_equal(oa[agent], ob[agent])
        rewards["a"] += sum(ra.values())
        rewards["b"] += sum(rb.values())
    assert b.agents == []
    assert rewards["a"] == rewards["b"] < 0.0


def test_what_it_cannot_drive_is_refused_in_one_line() -> None:
    with pytest.raises(ValueError, match=r"followers must be distinct follower ids of the run \(\[2, 3\]\), got \[1\]"):
        _env(followers=[1])  # the leader
    with pytest.raises(ValueError, match=r"got \[2, 2\]"):
        _env(followers=[2, 2])
    env = _env(followers=[2])
    env.reset()
    with pytest.raises(ValueError, match=r"actions for agents not live: \['follower_3'\]"):
        env.step({"follower_3": np.zeros(2, dtype=np.float32)})
    with pytest.raises(ValueError, match=r"follower 2's action must be \('left_mps', 'right_mps'\), got shape \(3,\)"):
        env.step({"follower_2": np.zeros(3)})
    with pytest.raises(ValueError, match=r"actions\[2\] left_mps must be a finite number"):
        env.step({"follower_2": np.array([np.nan, 0.0])})
    assert env.run.engine.tick == 0
