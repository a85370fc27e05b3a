"""The world's tick as a plain object: decoded messages in, what to send out.

:class:`WorldTick` decides everything the world decides, with no Zenoh and
no waiting: which commands count for which tick (world.commands judges
them; lockstep takes an answer only for the tick it published), what the
command links do with them, which robots are observed, waited for, lost or
re-admitted (world.process_faults), what the engine does each tick. It
returns the Observations, the Truth, the Status and the FaultCalls to
publish. The world process (formation_swarm.nodes.world.node) wraps it with
the session, the liveliness tokens, the inbox and a clock that says when a
tick starts and how long its answers are waited for.

One tick k, as the process drives it: :meth:`start`, the fault calls
(:meth:`calls_due`, :meth:`apply_call`) and the returning robots
(:meth:`readmit`), :meth:`observations`, the last tick's :meth:`truth` and
:meth:`record`, the answers (:meth:`receive` or :meth:`command`; in lockstep
until :meth:`waiting` is empty or the deadline's :meth:`miss`), then
:meth:`close` and :meth:`step`.
"""

from __future__ import annotations

import collections
import hashlib
import struct
from collections.abc import Callable, Iterator
from typing import Any

from formation_swarm.protocol.links import Link, faults_on, link_name
from formation_swarm.protocol.messages import WORLD_ID, Command, FaultCall, Observation, Status, Truth
from formation_swarm.world import wire
from formation_swarm.world.commands import CommandGate
from formation_swarm.world.engine import WorldEngine
from formation_swarm.world.kinematics import Pose
from formation_swarm.world.misses import Misses
from formation_swarm.world.process_faults import START, Call, ProcessFaults
from formation_swarm.world.setup import WorldSetup
from formation_swarm.world.stalls import LOST_WAIT_S, STALL_AFTER_MISSES, Stalls

# The state ground truth is made of, taken once tick k's commands are in: (tick,
# time_s, robots, poses, each follower's formation code).
TruthState = tuple[int, float, tuple, dict[int, Pose], dict[int, int]]


class WorldTick:
    """The world of one run, tick by tick. ``lockstep``: an answer counts only
    for the tick it answers and staleness is measured on sim time; else (real
    time) the latest command counts and staleness is measured on the wall
    time each tick starts at. ``wall_s`` gives the wall seconds the fault log
    records (the world's loop time)."""

    def __init__(self, setup: WorldSetup, seed: int, *, lockstep: bool, wall_s: Callable[[], float]) -> None:
        self.setup = setup
        self.lockstep = lockstep
        self.wall_s = wall_s
        self.engine = WorldEngine(setup, seed)
        # Kills, restarts, freezes and agents that come and go (world.process_faults).
        self.faults = ProcessFaults(self.engine, tuple(setup.faults), lockstep)
        self.gate = CommandGate(setup)
        self.stalls = Stalls()  # lockstep: robots silent while their token stays (world.stalls)
        # The receiving ends of the command links, with the faults the run's schedule puts on them.
        self.cmd_links: dict[int, Link[Command]] = {
            rid: Link(
                link_name("cmd", rid, WORLD_ID),
                setup.links.cmd_drop,
                seed,
                faults_on(setup.faults, "cmd", rid),
                setup.dt_s,
            )
            for rid in setup.robots
        }
        # A sequence per stream (each robot's observations, truth, status): the number
        # an observation's link drop is decided on must not depend on how many status
        # messages the wall clock sent before it.
        self.seqs: collections.Counter[str] = collections.Counter()
        self._obs_streams = {rid: link_name("obs", WORLD_ID, rid) for rid in setup.robots}  # made once
        self.counts = {"obs_sent": 0, "cmd_received": 0, "truth_sent": 0}
        self.tick_wall_s = 0.0  # real time: the wall time the current tick started at
        self.misses = 0
        self.robot_misses = Misses(setup.faults, setup.dt_s)  # each robot's, and those a fault explains
        self.late_answers = 0
        # Per robot, answers refused because it had answered their tick already: a second agent's.
        self.duplicate_agents: collections.Counter[int] = collections.Counter()
        self.leader_done = False
        self.finished = False  # "done" sent: agents leaving now are not deaths
        self.truth_due: TruthState | None = None  # ground truth not yet sent (take_truth)
        # Each robot's own trajectory digest (the engine's covers them all): what a
        # fault or a forgery left untouched shows as an equal digest.
        self.robot_hashes = {rid: hashlib.sha256() for rid in setup.robots}

    @property
    def running(self) -> bool:
        """Whether there is a tick to run: the duration not reached, the leader not done."""
        return self.engine.tick < self.setup.ticks and not self.leader_done

    @property
    def now_s(self) -> float:
        """The time a command is stamped with and staleness is measured on."""
        return self.engine.time_s if self.lockstep else self.tick_wall_s

    def start(self, wall_s: float) -> None:
        """Tick k starts, ``wall_s`` after the loop did."""
        self.tick_wall_s = wall_s

    def _next_seq(self, stream: str) -> int:
        self.seqs[stream] += 1
        return self.seqs[stream]

    # -- the agents' answers ----------------------------------------------------------
    def receive(self, robot_id: int | None, payload: bytes) -> None:
        """A payload on robot ``robot_id``'s command key (None: a key of no robot)."""
        msg = self.gate.decode(robot_id, payload)
        if msg is not None:
            self.command(msg)

    def command(self, msg: Command) -> None:
        """A decoded command, from the robot its key names."""
        eng = self.engine
        self.counts["cmd_received"] += 1
        if msg.done and not self.gate.done(msg, eng.robots[self.setup.leader.robot_id].pose):
            return
        answered_tick = self.gate.last[msg.sender][0]
        if not self.gate.admit(msg, eng.tick):
            return
        self._heard(msg.sender)
        if self.lockstep and msg.tick != eng.tick:
            self.late_answers += 1
            return
        if msg.tick == answered_tick:
            # One robot, one agent. An agent answers a tick once; Zenoh merges the
            # tokens of one key, so a second agent of the robot shows here only.
            self.duplicate_agents[msg.sender] += 1
            return
        # It answers the tick, whatever its link does with it: lost or held, the
        # robot's command is not renewed now.
        r = eng.robots[msg.sender]
        r.answered = True
        if r.alive:
            self.faults.answered(msg.sender, self.wall_s())
        if msg.done:  # the leader's, at its last waypoint (CommandGate.done)
            self.leader_done = True
        for handed in self.cmd_links[msg.sender].deliver(msg.seq, msg.tick, msg):
            self._apply(handed)

    def _apply(self, msg: Command) -> None:
        """A command its link hands over (now, or held until this tick)."""
        if not self.gate.fresh(msg) or not self.engine.robots[msg.sender].alive:
            return
        left, right = self.gate.wheels(msg)
        self.engine.set_command(msg.sender, left, right, msg.formation, self.now_s)

    # -- who takes part -----------------------------------------------------------------
    def agent_token(self, rid: int, present: bool) -> str | None:
        """Robot ``rid``'s agent token came or went; a line to print when that
        means the robot is lost."""
        lost = self.faults.token(rid, present, self.wall_s(), self.finished)
        if lost is not None and self._lost_after_stall(rid):
            lost += f"; it had stalled: awaited up to {LOST_WAIT_S:g} s (the clock holds)"
        return lost

    def calls_due(self) -> list[Call]:
        """The process fault calls of this tick, in schedule order."""
        return self.faults.due(self.engine.tick)

    def call_message(self, call: Call) -> FaultCall:
        """The FaultCall that asks the executor to do ``call``."""
        eng = self.engine
        seq = self._next_seq("faults")
        return FaultCall(
            sender=WORLD_ID,
            seq=seq,
            tick=eng.tick,
            time_s=eng.time_s,
            action=call.action,
            process=call.fault.target,
            index=call.index,
        )

    def apply_call(self, call: Call) -> int | None:
        """The world's side of a call, before the tick's observations; the robot
        whose fresh agent the world waits for now (lockstep, a restart), if any."""
        self.faults.execute(call, self.wall_s())
        if call.action == START and self.lockstep and call.robot in self.faults.starting:
            return call.robot
        return None

    def back(self, rid: int) -> bool:
        """Whether stopped robot ``rid``'s agent is back (a fresh token)."""
        return self.faults.back(rid)

    def not_back(self, rid: int) -> None:
        """No fresh agent for restarted robot ``rid`` in time: it stays stopped."""
        self.faults.not_back(rid, self.wall_s())

    def readmit(self, hears: Callable[[int], bool]) -> list[int]:
        """Re-admit the robots whose agent is back; the robots re-admitted. In
        lockstep one whose observations nobody hears yet (``hears``) waits for
        the next tick: they would be lost."""
        back = []
        for rid in self.faults.returned():
            if self.lockstep and not hears(rid):
                continue
            self.faults.readmit(rid, self.wall_s())
            # A fresh agent counts its messages from 1; what its predecessor's link
            # still held would be taken for newer than all of them.
            self.gate.forget(rid)
            self.cmd_links[rid].forget_held()
            self.stalls.back(rid)
            back.append(rid)
        return back

    # -- what the world sends -------------------------------------------------------
    def _to_observe(self) -> list[int]:
        """The robots observed this tick, the followers first: their controller
        (EKF, two fuzzy inferences) takes longer than the leader's pilot."""
        eng = self.engine
        observed = [rid for rid in eng.alive_ids if self.faults.observed(rid)]  # frozen (lockstep): not waited for
        if self.stalls.stalled:  # a stalled robot: now and then (world.stalls)
            observed = self.stalls.observe(observed, self.wall_s())
        observed.sort(key=self.setup.leader.robot_id.__eq__)
        return observed

    def _sent(self, rid: int) -> int:
        """Robot ``rid``'s observation goes out: its seq; the robot now owes an answer."""
        self.engine.robots[rid].answered = False
        self.counts["obs_sent"] += 1
        return self._next_seq(self._obs_streams[rid])

    def observations(self) -> Iterator[tuple[int, Observation]]:
        """This tick's Observation for each robot observed, each made as the one
        before it is sent, the followers' first (:meth:`encoded_observations`
        gives their bytes, made at once)."""
        eng = self.engine
        for rid, observed in eng.each_observation(self._to_observe()):
            yield rid, wire.observation(self._sent(rid), eng.tick, eng.time_s, observed)

    def encoded_observations(self) -> list[tuple[int, bytes]]:
        """:meth:`observations` as the bytes each Observation encodes to, in the
        same order, every camera read and encoded at once (world.wire): a
        fraction of the cost per robot at hundreds of robots."""
        observed = self._to_observe()
        seqs = {rid: self._sent(rid) for rid in observed}
        return wire.observation_payloads(self.engine, observed, seqs)

    def take_truth(self) -> None:
        """Ground truth of tick k, once its commands are in, before its step: the
        state it is made of, kept for :meth:`truth` (the logger's; in lockstep
        it is made and sent while the agents work on tick k + 1)."""
        eng = self.engine
        robots = tuple((rid, *r.pose, r.alive) for rid, r in eng.robots.items())
        poses = {rid: r.pose for rid, r in eng.robots.items()}
        formations = {rid: eng.robots[rid].formation for rid in self.setup.follower_ids}
        self.truth_due = (eng.tick, eng.time_s, robots, poses, formations)
        self._digest_poses(poses)

    def _digest_poses(self, poses: dict[int, Pose]) -> None:
        for rid, pose in poses.items():
            self.robot_hashes[rid].update(struct.pack("<3d", *pose))

    def truth(self) -> Truth | None:
        """The ground truth taken last, if not yet sent: each follower's true
        target is that of the formation it flies at tick k (a code is flown from
        the command that carries it), as the world's formation error takes it."""
        if self.truth_due is None:
            return None
        (tick, time_s, robots, poses, formations), self.truth_due = self.truth_due, None
        eng = self.engine
        targets = tuple(eng.targets_in(formations, poses))
        self.counts["truth_sent"] += 1
        return Truth(
            sender=WORLD_ID, seq=self._next_seq("truth"), tick=tick, time_s=time_s, robots=robots, targets=targets
        )

    def status(self, state: str) -> Status:
        eng = self.engine
        return Status(
            sender=WORLD_ID,
            seq=self._next_seq("status"),
            tick=eng.tick,
            time_s=eng.time_s,
            state=state,
            total_ticks=self.setup.ticks,
        )

    # -- the tick's course ----------------------------------------------------------
    def record(self) -> None:
        """The last tick's metrics (while the agents work on this one)."""
        self.engine.record()

    def waiting(self, among: list[int] | None = None) -> list[int]:
        """The robots of ``among`` (default: the live ones) this tick still waits
        for: alive, observed, not answered, not stalled (world.stalls)."""
        robots = self.engine.robots
        waiting = [
            rid
            for rid in (self.engine.alive_ids if among is None else among)
            if not robots[rid].answered and robots[rid].alive and self.faults.observed(rid)
        ]
        return self._not_stalled(waiting) if self.stalls.stalled else waiting

    def thawing(self, waiting: list[int]) -> bool:
        """Whether one of ``waiting`` was just thawed: its first answer may wait for its SIGCONT."""
        thawing = self.faults.thawing
        return bool(thawing) and any(rid in thawing for rid in waiting)

    def miss(self, waiting: list[int]) -> list[int]:
        """The deadline passed: each robot of ``waiting`` missed this tick and is
        stopped for its step; the ones just thawed among them."""
        self.misses += len(waiting)
        thawed = []
        for rid in waiting:
            self.robot_misses.count(rid, self.engine.tick, returning=self.faults.returning(rid))
            self.engine.robots[rid].command = (0.0, 0.0)  # missed: stopped this tick
            if rid in self.faults.thawing:
                self.faults.thawing.discard(rid)
                thawed.append(rid)
        return thawed

    def close(self) -> None:
        """The tick's answers are in: the commands its links held back until
        now are applied, and its ground truth taken."""
        tick = self.engine.tick
        for link in self.cmd_links.values():
            for held in link.due(tick):
                self._apply(held)
        self.take_truth()

    def step(self) -> None:
        self.engine.step(self.now_s)

    def finish(self) -> Status:
        """The run is over: the Status "done" to send; agents leaving from now on are not lost."""
        status = self.status("done")
        self.finished = True
        return status

    # -- robots that fall silent (lockstep; world.stalls) ---------------------------------
    def _heard(self, rid: int) -> None:
        """A command of ``rid`` was taken (on time or late): a stall, if any, ends."""
        eng = self.engine
        if self.stalls.heard(rid, eng.tick, eng.time_s):
            self.faults.log("answering again", rid, None, self.wall_s())

    def _not_stalled(self, waiting: list[int]) -> list[int]:
        observed = [rid for rid in self.engine.alive_ids if self.faults.observed(rid)]
        return self.stalls.wait_for(waiting, observed)

    def stall(self, missed: list[int]) -> list[str]:
        """``missed`` missed this tick's deadline: lines to print for those now stalled."""
        eng = self.engine
        lines = []
        for rid in self.stalls.missed(missed, eng.tick, eng.time_s):
            self.faults.log("stalled", rid, None, self.wall_s())
            lines.append(
                f"robot {rid} stalled at t={eng.time_s:.2f} s: {STALL_AFTER_MISSES} deadlines missed in a row; "
                "stopped and not waited for until it answers again"
            )
        return lines

    def _lost_after_stall(self, rid: int) -> bool:
        eng = self.engine
        if not self.stalls.lost(rid, eng.tick, eng.time_s, self.wall_s()):
            return False
        self.faults.log("awaited", rid, None, self.wall_s())
        return True

    def awaited(self) -> list[int]:
        """The robots lost after a stall the clock is held for."""
        return sorted(self.stalls.awaited)

    def overdue(self) -> list[str]:
        """Lines to print for the awaited robots whose wait has ended: the run goes on without them."""
        eng, wall = self.engine, self.wall_s()
        lines = []
        for rid in self.stalls.overdue(eng.tick, eng.time_s, wall):
            self.faults.log("not back", rid, None, wall)
            lines.append(f"robot {rid} not back within {LOST_WAIT_S:g} s of its loss; the run goes on without it")
        return lines

    # -- figures ------------------------------------------------------------------------
    def summary(self) -> dict[str, Any]:
        """The engine's summary, with the commands the gate clamped beside its stale stops."""
        out: dict[str, Any] = {}
        for key, value in self.engine.summary().items():
            out[key] = value
            if key == "stale_stops":
                out["clamped_commands"] = self.gate.clamped
        return out

    def robot_digests(self) -> dict[str, str]:
        """Each robot's trajectory digest, by robot id."""
        return {str(rid): h.hexdigest() for rid, h in self.robot_hashes.items()}

    def link_stats(self) -> dict[str, Any]:
        return {lk.name: lk.stats() for lk in self.cmd_links.values()}

    def rejected(self) -> dict[str, int]:
        return dict(self.gate.rejections.by_reason)
