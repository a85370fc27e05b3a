"""How the viewer shows a run: its layout (``blueprint``) and the static
data logged once at the start: the map's flip to y up, the obstacles, the
leader's path, the formations and how each robot's entities are drawn
(colour: formation_swarm.common.palette, size, series names). Every entity
path here is one formation_swarm.nodes.logger.recorder writes.

The layout: the formation followed (a view a few metres wide whose origin is
the leader's position, LEADER_FRAME) over the whole path; then one view per
quantity with every follower in it. V_N and the wheel speeds are drawn as
their 1 s means over the per-tick values (faint); beyond MANY_FOLLOWERS,
the means alone and no legend.

Beyond a dozen robots (crowd.CROWD_ROBOTS) the maps draw the swarm as a
whole, the leader alone labelled (at that count labels overlap) and the
follower worst in formation error ringed in red; each plot draws at most
3 series, the median and the worst follower's (formation_swarm.nodes.logger.crowd),
and a table names the worst followers. Each robot's own series are in the plots, hidden: its
eye in the blueprint panel shows it.
"""

from __future__ import annotations

import math
from typing import TYPE_CHECKING, Any

import rerun as rr
import rerun.blueprint as rrb

from formation_swarm.agents.params import LAWS
from formation_swarm.common.palette import OBSTACLE, PATH, lighter, robot_colour
from formation_swarm.nodes.logger.crowd import AGGREGATES, CROWD_ROBOTS

if TYPE_CHECKING:
    from formation_swarm.spec.scenario import Scenario

TIMELINE = "sim_time"
LEADER_FRAME = "leader_frame"  # the leader's position, y up: the origin of the followed view
MEAN_S = 1.0  # the window of the series' moving means, s (the report's)
SMOOTHED = ("fis/v_n", "wheels/left", "wheels/right")  # series with a 1 s mean beside them: <name>_1s
MANY_FOLLOWERS = 10  # beyond, the series views show the means alone, without a legend
FOLLOW_MARGIN_M = 1.5  # the followed view: this much around the formation's farthest slot
TRAIL_S = 10.0  # the map's trails: this much of the past, s
LINK_SERIES = ("links/obs_dropped", "links/formation_dropped")
FLIP = rr.Transform3D(scale=(1.0, -1.0, 1.0))  # the 2D view draws y down; the paper's figures y up


def blueprint(sc: Scenario) -> rrb.Blueprint:
    """The viewer's layout for ``sc``: the formation followed over the whole
    path, then the follower series over time and the run's events. Every entity is named by its full
    path: the viewer matches no wildcard in the middle of a path."""
    if len(sc.robots) > CROWD_ROBOTS:
        return _crowd_blueprint(sc)
    followers = sc.follower_ids
    many = len(followers) > MANY_FOLLOWERS
    legend = rrb.PlotLegend(visible=False) if many else rrb.PlotLegend(corner="LeftTop")

    def series(name: str, leaves: tuple[str, ...]) -> rrb.TimeSeriesView:
        if many:  # per-tick values of many robots are a blur: their means alone
            leaves = tuple(f"{leaf}_1s" if leaf in SMOOTHED else leaf for leaf in leaves)
        else:
            leaves += tuple(f"{leaf}_1s" for leaf in leaves if leaf in SMOOTHED)
        paths = [f"+ /robots/r{r}/{leaf}" for r in followers for leaf in leaves]
        return rrb.TimeSeriesView(name=name, origin="/", contents=paths, plot_legend=legend)

    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(_follow_view(sc), _map_view(sc), row_shares=[3, 2]),
            rrb.Vertical(
                series("formation error, m (Fig. 6b, 7b)", ("error/formation",)),
                series("V_N, m/s, 1 s mean (Fig. 8; per tick: faint)", ("fis/v_n",)),
                series("target error: raw (light) vs EKF, m (Fig. 9-10)", ("error/measured", "error/ekf")),
            ),
            rrb.Vertical(
                series(
                    "wheel speeds, m/s, 1 s mean: left, right (light); per tick: faint", ("wheels/left", "wheels/right")
                ),
                series("link drops: observations, formation codes (light)", LINK_SERIES),
                *_controller_series(sc),
                _events_view(sc),
            ),
            column_shares=[1.5, 1.75, 1.75],
        ),
        rrb.TimePanel(state="collapsed", timeline=TIMELINE, play_state="following"),
        collapse_panels=True,
    )


def _crowd_blueprint(sc: Scenario) -> rrb.Blueprint:
    """Beyond a dozen robots: the swarm drawn as a whole, aggregates in the plots
    (each robot's own series there, hidden), the worst followers named."""

    def series(name: str, quantities: tuple[str, ...]) -> rrb.TimeSeriesView:
        shown = [f"/swarm/{q}/{kind}" for q in quantities for kind in AGGREGATES[q]]
        own = [f"/robots/r{r}/{q}" for r in sc.follower_ids for q in quantities]
        hidden = {path: rrb.EntityBehavior(visible=False) for path in own}
        legend = rrb.PlotLegend(corner="LeftTop")
        return rrb.TimeSeriesView(
            name=name, origin="/", contents=[f"+ {p}" for p in shown + own], plot_legend=legend, overrides=hidden
        )

    contents = ["+ /world/obstacles", "+ /world/path"] if sc.obstacles else ["+ /world/path"]
    contents.append("+ /world/swarm/**")
    trail = {"/world/swarm/trails": _trail()}
    half = formation_reach_m(sc) + sc.diameter_m + FOLLOW_MARGIN_M
    follow = rrb.Spatial2DView(
        name=f"formation, following the leader R{sc.leader.robot_id}, m, y up",
        origin=f"/{LEADER_FRAME}",
        contents=contents,
        visual_bounds=rrb.VisualBounds2D(x_range=(-half, half), y_range=(-half, half)),
        overrides=trail,
    )
    whole = _map_view(sc, (contents, trail))
    return rrb.Blueprint(
        rrb.Horizontal(
            rrb.Vertical(follow, whole, row_shares=[3, 2]),
            rrb.Vertical(
                series("formation error, m: median and worst follower (Fig. 6b, 7b)", ("error/formation",)),
                series("V_N, m/s: median and largest follower (Fig. 8)", ("fis/v_n",)),
                series("target error, m: EKF median, worst; raw median (Fig. 9-10)", ("error/ekf", "error/measured")),
            ),
            rrb.Vertical(
                rrb.TextDocumentView(name="worst followers now", origin="/swarm/worst"),
                series("wheel speeds, m/s: median left, right", ("wheels/left", "wheels/right")),
                series("link drops: observations, formation codes, all followers", LINK_SERIES),
                *_controller_series(sc),
                _events_view(sc),
                row_shares=[1.4, 2, 1.6, *([2] if _controller_series(sc) else []), 2],
            ),
            column_shares=[1.5, 1.75, 1.75],
        ),
        rrb.TimePanel(state="collapsed", timeline=TIMELINE, play_state="following"),
        collapse_panels=True,
    )


def _events_view(sc: Scenario) -> rrb.TextLogView:
    """The run's events: formation changes, faults and the world's calls for them."""
    events = ["+ /events"]
    if sc.faults:
        events.append("+ /events/faults")
    if any(f.process is not None for f in sc.faults):
        events.append("+ /events/fault_calls")
    return rrb.TextLogView(
        name="events: formation changes, faults",
        origin="/",
        contents=events,
        columns=rrb.TextLogColumns(
            timeline_columns=[rrb.encodings.TimelineColumn(TIMELINE)],
            text_log_columns=[
                rrb.encodings.TextLogColumn("LogLevel"),
                rrb.encodings.TextLogColumn("Body"),
                rrb.encodings.TextLogColumn("EntityPath", visible=False),
            ],
        ),
    )


def _controller_series(sc: Scenario) -> list[rrb.TimeSeriesView]:
    """The values of the followers' own controllers (robots/r<id>/controller/<name>),
    when one flies a law that is not built in: the paper's send none."""
    own = [rid for rid, fp in sc.followers.items() if fp.law not in LAWS]
    if not own:
        return []
    contents = [f"+ /robots/r{rid}/controller/**" for rid in own]
    legend = rrb.PlotLegend(corner="LeftTop")
    return [rrb.TimeSeriesView(name="controllers' own values", origin="/", contents=contents, plot_legend=legend)]


def _map_contents(sc: Scenario) -> tuple[list[str], dict[str, Any]]:
    """What a map draws: the obstacles, the path, the robots, their trails
    (over the last TRAIL_S only), targets and EKF estimates; the trails' overrides."""
    robots = [f"/robots/r{r}" for r in sc.robots]
    contents = ["+ /world/obstacles", "+ /world/path"] if sc.obstacles else ["+ /world/path"]
    contents += [f"+ {base}/{leaf}" for base in robots for leaf in ("trajectory", "pose", "heading")]
    contents += [f"+ /robots/r{r}/{leaf}" for r in sc.follower_ids for leaf in ("target/true", "ekf/target", "ekf/cov")]
    return contents, {f"{base}/trajectory": _trail() for base in robots}


def _trail() -> rrb.VisibleTimeRanges:
    """A trail's points: the last TRAIL_S of them."""
    return rrb.VisibleTimeRanges(
        rrb.VisibleTimeRange(
            TIMELINE,
            start=rrb.TimeRangeBoundary.cursor_relative(seconds=-TRAIL_S),
            end=rrb.TimeRangeBoundary.cursor_relative(),
        )
    )


def formation_reach_m(sc: Scenario) -> float:
    """How far from the leader a follower's slot can be, over the formations:
    each slot's offset added along its chain of references."""
    reach = 0.0
    for f in sc.formations.values():
        far = {sc.leader.robot_id: 0.0}
        for _ in f.slots:  # a chain is at most as long as the slots
            for rid, slot in f.slots.items():
                if slot.reference in far:
                    far[rid] = far[slot.reference] + math.hypot(*slot.offset)
        reach = max(reach, *far.values())
    return reach


def _follow_view(sc: Scenario) -> rrb.Spatial2DView:
    """The formation followed: the map seen from LEADER_FRAME (the leader's
    position, which the recorder logs each tick), a few metres around it."""
    contents, overrides = _map_contents(sc)
    half = formation_reach_m(sc) + sc.diameter_m + FOLLOW_MARGIN_M
    return rrb.Spatial2DView(
        name=f"formation, following the leader R{sc.leader.robot_id}, m, y up",
        origin=f"/{LEADER_FRAME}",
        contents=contents,
        visual_bounds=rrb.VisualBounds2D(x_range=(-half, half), y_range=(-half, half)),
        overrides=overrides,
    )


def _map_view(sc: Scenario, drawn: tuple[list[str], dict[str, Any]] | None = None) -> rrb.Spatial2DView:
    """The whole path, y up (the world and the robots are drawn through a
    flip, FLIP), with the formation around it; ``drawn``: its contents and
    overrides, if not each robot's (_map_contents)."""
    contents, overrides = drawn or _map_contents(sc)
    xs = [x for x, _ in sc.leader.waypoints] + [o.x_m + s * o.radius_m for o in sc.obstacles for s in (-1, 1)]
    ys = [y for _, y in sc.leader.waypoints] + [o.y_m + s * o.radius_m for o in sc.obstacles for s in (-1, 1)]
    reach = max((math.hypot(*slot.offset) for f in sc.formations.values() for slot in f.slots.values()), default=0.0)
    margin = 1.0 + reach * max(1, len(sc.follower_ids))  # the formation around the path
    return rrb.Spatial2DView(
        name="whole path, m, y up (Fig. 6a, 7a, 9-11)",
        origin="/",
        contents=contents,
        visual_bounds=rrb.VisualBounds2D(
            x_range=(min(xs) - margin, max(xs) + margin), y_range=(-max(ys) - margin, -min(ys) + margin)
        ),
        overrides=overrides,
    )


def static_entities(sc: Scenario) -> list[tuple[str, Any]]:
    """The static data of a run of ``sc``, (entity path, what to log), in
    the order logged: the flip of y, the obstacles, the leader's path, the
    formations as text and how each robot is drawn."""
    out: list[tuple[str, Any]] = [(top, FLIP) for top in ("world", "robots")]  # y up, as in the paper's figures
    if sc.obstacles:
        circles = rr.Ellipses2D(
            centers=[(o.x_m, o.y_m) for o in sc.obstacles],
            half_sizes=[(o.radius_m, o.radius_m) for o in sc.obstacles],
            colors=[OBSTACLE],
            line_radii=[rr.Radius.ui_points(2.0)],
        )
        out.append(("world/obstacles", circles))
    out.append(
        ("world/path", rr.LineStrips2D([list(sc.leader.waypoints)], colors=[PATH], radii=[rr.Radius.ui_points(1.0)]))
    )
    lines = [
        f"{name} (code {i}): "
        + ", ".join(
            f"R{r} <- R{s.reference} at ({s.offset.x_m:+.2f}, {s.offset.y_m:+.2f}) m"
            for r, s in sorted(f.slots.items())
        )
        for i, (name, f) in enumerate(sc.formations.items())
    ]
    out.append(("world/formations", rr.TextDocument("\n".join(lines))))
    for rid in sc.robots:
        out += [(f"robots/r{rid}/{entity}", style) for entity, style in robot_styles(sc, rid).items()]
    return out


def robot_styles(sc: Scenario, rid: int) -> dict[str, Any]:
    """How robot ``rid``'s entities are drawn (static: colours, sizes, names),
    by path under robots/r<id>: its body at true scale, labelled, its heading,
    its trail; a follower's targets, EKF ellipse and series."""
    colour, light = robot_colour(rid), lighter(robot_colour(rid))
    faint = lighter(colour, 0.75)  # per-tick values under their means
    leader = rid == sc.leader.robot_id
    name = f"R{rid}"
    styles: dict[str, Any] = {
        "pose": rr.Points2D.from_fields(
            radii=[sc.diameter_m / 2],
            colors=[colour],
            labels=[f"{name} leader" if leader else name],
            show_labels=True,
            draw_order=40.0,  # over the trails and the targets
        ),
        "heading": rr.Arrows2D.from_fields(colors=[colour], radii=[rr.Radius.ui_points(1.5)]),
        "trajectory": rr.Points2D.from_fields(colors=[light], radii=[rr.Radius.ui_points(1.5)], draw_order=25.0),
    }
    if leader:
        return styles
    return styles | {
        "target/true": rr.Points2D.from_fields(colors=[colour], radii=[rr.Radius.ui_points(3.0)]),
        "ekf/target": rr.Points2D.from_fields(colors=[light], radii=[rr.Radius.ui_points(3.0)]),
        "ekf/cov": rr.LineStrips2D.from_fields(colors=[colour], radii=[rr.Radius.ui_points(1.0)]),
        "error/formation": rr.SeriesLines(colors=[colour], names=[name]),
        "fis/v_n": rr.SeriesLines(colors=[faint], names=[f"{name} per tick"], widths=[0.75]),
        "fis/v_n_1s": rr.SeriesLines(colors=[colour], names=[f"{name} 1 s mean"], widths=[2.0]),
        "error/ekf": rr.SeriesLines(colors=[colour], names=[f"{name} EKF"]),
        "error/measured": rr.SeriesLines(colors=[light], names=[f"{name} raw"], widths=[0.75]),
        "wheels/left": rr.SeriesLines(colors=[faint], names=[f"{name} left per tick"], widths=[0.75]),
        "wheels/right": rr.SeriesLines(colors=[faint], names=[f"{name} right per tick"], widths=[0.75]),
        "wheels/left_1s": rr.SeriesLines(colors=[colour], names=[f"{name} left 1 s mean"], widths=[2.0]),
        "wheels/right_1s": rr.SeriesLines(colors=[light], names=[f"{name} right 1 s mean"], widths=[2.0]),
        "links/obs_dropped": rr.SeriesLines(colors=[colour], names=[f"{name} observations"]),
        "links/formation_dropped": rr.SeriesLines(colors=[light], names=[f"{name} formation codes"]),
    }
