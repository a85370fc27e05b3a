"""The formation errors of many followers taken at once (world.formation_errors)
are the per-follower loop's, bit for bit: on random layouts, headings, wheel
commands (turning or not) and formations, every follower's metrics, error
windows, recovery and error until its stop, and the trajectory digest, equal
an oracle that takes them follower by follower as the metrics did before."""

from __future__ import annotations

import hashlib
import json
import math
import random
import struct

import pytest

from formation_swarm.spec import files as scenario_files
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.kinematics import Pose, from_body_frame
from formation_swarm.world.metrics import ERRORS_AT_ONCE_FROM, TURN_RATE_RPS, FollowerMetrics, RunMetrics
from formation_swarm.world.recovery import Recovery


def _scenario(robots: int) -> scenario_mod.Scenario:
    return scenario_mod.load(
        scenario_files.resolve("fig11_obstacles"),
        {"run.robots": robots, "leader.formation": "line", "controller.lookahead_m": 1.0},
    )


class _Oracle:
    """The metrics' figures follower by follower: the loop world.metrics ran before."""

    def __init__(self, sc: scenario_mod.Scenario, window_ticks: int) -> None:
        self.sc, self.window_ticks, self.recorded = sc, window_ticks, 0
        self.followers = {rid: FollowerMetrics() for rid in sc.follower_ids}
        self.windows: dict[int, list[list[float]]] = {rid: [] for rid in sc.follower_ids}
        self.digest = hashlib.sha256()

    def record(self, snap: dict) -> dict[int, float]:
        sc, errors = self.sc, {}
        poses = {rid: pose for rid, (pose, _, _) in snap.items()}
        for rid, metrics in self.followers.items():
            pose, _, formation = snap[rid]
            slot = sc.formation_by_code(formation).slots[rid]
            ref_pose, ref_command, _ = snap[slot.reference]
            tx, ty = from_body_frame(poses[slot.reference], slot.offset[0], slot.offset[1])
            ex, ey = tx - pose.x_m, ty - pose.y_m
            along = ex * math.cos(ref_pose.theta_rad) + ey * math.sin(ref_pose.theta_rad)
            turning = abs(ref_command[1] - ref_command[0]) / sc.width_m >= TURN_RATE_RPS
            err = math.hypot(ex, ey)
            errors[rid] = err
            metrics.add(err, along, turning)
            if self.recorded % self.window_ticks == 0:
                self.windows[rid].append([0.0, 0.0, 0])
            w = self.windows[rid][-1]
            w[0], w[1], w[2] = w[0] + err, max(w[1], err), w[2] + 1
        self.recorded += 1
        for rid in sorted(snap):
            self.digest.update(struct.pack("<3d", *snap[rid][0]))
        return errors


def _snapshot(sc: scenario_mod.Scenario, rng: random.Random, shuffle: bool) -> dict:
    """Random poses within 60 m, wheel commands of which some turn, each follower in a random formation."""
    codes = range(len(sc.formation_names))
    ids = list(sc.robots)
    if shuffle:  # the snapshot's order of robots is not the followers' order
        rng.shuffle(ids)
    snap = {}
    for rid in ids:
        pose = Pose(rng.uniform(-60, 60), rng.uniform(-60, 60), rng.uniform(-math.pi, math.pi))
        left = rng.choice([1.0, 0.0, -0.5, rng.uniform(-1.5, 1.5)])
        right = rng.choice([left, left + 1e-3, rng.uniform(-1.5, 1.5)])
        snap[rid] = (pose, (left, right), rng.choice(codes) if rng.random() < 0.3 else 0)
    return snap


def _same(a: object, b: object) -> bool:
    """Equal to the bit, NaN included (repr of floats is exact)."""
    return json.dumps(a, sort_keys=True) == json.dumps(b, sort_keys=True)


@pytest.mark.parametrize(("robots", "seed"), [(5, 0), (ERRORS_AT_ONCE_FROM + 1, 1), (40, 2), (200, 3)])
def test_errors_at_once_are_the_per_follower_loops(robots: int, seed: int) -> None:
    sc = _scenario(robots)
    rng = random.Random(seed)
    metrics = RunMetrics(sc)
    assert (metrics.at_once is not None) == (len(sc.follower_ids) >= ERRORS_AT_ONCE_FROM)
    oracle = _Oracle(sc, metrics.window_ticks)
    watched = tuple(sc.follower_ids[:3])
    rec = Recovery(robot=watched[0], event="thawed", fault=None, since_tick=5, watched=watched, dt_s=sc.dt_s)
    oracle_rec = Recovery(robot=watched[0], event="thawed", fault=None, since_tick=5, watched=watched, dt_s=sc.dt_s)
    ticks = 2 * metrics.window_ticks + 7  # three windows, the last one short
    stopped = sc.follower_ids[-1]
    until_stopped = None
    for tick in range(ticks):
        snap = _snapshot(sc, rng, shuffle=tick % 5 == 4)
        if tick == 3:
            metrics.recoveries.append(rec)
        metrics.record(snap, tick)
        errors = oracle.record(snap)
        if tick >= 3:
            oracle_rec.add(tick, errors)
        if tick == ticks // 2:
            metrics.stopped(stopped, tick * sc.dt_s)
            m = oracle.followers[stopped]
            until_stopped = {"time_s": tick * sc.dt_s, "rms_m": m.rms_m(), "max_m": m.max_m}
    for rid in sc.follower_ids:
        got = metrics.follower_summary(rid)
        want = dict(oracle.followers[rid].as_dict())
        if rid == stopped:
            want["until_stopped"] = until_stopped
        assert _same(got, want), rid
    windows = metrics.error_windows()
    assert _same(windows["mean_m"], {str(r): [round(w[0] / w[2], 4) for w in ws] for r, ws in oracle.windows.items()})
    assert _same(windows["max_m"], {str(r): [round(w[1], 4) for w in ws] for r, ws in oracle.windows.items()})
    assert [len(ws) for ws in windows["max_m"].values()] == [3] * len(sc.follower_ids)
    assert _same(rec.as_dict(), oracle_rec.as_dict())
    assert metrics.digest() == oracle.digest.hexdigest()
    # Some samples in a turn and some not: both branches were taken.
    turns = [metrics.follower_summary(r)["turn_samples"] for r in sc.follower_ids]
    assert 0 < sum(turns) < ticks * len(sc.follower_ids)
