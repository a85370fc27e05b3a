"""Beyond a dozen robots: aggregates that equal numpy's, the worst follower
named, each robot's series held for the file's batch, the layout's plots
at most 5 series, and a recorder whose buffers stay bounded."""

from __future__ import annotations

import math
from pathlib import Path
from typing import Any

import numpy as np
import rerun.blueprint as rrb

from formation_swarm.nodes.logger import blueprint as bp
from formation_swarm.nodes.logger.columns import CROWD_BATCH_S, ColumnSink
from formation_swarm.nodes.logger.crowd import Crowd
from formation_swarm.nodes.logger.recorder import HISTORY_TICKS, Recorder
from formation_swarm.nodes.logger.recording import Recording
from formation_swarm.protocol.messages import WORLD_ID, Telemetry, Truth
from formation_swarm.spec import files as scenario_files
from formation_swarm.spec import scenario as scenario_mod


def _scenario(n: int, **more: Any) -> scenario_mod.Scenario:
    over = {"run.robots": n, "leader.formation": "line", "run.duration_s": 600.0, "controller.lookahead_m": 1.0}
    return scenario_mod.load(scenario_files.resolve("fig11_obstacles"), over | more)


class FakeSink:
    """What a Crowd adds, by entity; its batch due when told."""

    def __init__(self) -> None:
        self.rows: dict[str, list[tuple[np.ndarray, np.ndarray, bool]]] = {}
        self.is_due = False

    def add(self, entity: str, kind: str, times: Any, values: Any, *, lengths: Any = None, prompt: bool = True) -> None:
        self.rows.setdefault(entity, []).append((np.asarray(times), np.asarray(values), prompt))

    def due(self) -> bool:
        return self.is_due


def _truth(sc: scenario_mod.Scenario, k: int, rng: np.random.Generator) -> tuple[Truth, dict[int, float]]:
    """Tick ``k``'s truth, each follower off its target by a random distance (returned)."""
    ids = sorted(sc.robots)
    robots = tuple((r, 0.5 * i, 0.1 * k - 0.6 * i, math.pi / 2, True) for i, r in enumerate(ids))
    off = {r: float(rng.uniform(0.0, 1.0)) for r in sc.follower_ids}
    targets = tuple((r, 0.5 * i + off[r], 0.1 * k - 0.6 * i) for i, r in enumerate(ids) if r in off)
    return Truth(sender=WORLD_ID, seq=k + 1, tick=k, time_s=k * sc.dt_s, robots=robots, targets=targets), off


def test_formation_error_aggregates_equal_numpy_s_and_the_worst_is_named() -> None:
    sc, rng = _scenario(30), np.random.default_rng(3)
    sink = FakeSink()
    crowd = Crowd(sc, sink, lambda rid, rows: None)  # type: ignore[arg-type]
    truths, offs = zip(*(_truth(sc, k, rng) for k in range(5)), strict=True)
    crowd.truth(list(truths))
    ((t, med, _),) = sink.rows["swarm/error/formation/median"]
    ((_, worst, _),) = sink.rows["swarm/error/formation/worst"]
    assert t.tolist() == [k * sc.dt_s for k in range(5)]
    np.testing.assert_allclose(med, [np.median(list(o.values())) for o in offs], atol=1e-12)
    np.testing.assert_allclose(worst, [max(o.values()) for o in offs], atol=1e-12)
    last = offs[-1]
    rid = max(last, key=lambda r: last[r])
    assert crowd.worst["error/formation"][0] == rid
    crowd.name()
    ((_, ring, _),) = sink.rows["world/swarm/worst"]
    np.testing.assert_allclose(ring, [crowd.where[rid]], atol=1e-12)
    ((_, leader, _),) = sink.rows["world/swarm/labels"]  # its label, "R1 leader", is static: the one label
    np.testing.assert_allclose(leader, [crowd.where[sc.leader.robot_id]], atol=1e-12)
    ((_, table, _),) = sink.rows["swarm/worst"]
    assert f"| formation error | R{rid} | {last[rid]:.3f} m |" in table[0]
    # Each robot's own series: held until the batch is due, then one entity per robot, not prompt.
    assert not any(e.startswith("robots/") for e in sink.rows)
    sink.is_due = True
    crowd.flush()
    own = {e: parts for e, parts in sink.rows.items() if e.startswith("robots/")}
    assert len(own) == 30 + 29 * 2  # every robot's pose; each follower's error and true target
    assert not crowd.held
    ((times, values, prompt),) = own[f"robots/r{rid}/error/formation"]
    assert not prompt
    assert times.tolist() == t.tolist()
    np.testing.assert_allclose(values, [o[rid] for o in offs], atol=1e-12)


class FakeStream:
    """A Rerun stream that keeps the entities sent as columns."""

    def __init__(self) -> None:
        self.sent: list[str] = []
        self.logged: list[str] = []

    def set_time(self, timeline: str, duration: float) -> None:
        pass

    def log(self, entity: str, data: Any, static: bool = False) -> None:
        self.logged.append(entity)

    def flush(self, timeout_sec: float) -> None:
        pass

    def send_columns(self, entity: str, indexes: Any, columns: Any) -> None:
        self.sent.append(entity)


def test_rows_held_back_from_the_live_stream_go_with_the_file_s_batch() -> None:
    file, live = FakeStream(), FakeStream()
    sink = ColumnSink(Recording(file=file, live=live), "sim_time", batch_s=1.0)  # type: ignore[arg-type]
    sink.add("a", "scalar", np.array([0.0, 0.5]), np.array([1.0, 2.0]))
    sink.add("robots/r2/x", "scalar", np.array([0.0, 0.5]), np.array([1.0, 2.0]), prompt=False)
    sink.write()
    assert (live.sent, file.sent, sink.due()) == (["a"], [], False)
    sink.add("a", "scalar", np.array([1.0]), np.array([3.0]))
    assert sink.due()
    sink.write()
    assert sorted(file.sent) == ["a", "robots/r2/x"]
    assert live.sent == ["a", "a", "robots/r2/x"]


def _visible_series(view: rrb.TimeSeriesView) -> int:
    """Entities a time series view draws: its contents less those hidden by an override."""
    contents = [str(c) for c in view.contents or []]
    hidden = {p for p, o in view.visualizer_overrides.items() if isinstance(o, rrb.EntityBehavior)}
    return sum(1 for c in contents if c.removeprefix("+ ") not in hidden)


def _views(node: Any) -> list[Any]:
    kids = getattr(node, "contents", None)
    if isinstance(node, rrb.TimeSeriesView | rrb.Spatial2DView | rrb.TextLogView | rrb.TextDocumentView):
        return [node]
    return [v for kid in kids or [] for v in _views(kid)]


def test_beyond_a_dozen_robots_a_plot_draws_at_most_5_series() -> None:
    sc = _scenario(100)
    layout = bp.blueprint(sc)
    series = [v for v in _views(layout.root_container) if isinstance(v, rrb.TimeSeriesView)]
    assert len(series) == 5
    drawn = {v.name: _visible_series(v) for v in series}
    assert max(drawn.values()) <= 5, drawn
    assert min(drawn.values()) >= 1, drawn
    assert any(isinstance(v, rrb.TextDocumentView) for v in _views(layout.root_container))


def test_a_long_crowd_run_keeps_the_recorder_s_buffers_bounded(tmp_path: Path) -> None:
    sc, rng = _scenario(14), np.random.default_rng(4)
    rec = Recording(file=FakeStream())  # type: ignore[arg-type]
    recorder = Recorder(rec, sc)
    ticks = HISTORY_TICKS + 200  # 30 s: 3 file batches
    for k in range(ticks):
        truth, _ = _truth(sc, k, rng)
        recorder.add_truths([truth])
        recorder.add_telemetry([_tel(r, k, sc.dt_s) for r in sc.follower_ids])
        if k % 5 == 4:
            recorder.send()
    assert len(recorder.poses) <= HISTORY_TICKS + 1
    assert len(recorder.tels) <= 13 * 3
    assert recorder.crowd is not None
    assert len(recorder.crowd.held) <= 3 * 41  # per send: poses, targets, telemetry; 40 sends a batch
    assert recorder.counts["log_errors"] == 0
    # What waits for the file's next batch: less than a batch of sim time.
    assert recorder.sink.span[1] - recorder.sink.span[0] < CROWD_BATCH_S
    recorder.send(final=True)
    assert recorder.counts["unjoined"] == 0
    assert recorder.counts["rows"] == 13 * ticks + 13  # and each one's first formation
    assert sorted(recorder.stats()["target_errors"]) == sorted(str(r) for r in sc.follower_ids)


def test_record_every_takes_every_n_th_tick_alone() -> None:
    sc, rng = _scenario(4, **{"run.record_every": 5}), np.random.default_rng(5)
    rec = Recording(file=FakeStream())  # type: ignore[arg-type]
    recorder = Recorder(rec, sc)
    for k in range(20):
        recorder.add_truths([_truth(sc, k, rng)[0]])
        recorder.add_telemetry([_tel(2, k, sc.dt_s)])
    assert [t.tick for t in recorder.truths] == [0, 5, 10, 15] == [t.tick for t in recorder.tels]


def _tel(rid: int, k: int, dt_s: float) -> Telemetry:
    return Telemetry(
        sender=rid, seq=k + 1, tick=k, time_s=k * dt_s, reference=rid - 1, formation=1,
        measured=(0.01, -0.5), estimate=(0.02, -0.5), target_cov=(0.01, 0.0, 0.02),
        rho_m=0.5, alpha_rad=0.1, vn=0.2, left_mps=0.2, right_mps=0.21,
        steering_to=0, changing=False, obs_dropped=0, formation_dropped=0, rejected=0,
    )  # fmt: skip


def test_a_batch_spans_more_sim_time_as_the_robots_grow_beyond_a_hundred() -> None:
    """A robot's series cost a call per entity and batch: the calls per sim second
    of 100 robots stay those of 200 and 500, up to a batch of a minute."""
    from formation_swarm.nodes.logger.columns import FILE_BATCH_S, MAX_BATCH_S, batch_s
    from formation_swarm.nodes.logger.crowd import CROWD_ROBOTS

    assert batch_s(CROWD_ROBOTS, CROWD_ROBOTS) == FILE_BATCH_S
    calls = {n: n / batch_s(n, CROWD_ROBOTS) for n in (13, 100, 200, 500)}
    assert calls[100] == calls[200] == calls[500] == 10.0
    assert calls[13] == 1.3
    assert batch_s(10_000, CROWD_ROBOTS) == MAX_BATCH_S


def test_a_crowd_s_events_are_its_followers_changes_not_their_first_formations() -> None:
    """14 robots: the 13 followers' first formation makes no event; robot 5's
    change at tick 40 makes one."""
    import dataclasses

    sc, rng = _scenario(14), np.random.default_rng(6)
    stream = FakeStream()
    recorder = Recorder(Recording(file=stream), sc)  # type: ignore[arg-type]
    for k in range(80):
        truth, _ = _truth(sc, k, rng)
        recorder.add_truths([truth])
        tels = [_tel(r, k, sc.dt_s) for r in sc.follower_ids]
        recorder.add_telemetry([dataclasses.replace(t, formation=0) if t.sender == 5 and k >= 40 else t for t in tels])
        if k % 5 == 4:
            recorder.send()
        if k == 39:
            assert stream.logged.count("events") == 0  # 13 first formations, no change yet
    recorder.send(final=True)
    assert stream.logged.count("events") == 1  # robot 5's change
    assert recorder.formation == dict.fromkeys(sc.follower_ids, 1) | {5: 0}
