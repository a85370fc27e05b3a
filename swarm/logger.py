"""The logger process: the run's key space streamed to Rerun.

    swarm logger --scenario S.toml --run RUN --out recording.rrd [--live URL] [--serve-web]
                 [--stats FILE] --connect ENDPOINT

Timeline ``sim_time`` (the messages' sim time, never the wall clock).
Entity paths mirror the key space::

    world/obstacles                      static circles
    robots/r<id>/pose, /heading          true position and heading (Truth)
    robots/r<id>/trajectory              the same positions, shown with their past
    robots/r<id>/target/true             the follower's true virtual target
    robots/r<id>/target/measured         the target from the raw reading (eq. 1-2)
    robots/r<id>/ekf/target, /ekf/cov    EKF estimate and its 2-sigma ellipse
    robots/r<id>/error/formation         |follower - true target|, m
    robots/r<id>/error/ekf, /error/measured   |estimate or reading - true target|, m
    robots/r<id>/fis/rho, /fis/alpha, /fis/v_n, robots/r<id>/wheels/left, /wheels/right
    robots/r<id>/formation               formation code flown; events: changes as text
    robots/r<id>/links/obs_dropped, /links/formation_dropped

Data is buffered and sent as columns every 0.25 s of wall time and the file
is flushed every 0.5 s, so a logger killed with SIGKILL loses at most about
the last second. Logging errors are counted, never fatal.
"""

from __future__ import annotations

import argparse
import contextlib
import gc
import math
import os
import queue
import sys
import threading
import time
from collections import defaultdict
from typing import Any

import numpy as np
import rerun as rr
import rerun.blueprint as rrb
import zenoh

from protocol import session
from protocol.keys import Keys
from protocol.messages import Rejections, Status, Telemetry, Truth
from swarm import scenario as scenario_mod
from swarm.proc import install_stop_handlers, role_inputs, write_json
from world.kinematics import Pose, from_body_frame

SEND_PERIOD_S = 0.25
FLUSH_PERIOD_S = 0.5
TIMELINE = "sim_time"
_CIRCLE = np.stack([np.cos(np.linspace(0, 2 * np.pi, 25)), np.sin(np.linspace(0, 2 * np.pi, 25))], axis=1)


def blueprint() -> rrb.Blueprint:
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Spatial2DView(
                name="formation (Fig. 6a, 7a, 9-11)",
                origin="/",
                contents=["+ /world/**", "+ /robots/**"],
                time_ranges=rrb.VisibleTimeRange(
                    TIMELINE, start=rrb.TimeRangeBoundary.infinite(), end=rrb.TimeRangeBoundary.cursor_relative()
                ),
            ),
            rrb.Vertical(
                rrb.TimeSeriesView(
                    name="formation error, m (Fig. 6b, 7b)", origin="/", contents=["+ /robots/*/error/formation"]
                ),
                rrb.TimeSeriesView(name="V_N (Fig. 8)", origin="/", contents=["+ /robots/*/fis/v_n"]),
                rrb.TimeSeriesView(
                    name="target error: raw vs EKF, m (Fig. 9-10)",
                    origin="/",
                    contents=["+ /robots/*/error/ekf", "+ /robots/*/error/measured"],
                ),
            ),  # fmt: skip
            column_shares=[3, 2],
        ),
        collapse_panels=True,
    )


class Columns:
    """Rows buffered per entity, sent with send_columns."""

    def __init__(self) -> None:
        self.rows: dict[tuple[str, str], list[tuple[float, Any]]] = defaultdict(list)
        self.count = 0

    def add(self, entity: str, kind: str, t: float, value: Any) -> None:
        self.rows[(entity, kind)].append((t, value))
        self.count += 1

    def send(self, rec: rr.RecordingStream) -> None:
        rows, self.rows = self.rows, defaultdict(list)
        self.count = 0
        for (entity, kind), items in rows.items():
            times = np.array([t for t, _ in items])
            idx = [rr.TimeColumn(TIMELINE, duration=times)]
            vals = [v for _, v in items]
            if kind == "scalar":
                cols = rr.Scalars.columns(scalars=np.array(vals, dtype=float))
            elif kind == "point":
                cols = rr.Points2D.columns(positions=np.array(vals, dtype=float).reshape(-1, 2))
            elif kind == "arrow":
                arr = np.array(vals, dtype=float).reshape(-1, 4)
                cols = rr.Arrows2D.columns(origins=arr[:, :2], vectors=arr[:, 2:])
            elif kind == "strip":
                cols = rr.LineStrips2D.columns(strips=vals)
            else:  # pragma: no cover - programming error
                raise ValueError(f"unknown column kind {kind!r}")
            rec.send_columns(entity, indexes=idx, columns=cols)


class Logger:
    def __init__(self, sess: zenoh.Session, sc: scenario_mod.Scenario, run_id: str, rec: rr.RecordingStream,
                 stop: threading.Event) -> None:  # fmt: skip
        self.session = sess
        self.sc = sc
        self.keys = Keys(run_id)
        self.rec = rec
        self.stop = stop
        self.inbox: queue.SimpleQueue[tuple[str, bytes]] = queue.SimpleQueue()
        self.rejections = Rejections()
        self.cols = Columns()
        self.poses: dict[int, dict[int, Pose]] = {}  # tick -> robot -> pose
        self.targets: dict[int, dict[int, tuple[float, float]]] = {}
        self.pending: list[Telemetry] = []
        self.formation: dict[int, int] = {}
        self.counts = {"truth": 0, "telemetry": 0, "other": 0, "log_errors": 0, "rows": 0}
        self.last_time_s = -1.0
        self.done = False

    def _on_sample(self, sample: zenoh.Sample) -> None:
        self.inbox.put((str(sample.key_expr), sample.payload.to_bytes()))

    def run(self) -> int:
        s, k = self.session, self.keys
        self._log_static()
        # What it logs, not the whole key space: observations, commands and
        # formation codes would double the router's work for nothing.
        s.declare_subscriber(k.world_all, self._on_sample)
        s.declare_subscriber(k.all_telemetry, self._on_sample)
        gc.freeze()  # start-up objects (numpy, scipy, zenoh) leave the collector's scans
        token = s.liveliness().declare_token(k.alive("logger", 0))
        last_send = last_flush = time.monotonic()
        try:
            while not self.stop.is_set() and not self.done:
                try:
                    key, payload = self.inbox.get(timeout=0.05)
                    self._handle(key, payload)
                    for _ in range(5000):  # drain what is there, bounded
                        key, payload = self.inbox.get_nowait()
                        self._handle(key, payload)
                except queue.Empty:
                    pass
                now = time.monotonic()
                if now - last_send >= SEND_PERIOD_S:
                    self._send()
                    last_send = now
                if now - last_flush >= FLUSH_PERIOD_S:
                    self._flush(timeout_s=0.2)
                    last_flush = now
            # Drain what already arrived, then close the file properly.
            while True:
                try:
                    self._handle(*self.inbox.get_nowait())
                except queue.Empty:
                    break
            self._send()
            self._flush(timeout_s=1.0)
        finally:
            token.undeclare()
        return 0

    def _guard(self, fn: Any, *args: Any, **kwargs: Any) -> None:
        try:
            fn(*args, **kwargs)
        except Exception as exc:  # noqa: BLE001 - logging never takes the process down
            self.counts["log_errors"] += 1
            if self.counts["log_errors"] <= 3:
                print(f"logger: rerun error ({type(exc).__name__}: {exc}); continuing", file=sys.stderr, flush=True)

    def _send(self) -> None:
        self.counts["rows"] += self.cols.count
        self._guard(self.cols.send, self.rec)

    def _flush(self, timeout_s: float) -> None:
        self._guard(self.rec.flush, timeout_sec=timeout_s)

    def _log_static(self) -> None:
        sc = self.sc
        if sc.obstacles:
            self._guard(
                self.rec.log, "world/obstacles",
                rr.Ellipses2D(centers=[(o.x_m, o.y_m) for o in sc.obstacles],
                              half_sizes=[(o.radius_m, o.radius_m) for o in sc.obstacles], colors=[200, 60, 60]),
                static=True,
            )  # fmt: skip
        self._guard(self.rec.log, "world/path", rr.LineStrips2D([list(sc.leader.waypoints)], colors=[120, 120, 120]),
                    static=True)  # fmt: skip
        lines = [f"{name} (code {i}): " + ", ".join(
            f"R{r} <- R{s.reference} at ({s.offset.x_m:+.2f}, {s.offset.y_m:+.2f}) m"
            for r, s in sorted(f.slots.items())) for i, (name, f) in enumerate(sc.formations.items())]  # fmt: skip
        self._guard(self.rec.log, "world/formations", rr.TextDocument("\n".join(lines)), static=True)

    def _handle(self, key: str, payload: bytes) -> None:
        rk = self.keys.parse_robot(key)
        if key == self.keys.truth:
            msg = self.rejections.decode(Truth, payload)
            if msg is not None:
                self.counts["truth"] += 1
                self._on_truth(msg)
        elif rk is not None and rk.kind == "telemetry":
            tel = self.rejections.decode(Telemetry, payload, sender=rk.robot_id)
            if tel is not None:
                self.counts["telemetry"] += 1
                self._on_telemetry(tel)
        elif key == self.keys.status:
            st = self.rejections.decode(Status, payload)
            if st is not None and st.state == "done":
                self.done = True
        else:
            self.counts["other"] += 1

    def _on_truth(self, msg: Truth) -> None:
        t = msg.time_s
        self.last_time_s = max(self.last_time_s, t)
        poses = {}
        for rid, x, y, th, _alive in msg.robots:
            poses[rid] = Pose(x, y, th)
            base = f"robots/r{rid}"
            self.cols.add(f"{base}/pose", "point", t, (x, y))
            self.cols.add(f"{base}/trajectory", "point", t, (x, y))
            self.cols.add(f"{base}/heading", "arrow", t, (x, y, 0.4 * math.cos(th), 0.4 * math.sin(th)))
        targets = {}
        for rid, x, y in msg.targets:
            targets[rid] = (x, y)
            self.cols.add(f"robots/r{rid}/target/true", "point", t, (x, y))
            if rid in poses:
                self.cols.add(f"robots/r{rid}/error/formation", "scalar", t, math.dist(poses[rid][:2], (x, y)))
        self.poses[msg.tick] = poses
        self.targets[msg.tick] = targets
        # Keep a bounded history to join telemetry with.
        for old in [k for k in self.poses if k < msg.tick - 400]:
            self.poses.pop(old, None)
            self.targets.pop(old, None)
        still = []
        for tel in self.pending:
            if tel.tick in self.poses:
                self._on_telemetry(tel)
            elif tel.tick > msg.tick - 400:
                still.append(tel)
        self.pending = still

    def _on_telemetry(self, tel: Telemetry) -> None:
        pose = self.poses.get(tel.tick, {}).get(tel.sender)
        if pose is None:
            if len(self.pending) < 10_000:
                self.pending.append(tel)
            return
        t, base = tel.time_s, f"robots/r{tel.sender}"
        true_target = self.targets.get(tel.tick, {}).get(tel.sender)
        for name, value in (("rho", tel.rho_m), ("alpha", tel.alpha_rad), ("v_n", tel.vn)):
            if value is not None:
                self.cols.add(f"{base}/fis/{name}", "scalar", t, value)
        self.cols.add(f"{base}/wheels/left", "scalar", t, tel.left_mps)
        self.cols.add(f"{base}/wheels/right", "scalar", t, tel.right_mps)
        self.cols.add(f"{base}/links/obs_dropped", "scalar", t, float(tel.obs_dropped))
        self.cols.add(f"{base}/links/formation_dropped", "scalar", t, float(tel.formation_dropped))
        if self.formation.get(tel.sender) != tel.formation:
            self.formation[tel.sender] = tel.formation
            self.cols.add(f"{base}/formation", "scalar", t, float(tel.formation))
            name = self.sc.formation_names[tel.formation] if tel.formation < len(self.sc.formation_names) else "?"
            self._guard(self._event, t, f"R{tel.sender} flies {name}")
        if tel.measured is not None:
            m = from_body_frame(pose, *tel.measured)
            self.cols.add(f"{base}/target/measured", "point", t, m)
            if true_target is not None:
                self.cols.add(f"{base}/error/measured", "scalar", t, math.dist(m, true_target))
        if tel.estimate is not None:
            e = from_body_frame(pose, *tel.estimate)
            self.cols.add(f"{base}/ekf/target", "point", t, e)
            if true_target is not None:
                self.cols.add(f"{base}/error/ekf", "scalar", t, math.dist(e, true_target))
            if tel.target_cov is not None:
                self.cols.add(f"{base}/ekf/cov", "strip", t, _ellipse(pose, e, tel.target_cov))

    def _event(self, t: float, text: str) -> None:
        self.rec.set_time(TIMELINE, duration=t)
        self.rec.log("events", rr.TextLog(text))

    def stats(self) -> dict[str, Any]:
        return {
            "messages": dict(self.counts),
            "last_sim_time_s": self.last_time_s,
            "rejected": dict(self.rejections.by_reason),
        }


def _ellipse(pose: Pose, center: tuple[float, float], cov: tuple[float, float, float]) -> np.ndarray:
    """2-sigma ellipse of a follower-frame covariance, as a world-frame polygon."""
    c = np.array([[cov[0], cov[1]], [cov[1], cov[2]]])
    vals, vecs = np.linalg.eigh(c)
    pts_body = (_CIRCLE * (2.0 * np.sqrt(np.maximum(vals, 0.0)))) @ vecs.T
    # Body-frame directions to world frame: x right -> (sin, -cos), y ahead -> (cos, sin).
    s, co = math.sin(pose[2]), math.cos(pose[2])
    rot = np.array([[s, co], [-co, s]])
    return pts_body @ rot.T + np.asarray(center)


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(prog="swarm logger", description=__doc__,
                                 formatter_class=argparse.RawDescriptionHelpFormatter)  # fmt: skip
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--run", required=True)
    ap.add_argument("--out", required=True, help="the .rrd file to write")
    ap.add_argument("--live", metavar="URL", help="also stream to a viewer, e.g. rerun+http://127.0.0.1:9876/proxy")
    ap.add_argument("--serve-web", action="store_true", help="also serve the web viewer (gRPC + web ports)")
    ap.add_argument("--stats", help="write the logger's counters (JSON) here at exit")
    ap.add_argument("--nice", type=int, default=10, help="scheduling niceness increment (default 10; 0 keeps it)")
    session.add_arguments(ap, default_mode="client")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    stop = install_stop_handlers()
    if args.nice:
        # Off the lockstep critical path: yield the cores to the world and the
        # agents; the logger buffers and catches up in their slack.
        with contextlib.suppress(OSError):
            os.nice(args.nice)
    inputs = role_inputs(args, "logger")
    if inputs is None:
        return 2
    sc, sess_cm = inputs
    with sess_cm as sess:
        rec = rr.RecordingStream("formation-swarm", recording_id=args.run,
                                 batcher_config=rr.ChunkBatcherConfig(flush_tick=0.1))  # fmt: skip
        sinks: list[Any] = [rr.FileSink(args.out)]
        if args.live:
            sinks.append(rr.GrpcSink(args.live))
        rec.set_sinks(*sinks, default_blueprint=blueprint())
        if args.serve_web:
            url = rr.serve_grpc(recording=rec, default_blueprint=blueprint())
            rr.serve_web_viewer(connect_to=url, open_browser=False)
            print(f"logger: web viewer serving {url}", flush=True)
        logger = Logger(sess, sc, args.run, rec, stop)
        code = logger.run()
        write_json(args.stats, logger.stats())
    rec.flush(timeout_sec=2.0)
    return code


if __name__ == "__main__":
    sys.exit(main())
