"""A lockstep run replayed in one process: the world's engine, the leader's and
the followers' brains and the link layer, called in the order the processes
call them (swarm/nodes/world.py, swarm/nodes/agent.py), without the wire.

In lockstep the processes add nothing to the figures: tick k is observed,
every robot answers it, the world steps. So this replica gives the run's
trajectory digest bit for bit (tests/system/test_distributed.py checks it against a
real run), and the published figures can be recomputed in a second, for
every change of the maths, by tests/unit/studies/test_published.py and by mutation testing.
"""

from __future__ import annotations

from collections.abc import Mapping
from pathlib import Path
from typing import Any

from formation_swarm.agents.follower import Follower
from formation_swarm.agents.leader import CodeRepeats, FormationSwitch
from formation_swarm.agents.pilot import PathPilot
from formation_swarm.protocol.links import Link, link_name
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.engine import WorldEngine
from formation_swarm.world.kinematics import Pose

WORLD = 0


def replay(path: str | Path, seed: int, overrides: Mapping[str, Any] | None = None) -> dict[str, Any]:
    """The world's summary of the lockstep run of a scenario with this seed."""
    sc = scenario_mod.load(path, overrides)
    eng = WorldEngine(sc, seed)
    ld = sc.leader
    lead = ld.robot_id
    pilot = PathPilot(ld.waypoints, ld.speed_mps, sc.width_m, ld.lookahead_m, ld.turn_rate_rps, corners=ld.corners)
    code = sc.code_of(ld.formation)
    avoid = None if ld.avoid_formation is None else sc.code_of(ld.avoid_formation)
    switch = FormationSwitch(code, avoid, ld.clear_after_s, sc.dt_s)
    repeats = CodeRepeats(ld.code_burst_s, ld.code_period_s, sc.dt_s)
    leader_cmd = (0.0, 0.0)
    codes = dict.fromkeys(sc.robots, code)  # the code each robot flies
    slots = sc.formation_by_code(code).slots
    followers = {rid: Follower(sc.followers[rid], slots[rid].offset) for rid in sc.follower_ids}
    reference = {rid: slots[rid].reference for rid in sc.follower_ids}
    obs_links = {rid: Link(link_name("obs", WORLD, rid), sc.links.obs_drop, seed) for rid in sc.robots}
    form_links = {
        rid: Link(link_name("formation", lead, rid), sc.links.formation_drop, seed) for rid in sc.follower_ids
    }
    cmd_links = {rid: Link(link_name("cmd", rid, WORLD), sc.links.cmd_drop, seed) for rid in sc.robots}
    seqs = dict.fromkeys(sc.robots, 0)  # each agent's one counter (commands, codes, telemetry)
    pending: dict[int, list[tuple[int, int]]] = {rid: [] for rid in sc.follower_ids}  # (tick, code) received
    while eng.tick < sc.ticks:
        tick, now = eng.tick, eng.time_s
        seen = {rid: eng.observation(rid) for rid in eng.alive_ids}  # published together, before any answer
        answers = {}
        for rid, (pose, readings, obstacles) in seen.items():
            delivered = obs_links[rid].accept(tick + 1)  # the world numbers each robot's observations from 1
            if rid == lead:
                if delivered:
                    codes[lead] = switch.step(obstacles)
                    leader_cmd = pilot.step(Pose(*pose))
                if repeats.due(codes[lead]):
                    seqs[lead] += 1  # one put for every follower; each link draws on its own
                    for f in sc.follower_ids:
                        if form_links[f].accept(seqs[lead]):
                            pending[f].append((tick, codes[lead]))
                answers[rid] = (*leader_cmd, codes[lead])
                continue
            while pending[rid] and pending[rid][0][0] < tick:  # a code for tick k is flown from k + 1
                _, new = pending[rid].pop(0)
                if new != codes[rid]:
                    slot = sc.formation_by_code(new).slots[rid]
                    if slot.reference != reference[rid]:
                        followers[rid].new_reference()
                    codes[rid], reference[rid] = new, slot.reference
                    followers[rid].set_offset(slot.offset)
            reading = None
            if delivered:
                reading = next(((r, p, b) for i, r, p, b in readings if i == reference[rid]), None)
            d = followers[rid].step(reading)
            answers[rid] = (d.left_mps, d.right_mps, codes[rid])
        for rid, (left, right, flown) in answers.items():
            seqs[rid] += 1
            if cmd_links[rid].accept(seqs[rid]):
                eng.set_command(rid, left, right, flown, now)
            if rid != lead:
                seqs[rid] += 1  # a follower's telemetry follows its command
        eng.step(now)
        if pilot.finished:
            break
    return eng.summary()
