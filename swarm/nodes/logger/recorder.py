"""The logger's Rerun side: what a run's messages become in the recording.

Timeline ``sim_time`` (the messages' sim time, never the wall clock).
Entity paths mirror the key space::

    world, robots                        static: a flip of y (the 2D view draws y down, the paper y up)
    world/obstacles, world/path          static circles, the leader's waypoints
    robots/r<id>/pose, /heading          true position (a disc of the robot's size) and heading (Truth)
    robots/r<id>/trajectory              the same positions, shown with their last TRAIL_S
    robots/r<id>/target/true             the follower's true virtual target
    robots/r<id>/target/measured         the target from the raw reading (eq. 1-2)
    robots/r<id>/ekf/target, /ekf/cov    EKF estimate and its 2-sigma ellipse
    robots/r<id>/error/formation         |follower - true target|, m
    robots/r<id>/error/ekf, /error/measured   |estimate or reading - true target|, m (the target
                                         of the formation the follower's telemetry says it flew)
    robots/r<id>/fis/rho, /fis/alpha, /fis/v_n, robots/r<id>/wheels/left, /wheels/right
    robots/r<id>/controller/<name>       a controller's own values (Telemetry.extras, docs/controllers.md)
    robots/r<id>/fis/v_n_1s, /wheels/left_1s, /wheels/right_1s   their 1 s centred moving means, as
                                         the report's (formation_swarm.nodes.logger.running_mean): given
                                         half a second late
    leader_frame                         the leader's position, y up: the formation view's origin
    robots/r<id>/formation               formation code flown
    events                               the run's start and each follower's formation changes, as text
    robots/r<id>/links/obs_dropped, /links/formation_dropped
    events/faults                        the fault schedule: each fault where it starts and ends (once reached)
    events/fault_calls                   the world's calls for process faults, at their tick

How each robot is drawn is static data too, and the viewer's layout names
these paths for the scenario's robots: formation_swarm.nodes.logger.blueprint.
Beyond a dozen robots the swarm is drawn and summed up as a whole, each
robot's series kept (formation_swarm.nodes.logger.crowd). ``run.record_every``
= N records every N-th tick's truth and telemetry alone.

Messages are kept as they arrive (cheap, per tick) and turned into Rerun
columns with numpy when the process loop calls ``Recorder.send`` (per send,
not per tick); the file gets them in batches of sim time
(formation_swarm.nodes.logger.columns). Logging errors are counted, never fatal.
"""

from __future__ import annotations

import math
import sys
from collections import defaultdict
from collections.abc import Mapping
from typing import TYPE_CHECKING, Any

import numpy as np
import rerun as rr

from formation_swarm.nodes.logger.blueprint import LEADER_FRAME, MEAN_S, SMOOTHED, TIMELINE, static_entities
from formation_swarm.nodes.logger.columns import ColumnSink, batch_s
from formation_swarm.nodes.logger.crowd import CROWD_ROBOTS, FIRST_SERIES, SERIES, Crowd, crowd_styles
from formation_swarm.nodes.logger.running_mean import CentredMean
from formation_swarm.nodes.logger.shapes import ellipses, to_world
from formation_swarm.world.kinematics import Pose, from_body_frame
from formation_swarm.world.metrics import TargetErrors

if TYPE_CHECKING:
    from formation_swarm.nodes.logger.recording import Recording
    from formation_swarm.protocol.messages import FaultCall, FormationCode, Telemetry, Truth
    from formation_swarm.spec.scenario import Scenario

HISTORY_TICKS = 400  # telemetry waits this long for its tick's truth
SETTLE_TICKS = 2  # beyond a dozen robots, a tick's telemetry is taken this many ticks late: whole, for its aggregates


class Recorder:
    """One run's recording: truth and telemetry messages in, Rerun columns out."""

    def __init__(self, rec: Recording, sc: Scenario) -> None:
        self.rec = rec
        self.sc = sc
        self.truths: list[Truth] = []  # since the last send
        self.tels: list[Telemetry] = []  # waiting for their tick's truth
        self.poses: dict[int, dict[int, Pose]] = {}  # tick -> robot -> pose, bounded history
        self.targets: dict[int, dict[int, tuple[float, float]]] = {}
        self.formation: dict[int, int] = {}
        self.leader_code: int | None = None  # the last formation code taken from the leader, and its tick
        self.leader_code_tick: int | None = None
        self.pending_events: list[tuple[float, str]] = []  # (sim time s, text) for /events at the next send
        # Per follower: the measured and the EKF target vs the true one, and the EKF's NEES.
        self.target_errors: dict[int, TargetErrors] = defaultdict(TargetErrors)
        self.counts = {"log_errors": 0, "rows": 0, "unjoined": 0}
        self.schedule: list[tuple[float, str, str]] = []  # fault schedule events still to come: time s, text, level
        self.last_time_s = -1.0
        crowd = len(sc.robots) > CROWD_ROBOTS
        self.sink = ColumnSink(rec, TIMELINE, batch_s(len(sc.robots), CROWD_ROBOTS))
        self.crowd = Crowd(sc, self.sink, self._target_errors) if crowd else None
        self.every = record_every(sc)
        self.means: dict[tuple[int, str], CentredMean] = {}  # (follower, series) -> its 1 s mean

    def add_truths(self, truths: list[Truth]) -> None:
        self.truths.extend(t for t in truths if t.tick % self.every == 0)

    def add_telemetry(self, tels: list[Telemetry]) -> None:
        self.tels.extend(t for t in tels if t.tick % self.every == 0)

    def add_leader_code(self, code: FormationCode) -> None:
        """The leader's formation code: a change is the leader's switch, an event."""
        if code.code != self.leader_code and (self.leader_code_tick is None or code.tick > self.leader_code_tick):
            self.leader_code, self.leader_code_tick = code.code, code.tick
            names = self.sc.formation_names
            name = names[code.code] if code.code < len(names) else "?"
            self.pending_events.append((code.tick * self.sc.dt_s, f"R{code.sender} (leader) flies {name}"))

    def guard(self, fn: Any, *args: Any, **kwargs: Any) -> None:
        try:
            fn(*args, **kwargs)
        except Exception as exc:  # noqa: BLE001 - logging never takes the process down
            self.counts["log_errors"] += 1
            if self.counts["log_errors"] <= 3:
                print(f"logger: rerun error ({type(exc).__name__}: {exc}); continuing", file=sys.stderr, flush=True)

    def flush(self, timeout_s: float) -> None:
        self.guard(self.rec.flush, timeout_sec=timeout_s)

    def log_static(self) -> None:
        """The obstacles, the leader's path, the formations and how each robot
        is drawn, logged once as static data (formation_swarm.nodes.logger.blueprint)."""
        sc = self.sc
        for entity, data in static_entities(sc) + (crowd_styles(sc) if self.crowd else []):
            self.guard(self.rec.log, entity, data, static=True)
        self._event(0.0, f"run of {sc.name}: {len(sc.robots)} robots, leader R{sc.leader.robot_id}")
        self.log_fault_schedule()

    def log_fault_schedule(self) -> None:
        """Every scheduled fault in the event log, where it starts and where it
        ends, each logged once the run's ground truth reaches its time: a
        viewer following the run must not jump to a time still to come."""
        sc = self.sc
        for f in sc.faults:
            self.schedule.append((f.start_tick(sc.dt_s) * sc.dt_s, f"fault: {f}", "WARN"))
            end = f.end_tick(sc.dt_s)
            if end is not None and f.kind != "restart":
                self.schedule.append((end * sc.dt_s, f"fault over: {f}", "INFO"))
        self.schedule.sort(key=lambda e: e[0])
        self._log_due_faults()

    def _log_due_faults(self) -> None:
        while self.schedule and self.schedule[0][0] <= max(self.last_time_s, 0.0):
            t, text, level = self.schedule.pop(0)
            self.guard(self.rec.set_time, TIMELINE, duration=t)
            self.guard(self.rec.log, "events/faults", rr.TextLog(text, level=level))

    def log_fault_call(self, call: FaultCall) -> None:
        """A call the world made to execute a process fault (kill, start, freeze, thaw)."""
        self.guard(self.rec.set_time, TIMELINE, duration=call.time_s)
        text = f"{call.action} {call.process} (fault {call.index}: {self._fault_text(call.index)}, tick {call.tick})"
        self.guard(self.rec.log, "events/fault_calls", rr.TextLog(text, level="WARN"))

    def _fault_text(self, index: int) -> str:
        return str(self.sc.faults[index]) if index < len(self.sc.faults) else "not in the schedule"

    def send(self, final: bool = False) -> None:
        self.guard(self._send_truth)
        self.guard(self._send_telemetry, final)
        if final:
            self.guard(self._end_means)
        if self.crowd is not None:
            self.guard(self.crowd.name)
            self.guard(self.crowd.flush, final)
        self.guard(self.sink.write, final)
        events, self.pending_events = self.pending_events, []
        for t, text in events:
            self._event(t, text)

    def _columns(self, entity: str, kind: str, times: np.ndarray, values: Any) -> None:
        """One entity's rows since the last send, as Rerun columns."""
        if len(times) == 0:
            return
        self.sink.add(entity, kind, times, values)
        self.counts["rows"] += len(times)

    def _send_truth(self) -> None:
        truths, self.truths = self.truths, []
        if self.crowd is not None:
            self._keep_truths(truths)
            self.crowd.truth(truths)
            self._log_due_faults()
            return
        robots: dict[int, list[tuple[float, float, float, float]]] = defaultdict(list)
        targets: dict[int, list[tuple[float, float, float, float, float]]] = defaultdict(list)
        for msg in truths:
            t = msg.time_s
            self.last_time_s = max(self.last_time_s, t)
            poses = {rid: Pose(x, y, th) for rid, x, y, th, _alive in msg.robots}
            self.poses[msg.tick] = poses
            self.targets[msg.tick] = {rid: (x, y) for rid, x, y in msg.targets}
            for rid, pose in poses.items():
                robots[rid].append((t, *pose))
            for rid, x, y in msg.targets:
                if rid in poses:
                    targets[rid].append((t, x, y, poses[rid].x_m, poses[rid].y_m))
        for rid, rows in robots.items():
            a = np.array(rows)
            t, xy, th = a[:, 0], a[:, 1:3], a[:, 3]
            base = f"robots/r{rid}"
            self._columns(f"{base}/pose", "point", t, xy)
            self._columns(f"{base}/trajectory", "point", t, xy)
            heading = self.sc.diameter_m * np.column_stack([np.cos(th), np.sin(th)])  # a diameter long
            self._columns(f"{base}/heading", "arrow", t, np.column_stack([xy, heading]))
            if rid == self.sc.leader.robot_id:  # under the root, past the flip of y: (x, -y)
                self._columns(LEADER_FRAME, "translation", t, np.column_stack([xy[:, 0], -xy[:, 1], np.zeros_like(t)]))
        for rid, rows in targets.items():
            a = np.array(rows)
            self._columns(f"robots/r{rid}/target/true", "point", a[:, 0], a[:, 1:3])
            err = np.hypot(a[:, 1] - a[:, 3], a[:, 2] - a[:, 4])
            self._columns(f"robots/r{rid}/error/formation", "scalar", a[:, 0], err)
        self._log_due_faults()

    def _keep_truths(self, truths: list[Truth]) -> None:
        """Each tick's true poses and targets, for its telemetry to join."""
        for msg in truths:
            self.last_time_s = max(self.last_time_s, msg.time_s)
            self.poses[msg.tick] = {rid: Pose(x, y, th) for rid, x, y, th, _alive in msg.robots}
            self.targets[msg.tick] = {rid: (x, y) for rid, x, y in msg.targets}

    def _send_telemetry(self, final: bool) -> None:
        """Telemetry whose tick's truth has arrived, joined with it: the follower's
        pose turns its body-frame points into world-frame ones."""
        newest = max(self.poses, default=-1)
        settled = newest - (SETTLE_TICKS if self.crowd is not None and not final else 0)
        ready: dict[int, list[tuple[Telemetry, Pose, tuple[float, float] | None]]] = defaultdict(list)
        waiting = []
        for tel in self.tels:
            pose = self.poses.get(tel.tick, {}).get(tel.sender) if tel.tick <= settled else None
            if pose is not None:
                ready[tel.sender].append((tel, pose, self._flown_target(tel)))
            elif tel.tick > newest - HISTORY_TICKS and not final:
                waiting.append(tel)
            else:
                self.counts["unjoined"] += 1
        self.tels = waiting
        for old in [k for k in self.poses if k < newest - HISTORY_TICKS]:
            del self.poses[old], self.targets[old]
        if self.crowd is not None:
            self._send_crowd(ready)
            return
        for rid, rows in ready.items():
            self._send_follower(rid, rows)

    def _flown_target(self, tel: Telemetry) -> tuple[float, float] | None:
        """The true target of the slot the follower flew at its tick: in the
        formation its telemetry names, from its reference's true pose. In real
        time a follower may apply a new formation code a tick before the world
        has its command naming it; the world's own target (``Truth``) would
        then be the old formation's slot, and its reading of the new one would
        count as metres of error for that tick."""
        poses = self.poses.get(tel.tick, {})
        try:
            slot = self.sc.formation_by_code(tel.formation).slots[tel.sender]
            return from_body_frame(poses[slot.reference], slot.offset[0], slot.offset[1])
        except (IndexError, KeyError):  # an unknown code or slot, a reference without a pose
            return self.targets.get(tel.tick, {}).get(tel.sender)

    def _send_crowd(self, ready: dict[int, list[tuple[Telemetry, Pose, tuple[float, float] | None]]]) -> None:
        """Many followers' telemetry at once (formation_swarm.nodes.logger.crowd)."""
        if not ready or self.crowd is None:
            return
        for rid, rows in ready.items():
            self._send_formations(rid, rows)
            self._send_extras(f"robots/r{rid}", rows)
        rows = [row for part in ready.values() for row in part]
        a = _rows(rows)
        rids = np.array([tel.sender for tel, _pose, _target in rows])
        pose = a[:, 1:4]
        self.crowd.telemetry(a, rids, to_world(pose, a[:, 6:8]), to_world(pose, a[:, 8:10]))
        self.counts["rows"] += len(a)

    def _target_errors(self, rid: int, a: np.ndarray) -> None:
        """Follower ``rid``'s target errors from its joined telemetry rows (``_rows``' columns)."""
        pose, target, cov = a[:, 1:4], a[:, 4:6], a[:, 10:13]
        self.target_errors[rid].add(pose, target, to_world(pose, a[:, 6:8]), to_world(pose, a[:, 8:10]), cov)

    def _send_follower(self, rid: int, rows: list[tuple[Telemetry, Pose, tuple[float, float] | None]]) -> None:
        base = f"robots/r{rid}"
        self._send_formations(rid, rows)
        a = _rows(rows)
        t, pose, target = a[:, 0], a[:, 1:4], a[:, 4:6]
        measured, estimate = to_world(pose, a[:, 6:8]), to_world(pose, a[:, 8:10])
        cov = a[:, 10:13]
        for col, name in enumerate(SERIES, start=FIRST_SERIES):
            ok = ~np.isnan(a[:, col])
            self._columns(f"{base}/{name}", "scalar", t[ok], a[ok, col])
            if name in SMOOTHED:
                self._mean(rid, name, t[ok], a[ok, col])
        for name, pts in (("measured", measured), ("ekf", estimate)):
            ok = ~np.isnan(pts[:, 0])
            self._columns(
                f"{base}/target/measured" if name == "measured" else f"{base}/ekf/target", "point", t[ok], pts[ok]
            )
            ok &= ~np.isnan(target[:, 0])
            err = np.hypot(*(pts[ok] - target[ok]).T)
            self._columns(f"{base}/error/{name}", "scalar", t[ok], err)
        self.target_errors[rid].add(pose, target, measured, estimate, cov)
        ok = ~np.isnan(estimate[:, 0]) & ~np.isnan(cov[:, 0])
        if ok.any():
            self._columns(f"{base}/ekf/cov", "strip", t[ok], ellipses(pose[ok], estimate[ok], cov[ok]))
        self._send_extras(base, rows)

    def _send_formations(self, rid: int, rows: list[tuple[Telemetry, Pose, tuple[float, float] | None]]) -> None:
        """Each change of the formation a follower flies: a row and an event (in a
        crowd, its first formation a row only: not a hundred events at the start)."""
        for tel, _pose, _target in rows:
            if self.formation.get(rid) != tel.formation:
                first = rid not in self.formation
                self.formation[rid] = tel.formation
                when, code = np.array([tel.time_s]), np.array([float(tel.formation)])
                self._columns(f"robots/r{rid}/formation", "scalar", when, code)
                if first and self.crowd is not None:
                    continue
                names = self.sc.formation_names
                self._event(tel.time_s, f"R{rid} flies {names[tel.formation] if tel.formation < len(names) else '?'}")

    def _send_extras(self, base: str, rows: list[tuple[Telemetry, Pose, tuple[float, float] | None]]) -> None:
        """The controller's own values, each a series under ``base``/controller/
        (a name absent from a tick has no row there)."""
        series: dict[str, tuple[list[float], list[float]]] = {}
        for tel, _pose, _target in rows:
            for name, value in tel.extras:
                times, values = series.setdefault(name, ([], []))
                times.append(tel.time_s)
                values.append(value)
        for name, (times, values) in series.items():
            self._columns(f"{base}/controller/{name}", "scalar", np.array(times), np.array(values))

    def _mean(self, rid: int, name: str, t: np.ndarray, v: np.ndarray) -> None:
        """Follower ``rid``'s series ``name`` into its 1 s mean; the means complete, as rows."""
        mean = self.means.setdefault((rid, name), CentredMean(MEAN_S, self.sc.dt_s))
        order = np.argsort(t, kind="stable")  # telemetry comes in any order
        mt, mv = mean.add(t[order].tolist(), v[order].tolist())
        self._columns(f"robots/r{rid}/{name}_1s", "scalar", np.array(mt), np.array(mv))

    def _end_means(self) -> None:
        for (rid, name), mean in self.means.items():
            mt, mv = mean.end()
            self._columns(f"robots/r{rid}/{name}_1s", "scalar", np.array(mt), np.array(mv))

    def _event(self, t: float, text: str) -> None:
        self.guard(self.rec.set_time, TIMELINE, duration=t)
        self.guard(self.rec.log, "events", rr.TextLog(text))

    def stats(self) -> dict[str, Any]:
        """``last_sim_time_s`` and, per follower, the RMS of the measured and EKF targets vs
        the true ones and the EKF's NEES (world.metrics.TargetErrors)."""
        return {
            "last_sim_time_s": self.last_time_s,
            "target_errors": {str(rid): acc.stats() for rid, acc in sorted(self.target_errors.items())},
        }


def _nan(x: float | None) -> float:
    return math.nan if x is None else x


def record_every(sc: Scenario) -> int:
    """``run.record_every``: record every N-th tick (1: every tick)."""
    run = sc.raw.get("run") if isinstance(sc.raw, Mapping) else None
    every = run.get("record_every", 1) if isinstance(run, Mapping) else 1
    return every if type(every) is int and every >= 1 else 1  # the loader checked it: this for a hand-made Scenario


def _rows(rows: list[tuple[Telemetry, Pose, tuple[float, float] | None]]) -> np.ndarray:
    """A follower's joined telemetry as columns: time, pose (3), true target (2),
    measured (2), estimate (2), cov (3), then crowd.SERIES (rho, alpha, V_N,
    wheels, link drops)."""
    nan = math.nan
    return np.array(
        [
            (
                tel.time_s,
                *pose,
                *(target or (nan, nan)),
                *(tel.measured or (nan, nan)),
                *(tel.estimate or (nan, nan)),
                *(tel.target_cov or (nan, nan, nan)),
                _nan(tel.rho_m),
                _nan(tel.alpha_rad),
                _nan(tel.vn),
                tel.left_mps,
                tel.right_mps,
                tel.obs_dropped,
                tel.formation_dropped,
            )
            for tel, pose, target in rows
        ]
    ).reshape(-1, 20)
