"""The recording of a swarm beyond a dozen robots (CROWD_ROBOTS): drawn and
summed up as a whole, each robot's own series kept a click away.

Entity paths (beside robots/r<id>/..., formation_swarm.nodes.logger.recorder)::

    world/swarm/robots, /headings        every robot's true position and heading, one entity
    world/swarm/trails                   the same positions every TRAIL_EVERY ticks
    world/swarm/targets, /ekf            the followers' true targets and EKF estimates
    world/swarm/labels                   the leader, named (the one label: no two overlap)
    world/swarm/worst                    a ring around the follower worst in formation error (named in swarm/worst)
    swarm/<quantity>/median, /worst      over the followers, per tick: error/formation,
                                         error/ekf, fis/v_n (worst: the largest); error/measured,
                                         wheels/left, wheels/right (median); links/<drops>/total
    swarm/worst                          a table of the worst followers now, each send

A robot's own series (robots/r<id>/error/formation, ..., and its pose and
targets, which the report reads: robots/r<id>/pose, /target/true,
/target/measured, /ekf/target) are held, as the whole swarm's arrays, until
the file's batch is due, then split by robot and sent to the file and the
live viewer (formation_swarm.nodes.logger.columns): a send costs a few calls
whatever the robots. Its EKF ellipse and 1 s means are left out. Everything
goes as columns, none through Rerun's batcher, whose rows a starved logger
was seen to hold back.
"""

from __future__ import annotations

from collections.abc import Callable
from typing import TYPE_CHECKING, Any

import numpy as np
import rerun as rr

if TYPE_CHECKING:
    from formation_swarm.nodes.logger.columns import ColumnSink
    from formation_swarm.protocol.messages import Truth
    from formation_swarm.spec.scenario import Scenario

CROWD_ROBOTS = 12  # beyond, the recording and the layout show the swarm as a whole
TRAIL_EVERY = 4  # ticks between two points of a trail
# Telemetry columns (recorder's rows): time, pose (3), target (2), measured (2), estimate (2), cov (3), then these.
SERIES = (
    "fis/rho",
    "fis/alpha",
    "fis/v_n",
    "wheels/left",
    "wheels/right",
    "links/obs_dropped",
    "links/formation_dropped",
)
FIRST_SERIES = 13
AGGREGATES = {  # quantity -> the aggregates drawn
    "error/formation": ("median", "worst"),
    "error/ekf": ("median", "worst"),
    "error/measured": ("median",),
    "fis/v_n": ("median", "worst"),
    "wheels/left": ("median",),
    "wheels/right": ("median",),
    "links/obs_dropped": ("total",),
    "links/formation_dropped": ("total",),
}


class Crowd:
    """A swarm's rows as whole-swarm entities, aggregates and each robot's own series."""

    def __init__(self, sc: Scenario, sink: ColumnSink, per_robot: Callable[[int, np.ndarray], None]) -> None:
        self.sc = sc
        self.sink = sink
        self.per_robot = per_robot  # called at each batch with a robot's telemetry rows (the recorder's columns)
        # Until the file's batch: each robot's series, as (times, robots, {series: values}) of the swarm,
        # and the telemetry rows with their robots.
        self.held: list[tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]] = []
        self.held_rows: list[tuple[np.ndarray, np.ndarray]] = []
        self.worst: dict[str, tuple[int, float, float]] = {}  # quantity -> robot, its value, the median; now
        self.where: dict[int, tuple[float, float]] = {}  # the latest true positions
        self.last_t = -1.0

    def truth(self, truths: list[Truth]) -> None:
        """Ground truth: the swarm's drawing, the formation errors (each robot's and aggregated)."""
        if not truths:
            return
        robots = [np.array([r[:4] for r in m.robots], dtype=float).reshape(-1, 4) for m in truths]
        times = np.array([m.time_s for m in truths])
        counts = np.array([len(r) for r in robots])
        r = np.concatenate(robots)
        add = self.sink.add
        t_rows = np.repeat(times, counts)
        add("world/swarm/robots", "point", times, r[:, 1:3], lengths=counts)
        heading = self.sc.diameter_m * np.column_stack([np.cos(r[:, 3]), np.sin(r[:, 3])])
        add("world/swarm/headings", "arrow", times, np.column_stack([r[:, 1:3], heading]), lengths=counts)
        trail = np.array([m.tick % TRAIL_EVERY == 0 for m in truths])
        add("world/swarm/trails", "point", times[trail], r[np.repeat(trail, counts), 1:3], lengths=counts[trail])
        lead = r[:, 0] == self.sc.leader.robot_id
        lt = t_rows[lead]
        add("leader_frame", "translation", lt, np.column_stack([r[lead, 1], -r[lead, 2], np.zeros_like(lt)]))
        # Each follower's true target beside its true position: the formation error.
        rows, tcounts = [], []
        for m, rr_ in zip(truths, robots, strict=True):
            at = {int(rid): i for i, rid in enumerate(rr_[:, 0])}
            got = [(m.time_s, rid, x, y, *rr_[at[rid], 1:3]) for rid, x, y in m.targets if rid in at]
            rows += got
            tcounts.append(len(got))
        self.where = {int(rid): (x, y) for rid, x, y, _th in robots[-1]}
        self.last_t = max(self.last_t, float(times.max()))
        if not rows:
            return
        a = np.array(rows)
        add("world/swarm/targets", "point", times, a[:, 2:4], lengths=np.array(tcounts))
        err = np.hypot(a[:, 2] - a[:, 4], a[:, 3] - a[:, 5])
        self.held.append((t_rows, r[:, 0].astype(int), {"pose": r[:, 1:3]}))
        self.held.append((a[:, 0], a[:, 1].astype(int), {"error/formation": err, "target/true": a[:, 2:4]}))
        self._aggregate("error/formation", a[:, 0], a[:, 1], err)

    def telemetry(self, a: np.ndarray, rids: np.ndarray, measured: np.ndarray, estimate: np.ndarray) -> None:
        """Joined telemetry rows of many followers (the recorder's columns), ``rids`` theirs."""
        if len(a) == 0:
            return
        order = np.lexsort((rids, a[:, 0]))  # by time, then robot
        a, rids, measured, estimate = a[order], rids[order], measured[order], estimate[order]
        t, target = a[:, 0], a[:, 4:6]
        series: dict[str, np.ndarray] = {name: a[:, col] for col, name in enumerate(SERIES, start=FIRST_SERIES)}
        series["error/measured"] = np.hypot(*(measured - target).T)
        series["error/ekf"] = np.hypot(*(estimate - target).T)
        self.held.append((t, rids, {**series, "target/measured": measured, "ekf/target": estimate}))
        self.held_rows.append((rids, a))
        for name, v in series.items():
            if name in AGGREGATES:
                self._aggregate(name, t, rids, v)
        ok = ~np.isnan(estimate[:, 0])
        times, counts = np.unique(t[ok], return_counts=True)
        self.sink.add("world/swarm/ekf", "point", times, estimate[ok], lengths=counts)

    def flush(self, final: bool = False) -> None:
        """Each robot's own series and rows, split by robot, once the file's batch is due."""
        if not (final or self.sink.due()):
            return
        held, self.held = self.held, []
        groups: dict[tuple[str, ...], list[tuple[np.ndarray, np.ndarray, dict[str, np.ndarray]]]] = {}
        for part in held:
            groups.setdefault(tuple(part[2]), []).append(part)
        for names, parts in groups.items():
            t = np.concatenate([p[0] for p in parts])
            rids = np.concatenate([p[1] for p in parts])
            values = {name: np.concatenate([p[2][name] for p in parts]) for name in names}
            for rid, idx in _by_robot(rids):
                ti = t[idx]
                for name, v in values.items():
                    vi = v[idx]
                    ok = ~np.isnan(vi if vi.ndim == 1 else vi[:, 0])
                    kind = "scalar" if vi.ndim == 1 else "point"
                    self.sink.add(f"robots/r{rid}/{name}", kind, ti[ok], vi[ok], prompt=False)
        rows, self.held_rows = self.held_rows, []
        if rows:
            rids, a = np.concatenate([r for r, _ in rows]), np.concatenate([a for _, a in rows])
            for rid, idx in _by_robot(rids):
                self.per_robot(rid, a[idx])

    def _aggregate(self, name: str, t: np.ndarray, rids: np.ndarray, v: np.ndarray) -> None:
        """Per tick, over the followers: the aggregates of ``name`` (rows sorted by time)."""
        ok = ~np.isnan(v)
        t, rids, v = t[ok], rids[ok], v[ok]
        if len(t) == 0:
            return
        order = np.argsort(t, kind="stable")
        t, rids, v = t[order], rids[order], v[order]
        times, starts = np.unique(t, return_index=True)
        parts = np.split(np.arange(len(t)), starts[1:])
        kinds = AGGREGATES[name]
        if "median" in kinds:
            med = np.array([np.median(v[p]) for p in parts])
            self.sink.add(f"swarm/{name}/median", "scalar", times, med)
        if "worst" in kinds:
            worst = np.maximum.reduceat(v, starts)
            self.sink.add(f"swarm/{name}/worst", "scalar", times, worst)
            last = parts[-1]
            i = last[int(np.argmax(v[last]))]
            self.worst[name] = (int(rids[i]), float(v[i]), float(np.median(v[last])))
        if "total" in kinds:
            self.sink.add(f"swarm/{name}/total", "scalar", times, np.add.reduceat(v, starts))

    def name(self) -> None:
        """The leader's label, the ring around the follower worst in formation
        error and the table naming the worst followers, at the latest truth's
        time: one row each (sent as columns, like the rest)."""
        if self.last_t < 0:
            return
        t, one = np.array([self.last_t]), np.array([1])
        leader = self.sc.leader.robot_id
        if leader in self.where:
            self.sink.add("world/swarm/labels", "point", t, np.array([self.where[leader]]), lengths=one)
        worst = self.worst.get("error/formation")
        if worst is not None and worst[0] in self.where:
            self.sink.add("world/swarm/worst", "point", t, np.array([self.where[worst[0]]]), lengths=one)
        lines = ["| followers now | worst | its value | median |", "|---|---|---|---|"]
        for name, title, unit in (
            ("error/formation", "formation error", "m"),
            ("error/ekf", "EKF target error", "m"),
            ("fis/v_n", "V_N", "m/s"),
        ):
            if name in self.worst:
                rid, value, median = self.worst[name]
                lines.append(f"| {title} | R{rid} | {value:.3f} {unit} | {median:.3f} {unit} |")
        self.sink.add("swarm/worst", "text", t, np.array(["\n".join(lines)], dtype=object))


def crowd_styles(sc: Scenario) -> list[tuple[str, Any]]:
    """How the swarm's entities are drawn (static): a colour per robot, in the order the world lists them."""
    from formation_swarm.common.palette import lighter, robot_colour

    colours = [robot_colour(r) for r in sorted(sc.robots)]
    followers = [robot_colour(r) for r in sorted(sc.follower_ids)]
    light, small, dot = [lighter(c) for c in colours], rr.Radius.ui_points(1.0), rr.Radius.ui_points(2.5)
    out: list[tuple[str, Any]] = [
        ("world/swarm/robots", rr.Points2D.from_fields(radii=[sc.diameter_m / 2], colors=colours, draw_order=40.0)),
        ("world/swarm/headings", rr.Arrows2D.from_fields(colors=colours, radii=[rr.Radius.ui_points(1.5)])),
        ("world/swarm/trails", rr.Points2D.from_fields(colors=light, radii=[small], draw_order=25.0)),
        ("world/swarm/targets", rr.Points2D.from_fields(colors=followers, radii=[dot])),
        ("world/swarm/ekf", rr.Points2D.from_fields(colors=[lighter(c) for c in followers], radii=[dot])),
        ("world/swarm/labels", rr.Points2D.from_fields(labels=[f"R{sc.leader.robot_id} leader"], show_labels=True)),
        ("swarm/worst", rr.TextDocument.from_fields(media_type=rr.MediaType.MARKDOWN)),
        ("world/swarm/worst", rr.Points2D.from_fields(radii=[sc.diameter_m * 1.5], colors=[(220, 30, 30, 110)])),
    ]
    dark, grey, red = (40, 40, 40), (150, 150, 150), (200, 30, 30)
    looks = {  # entity under swarm/: colour, width, name in the legend
        "error/formation/median": (dark, 2.0, "median follower"),
        "error/formation/worst": (red, 1.5, "worst follower"),
        "error/ekf/median": (dark, 2.0, "EKF, median follower"),
        "error/ekf/worst": (red, 1.5, "EKF, worst follower"),
        "error/measured/median": (grey, 1.0, "raw reading, median follower"),
        "fis/v_n/median": (dark, 2.0, "median follower"),
        "fis/v_n/worst": (red, 1.5, "largest"),
        "wheels/left/median": (dark, 1.5, "left, median follower"),
        "wheels/right/median": (grey, 1.5, "right, median follower"),
        "links/obs_dropped/total": (dark, 2.0, "observations, all followers"),
        "links/formation_dropped/total": (grey, 2.0, "formation codes, all followers"),
    }
    for entity, (colour, width, name) in looks.items():
        out.append((f"swarm/{entity}", rr.SeriesLines(colors=[colour], widths=[width], names=[name])))
    return out


def _by_robot(rids: np.ndarray) -> list[tuple[int, np.ndarray]]:
    """The rows of each robot, in their order: (robot, its row indices)."""
    order = np.argsort(rids, kind="stable")
    ids, starts = np.unique(rids[order], return_index=True)
    return [(int(r), part) for r, part in zip(ids, np.split(order, starts[1:]), strict=True)]
