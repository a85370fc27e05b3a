"""The world process: clock, physics and sensors of one run over Zenoh.

    swarm world --scenario S.toml --run RUN [--mode lockstep|realtime] [--seed N]
                [--stats FILE] [--out DIR] [--expect-logger] [--process-faults]
                [--peers-timeout S] [zenoh flags]

By default it is also the run's Zenoh router (``--zenoh-mode router --listen ...``):
agents and the logger connect to it as clients. Before tick 0 it waits, up
to ``--peers-timeout``, for an agent per robot (and the logger): their
liveliness tokens and the matching of every observation publisher, each
change waking the loop. With ``--out`` it writes the run's summary.json
(formation_swarm.runtime.summary, as ``swarm run`` does) from its own stats.

Lockstep: tick k is published to every live agent; tick k+1 starts when
every live agent has answered tick k, or when ``lockstep_deadline_s`` passes
(the miss is counted, that robot's command is not renewed). Real time: ticks
follow the wall clock at 1/dt Hz; the latest command is held; a robot whose
command is older than ``stale_after_s`` is stopped.

Process faults of the scenario (kill, restart, freeze) are driven from here:
at a fault's tick the world publishes a FaultCall on ``Keys.faults``, before
that tick's observations, for the launcher to execute, and applies the
fault's effect itself (world.process_faults). It needs ``--process-faults``,
the promise that an executor is there: then it also waits for the
executor's token before tick 0. A robot whose agent comes back (a restart,
a session regained) is re-admitted.

Commands reach the loop through a Zenoh FIFO channel read on the loop's own
thread (one thread switch per message; a callback thread and a queue made
two). That recv has no timeout: a deadline, a tick of the wall clock, a
liveliness change or a stop signal wakes it with a local put on
``Keys.world_wake``, which only this process subscribes to.
"""

from __future__ import annotations

import argparse
import collections
import contextlib
import gc
import math
import os
import threading
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import zenoh

from formation_swarm.protocol import session
from formation_swarm.protocol.batch import BatchPublisher
from formation_swarm.protocol.codec import Rejections
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.links import Link, faults_on, link_name
from formation_swarm.protocol.messages import WORLD_ID, Command, FaultCall, Observation, Status, Truth
from formation_swarm.runtime import cliargs, proc
from formation_swarm.runtime import role as role_mod
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.runtime.proc import exit_after_main, write_json
from formation_swarm.spec import files as scenario_files
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.engine import WorldEngine
from formation_swarm.world.process_faults import START, Call, ProcessFaults

STATUS_PERIOD_S = 0.25
# The real-time world's priority in Linux's real-time class (swarm.proc.realtime_priority):
# low among real-time threads (the kernel's own run from 50 up), above every normal one.
REALTIME_PRIORITY = 10
# Real time: Status "running" every tick up to this many robots, beyond it every
# STATUS_PERIOD_S like lockstep: each one is routed to every agent, whose
# status callback thread then wakes and takes the GIL from its loop.
STATUS_EVERY_TICK_UP_TO = 25
LINGER_S = 2.0  # after "done", at most this long for the agents to leave
# ... and for the logger, which leaves once it has every follower's last
# telemetry: a router that left first would lose what it had not yet forwarded.
# Longer, for a logger the machine starves (it runs at nice 10).
LINGER_LOGGER_S = 10.0
# Lockstep holds at most one command per robot here; when full, Zenoh waits
# for the loop (back-pressure) rather than dropping.
CMD_CAPACITY = 1024


def percentile(values: list[float], q: float) -> float:
    """The ``q``-th percentile of ``values`` (nearest rank); NaN when there are none."""
    if not values:
        return math.nan
    ranked = sorted(values)
    return ranked[min(len(ranked) - 1, max(0, math.ceil(q / 100.0 * len(ranked)) - 1))]


class Alarm:
    """Calls ``wake`` at a time of ``time.monotonic()``, from a thread of its own.

    Moving the alarm later costs no thread switch: the thread wakes at the
    earlier time, sees the later one and sleeps again. So a lockstep world can
    re-arm its deadline every tick and the thread wakes once per deadline
    span, not once per tick.
    """

    def __init__(self, wake: Callable[[], None]) -> None:
        self._wake = wake
        self._at = math.inf
        self._closed = False
        self._cond = threading.Condition()
        self._thread = threading.Thread(target=self._run, name="world-alarm", daemon=True)
        self._thread.start()

    def set(self, at: float) -> None:
        with self._cond:
            if at < self._at:
                self._cond.notify()
            self._at = at

    def close(self) -> None:
        with self._cond:
            self._closed = True
            self._cond.notify()
        self._thread.join(timeout=1.0)

    def _run(self) -> None:
        while True:
            with self._cond:
                while (left := self._at - time.monotonic()) > 0 and not self._closed:
                    self._cond.wait(None if left == math.inf else left)
                if self._closed:
                    return
                self._at = math.inf
            self._wake()


class World:
    def __init__(
        self,
        sess: zenoh.Session,
        sc: scenario_mod.Scenario,
        run_id: str,
        seed: int,
        mode: str,
        expect_logger: bool,
        role: role_mod.Role,
        where: str = "",
        executor: bool = False,
    ) -> None:
        self.session = sess
        self.sc = sc
        self.keys = Keys(run_id)
        self.mode = mode
        self.expect_logger = expect_logger
        self.role = role
        self.stop = role.stop
        self.where = where  # the session's endpoints, for messages
        self.engine = WorldEngine(sc, seed)
        # Kills, restarts, freezes and agents that come and go (world.process_faults).
        self.faults = ProcessFaults(self.engine, sc.faults, mode == "lockstep")
        self.executor = executor  # a process executes the fault calls (--process-faults)
        self.executor_seen = False
        self.t0 = time.monotonic()  # wall clock of the loop's start, for the fault log
        self.rejections = Rejections()
        # A sequence per stream (each robot's observations, truth, status): the number
        # an observation's link drop is decided on must not depend on how many status
        # messages the wall clock sent before it.
        self.seqs: collections.Counter[str] = collections.Counter()
        self.events: collections.deque[tuple[str, bool]] = collections.deque()  # liveliness, from its callback
        self.wakes = 0
        # The receiving ends of the command links, with the faults the run's schedule puts on them.
        self.cmd_links: dict[int, Link[Command]] = {
            rid: Link(link_name("cmd", rid, 0), sc.links.cmd_drop, seed, faults_on(sc.faults, "cmd", rid), sc.dt_s)
            for rid in sc.robots
        }
        self.cmd_ids = {self.keys.cmd(rid): rid for rid in sc.robots}  # each robot's command key, parsed once
        # Per robot, (tick, seq) of the last command taken, and of the last one its
        # cmd link handed over and was applied: each must be newer, in that order.
        self.last_cmd: dict[int, tuple[int, int]] = {rid: (-1, -1) for rid in sc.robots}
        self.applied: dict[int, tuple[int, int]] = {rid: (-1, -1) for rid in sc.robots}
        self.wheel_limit = sc.max_wheel_mps * (1.0 + 1e-9)
        self.misses = 0
        self.late_answers = 0
        self.late_ticks = 0
        self.max_tick_lateness_s = 0.0
        self.lateness_s: list[float] = []  # real time: each tick's lateness, for its percentiles
        self.loop_cpu_s = 0.0  # CPU time of this process over the loop (all its threads)
        self.agents_seen: set[int] = set()
        self.logger_seen = False
        self.present: set[str] = set()  # alive keys of the agents and the logger
        self.finished = False  # "done" sent: agents leaving now are not deaths
        self.leader_done = False
        self.end_reason = summary_mod.INTERRUPTED
        self.ended_at_s: float | None = None  # sim time when the run ended; None if it never started
        self.wall_s = 0.0
        self.loop_wall_s = 0.0
        self.wait_s = 0.0  # lockstep: time waiting for the agents' answers
        self.counts = {"obs_sent": 0, "cmd_received": 0, "truth_sent": 0}
        # (tick, time_s, robots, poses, formations) of the ground truth not yet sent (_take_truth).
        self.truth_due: tuple[int, float, tuple, dict, dict] | None = None

    # -- Zenoh callback: short, hands the event to the loop and wakes it -------
    def _on_alive(self, sample: zenoh.Sample) -> None:
        self.events.append((str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT))
        self._wake()

    def _wake(self) -> None:
        with contextlib.suppress(zenoh.ZError):  # a stop signal may come after the session closed
            self.wake_pub.put(b"")

    def run(self) -> int:
        s, k, sc = self.session, self.keys, self.sc
        # A second world of the run (started twice by hand or by a service) would
        # step the same robots and say the run is its own: asked of the router first
        # (before our liveliness subscriber: with it, Zenoh 1.10 answered this query empty).
        replies = s.liveliness().get(k.alive("world", 0), timeout=role_mod.DUPLICATE_QUERY_S)
        if any(reply.ok is not None for reply in replies):
            self.role.complain(
                f"run {k.run_id!r} already has a world ({self.where}); two worlds would both step its robots: "
                "not starting"
            )
            return role_mod.EXIT_DUPLICATE
        block = zenoh.CongestionControl.BLOCK  # Zenoh never drops an observation; our link layer may
        obs_pubs = {rid: s.declare_publisher(k.obs(rid), congestion_control=block) for rid in sc.robots}
        # For the logger only, batched; in lockstep it may hold the run back rather
        # than be lost (a dropped batch took up to 200 ticks out of the recording).
        truth_cc = block if self.mode == "lockstep" else zenoh.CongestionControl.DROP
        truth_pub = BatchPublisher(s.declare_publisher(k.truth, congestion_control=truth_cc))
        status_pub = s.declare_publisher(k.status)
        self.wake_pub = s.declare_publisher(k.world_wake, congestion_control=block)
        self.fault_pub = s.declare_publisher(k.faults, congestion_control=block) if self.executor else None
        self.obs_pubs = obs_pubs
        self.cmds = s.declare_subscriber(k.all_cmd, zenoh.handlers.FifoChannel(CMD_CAPACITY))
        self.alarm = Alarm(self._wake)
        self.stop.add_waker(self._wake)
        # A matching change wakes the loop: before tick 0, and when a fresh agent subscribes mid-run.
        self.matching = [p.declare_matching_listener(lambda _status: self._wake()) for p in obs_pubs.values()]
        s.liveliness().declare_subscriber(k.alive_any, self._on_alive, history=True)
        token = s.liveliness().declare_token(k.alive("world", 0))
        try:
            if not self._wait_ready(obs_pubs):
                if self.stop.is_set():
                    return self.stop.exit_code
                self.end_reason = summary_mod.PEERS_TIMEOUT
                return role_mod.EXIT_NO_PEERS
            self._publish_status(status_pub, "running")
            sc = self.sc
            self.role.say(
                f"run {self.keys.run_id} started: {len(sc.robots)} agents"
                f"{' and the logger' if self.expect_logger else ''} present; {self.mode}, "
                f"up to {sc.ticks} ticks of {sc.dt_s:g} s"
            )
            gc.freeze()  # start-up objects leave the collector's scans
            self.t0 = time.monotonic()
            cpu0 = time.process_time()
            code = self._loop(obs_pubs, truth_pub, status_pub)
            self.loop_wall_s = time.monotonic() - self.t0
            self.loop_cpu_s = time.process_time() - cpu0
            self.ended_at_s = self.engine.time_s
            if code == 0:
                self.end_reason = summary_mod.LEADER_FINISHED if self.leader_done else summary_mod.DURATION_REACHED
            self._publish_truth(truth_pub)  # the last tick's
            truth_pub.flush()  # before "done": the logger stops listening after it
            self._publish_status(status_pub, "done")
            self.finished = True
            self._linger()
            return code
        finally:
            self.alarm.close()
            token.undeclare()

    def _linger(self) -> None:
        """Stay up (we may be the router) until the agents and the logger have left
        on "done", so that their last messages still get routed. Bounded: the
        agents LINGER_S, the logger LINGER_LOGGER_S."""
        start, logger = time.monotonic(), self.keys.alive("logger", 0)
        while not self.stop.is_set():
            now = time.monotonic()
            ends = [start + (LINGER_LOGGER_S if key == logger else LINGER_S) for key in self.present]
            if not ends or now >= max(ends):
                return
            self._drain(until=max(ends))

    def _wait_ready(self, obs_pubs: dict[int, zenoh.Publisher]) -> bool:
        """Every agent's token (declared after its subscribers and after its
        command publisher matched us), every observation publisher matched and,
        if expected, the logger's token and the fault executor's (declared after
        its subscriber to the calls); until the role's peers deadline. A token
        or a matching change wakes the loop."""
        want = set(self.sc.robots)
        while not self.stop.is_set():
            self._drain(until=0.0)
            matched = all(p.matching_status.matching for p in obs_pubs.values())
            if (
                self.agents_seen >= want
                and matched
                and (self.logger_seen or not self.expect_logger)
                and (self.executor_seen or not self.executor)
            ):
                return True
            if self.role.left_s() <= 0:
                self._give_up(want, obs_pubs)
                return False
            self._drain(until=self.role.deadline)
        return False

    def _give_up(self, want: set[int], obs_pubs: dict[int, zenoh.Publisher]) -> None:
        missing = []
        if absent := sorted(want - self.agents_seen):
            missing.append(f"no agent for robot{'s' if len(absent) > 1 else ''} {', '.join(map(str, absent))}")
        if self.expect_logger and not self.logger_seen:
            missing.append("no logger")
        if self.executor and not self.executor_seen:
            missing.append("no executor of the process faults (the launcher's token alive/launcher/0)")
        deaf = sorted(r for r, p in obs_pubs.items() if r in self.agents_seen and not p.matching_status.matching)
        if deaf:
            missing.append(f"agents {', '.join(map(str, deaf))} present but not subscribed to their observations")
        self.role.gave_up(
            f"{' and '.join(missing)} in run {self.keys.run_id!r} ({self.where}); "
            "check --run and --connect of the missing processes"
        )

    def _next_seq(self, stream: str) -> int:
        self.seqs[stream] += 1
        return self.seqs[stream]

    def _publish_status(self, pub: zenoh.Publisher, state: str) -> None:
        seq = self._next_seq("status")
        eng = self.engine
        msg = Status(sender=WORLD_ID, seq=seq, tick=eng.tick, time_s=eng.time_s, state=state, total_ticks=self.sc.ticks)
        pub.put(msg.to_bytes())

    def _drain(self, until: float) -> None:
        """Handle what has arrived; if nothing has, wait for it until ``until``
        (``time.monotonic()``), or until a wake-up (liveliness, stop)."""
        channel = self.cmds.handler
        sample = channel.try_recv()
        if sample is None and not self.events and until > time.monotonic():
            self.alarm.set(until)
            sample = channel.recv()
        while sample is not None:
            self._on_sample(sample)
            sample = channel.try_recv()
        while self.events:
            self._on_alive_event(*self.events.popleft())

    def _on_sample(self, sample: zenoh.Sample) -> None:
        key = str(sample.key_expr)
        rid = self.cmd_ids.get(key)
        if rid is None:
            if key == self.keys.world_wake:
                self.wakes += 1
                return
            rk = self.keys.parse_robot(key)
            if rk is None or rk.robot_id not in self.engine.robots:
                self.rejections.reject("unknown robot")
                return
            rid = rk.robot_id
        msg = self.rejections.decode(Command, sample.payload.to_bytes(), sender=rid)
        if msg is not None:
            self._on_command(msg)

    def _on_alive_event(self, key: str, present: bool) -> None:
        parsed = self.keys.parse_alive(key)
        if parsed is None:
            return
        role, ident = parsed
        if role in ("agent", "logger"):
            (self.present.add if present else self.present.discard)(key)
        if role == "logger":
            self.logger_seen = self.logger_seen or present
        elif role == "launcher":
            self.executor_seen = self.executor_seen or present
        elif role == "agent" and ident.isdigit() and int(ident) in self.engine.robots:
            rid = int(ident)
            if present:
                self.agents_seen.add(rid)
            if lost := self.faults.token(rid, present, self._wall_s(), self.finished):
                print(f"world: {lost}", flush=True)

    def _wall_s(self) -> float:
        """Wall seconds since the loop started (before: since the world started)."""
        return time.monotonic() - self.t0

    def _on_command(self, msg: Command) -> None:
        eng = self.engine
        r = eng.robots[msg.sender]
        self.counts["cmd_received"] += 1
        # What no robot can do first, then what no honest agent sends: a command
        # answers an observation the world published, so never a tick to come,
        # never one older than (or the same message as) the last one taken.
        if not (abs(msg.left_mps) <= self.wheel_limit and abs(msg.right_mps) <= self.wheel_limit):
            self.rejections.reject("wheel speed out of bounds")
            return
        if msg.formation >= len(self.sc.formation_names):
            self.rejections.reject("unknown formation")
            return
        if msg.tick > eng.tick:
            self.rejections.reject("tick ahead of the world")
            return
        # Ordered by (tick, seq), the tick bounded by the world's own: a command
        # with a huge seq (a stolen login, say) cannot make the agent's real ones
        # look replayed beyond the tick it answers, as ordering by seq alone did.
        if (msg.tick, msg.seq) <= self.last_cmd[msg.sender]:
            self.rejections.reject("replayed or reordered")
            return
        self.last_cmd[msg.sender] = (msg.tick, msg.seq)
        if self.mode == "lockstep" and msg.tick != eng.tick:
            self.late_answers += 1
            return
        # It answers the tick, whatever its link does with it: lost or held, the
        # robot's command is not renewed now.
        r.answered = True
        if r.alive:
            self.faults.answered(msg.sender, self._wall_s())
        if msg.done and msg.sender == self.sc.leader.robot_id:
            self.leader_done = True
        for handed in self.cmd_links[msg.sender].deliver(msg.seq, msg.tick, msg):
            self._apply_command(handed)

    def _apply_command(self, msg: Command) -> None:
        """A command its link hands over (now, or held until this tick): taken if
        newer than the last one taken, else (a duplicate, one held behind a
        newer one) "replayed or reordered"."""
        if (msg.tick, msg.seq) <= self.applied[msg.sender]:
            self.rejections.reject("replayed or reordered")
            return
        self.applied[msg.sender] = (msg.tick, msg.seq)
        if not self.engine.robots[msg.sender].alive:
            return
        now = self.engine.time_s if self.mode == "lockstep" else self.wall_s
        self.engine.set_command(msg.sender, msg.left_mps, msg.right_mps, msg.formation, now)

    def _publish_observations(self, obs_pubs: dict[int, zenoh.Publisher]) -> None:
        eng = self.engine
        tick, t = eng.tick, eng.time_s
        observed = [rid for rid in eng.alive_ids if self.faults.observed(rid)]  # frozen (lockstep): not waited for
        # Each sent as soon as it is taken, the followers' first: their controller
        # (EKF, two fuzzy inferences) takes longer than the leader's pilot.
        observed.sort(key=self.sc.leader.robot_id.__eq__)
        for rid, (pose, readings, obstacles) in eng.each_observation(observed):
            eng.robots[rid].answered = False
            seq = self._next_seq(link_name("obs", 0, rid))
            obs = Observation(
                sender=WORLD_ID,
                seq=seq,
                tick=tick,
                time_s=t,
                pose=pose,
                readings=tuple(readings),
                obstacles=tuple(obstacles),
            )
            obs_pubs[rid].put(obs.to_bytes())
            self.counts["obs_sent"] += 1

    def _take_truth(self) -> None:
        """Ground truth of tick k, once its commands are in, before its step: the
        state it is made of, kept for :meth:`_publish_truth` (the logger's; in
        lockstep it is made and sent while the agents work on tick k + 1)."""
        eng = self.engine
        robots = tuple((rid, *r.pose, r.alive) for rid, r in eng.robots.items())
        poses = {rid: r.pose for rid, r in eng.robots.items()}
        formations = {rid: eng.robots[rid].formation for rid in self.sc.follower_ids}
        self.truth_due = (eng.tick, eng.time_s, robots, poses, formations)

    def _publish_truth(self, truth_pub: BatchPublisher) -> None:
        """The ground truth taken last, if not yet sent: each follower's true
        target is that of the formation it flies at tick k (a code is flown from
        the command that carries it), as the world's formation error takes it."""
        if self.truth_due is None:
            return
        (tick, time_s, robots, poses, formations), self.truth_due = self.truth_due, None
        eng = self.engine
        targets = tuple((rid, *eng.target_in(rid, formation, poses)) for rid, formation in formations.items())
        seq = self._next_seq("truth")
        truth = Truth(sender=WORLD_ID, seq=seq, tick=tick, time_s=time_s, robots=robots, targets=targets)
        truth_pub.put(truth.to_bytes())
        self.counts["truth_sent"] += 1

    def _loop(
        self, obs_pubs: dict[int, zenoh.Publisher], truth_pub: BatchPublisher, status_pub: zenoh.Publisher
    ) -> int:
        eng, sc = self.engine, self.sc
        period = sc.dt_s
        start = time.monotonic()
        next_status = start
        while eng.tick < sc.ticks and not self.leader_done:
            if self.stop.is_set():
                return self.stop.exit_code
            tick_start = start + eng.tick * period
            now = time.monotonic()
            if self.mode == "realtime":
                # Wait for this tick's time, handling commands meanwhile.
                while now < tick_start and not self.stop.is_set():
                    self._drain(until=tick_start)
                    now = time.monotonic()
                lateness = now - tick_start
                self.max_tick_lateness_s = max(self.max_tick_lateness_s, lateness)
                self.lateness_s.append(lateness)
                if lateness > 0.5 * period:
                    self.late_ticks += 1
                self.wall_s = now - start
            self._process_faults()  # this tick's fault calls and returning agents, before its observations
            self._publish_observations(obs_pubs)
            # While the agents work on this tick: the last tick's ground truth and metrics.
            self._publish_truth(truth_pub)
            eng.record()
            if self.mode == "lockstep":
                t_wait = time.perf_counter()
                deadline = time.monotonic() + sc.lockstep_deadline_s
                # A robot just thawed may wait for its SIGCONT: its first answer gets longer.
                thaw_deadline = time.monotonic() + self.role.peers_timeout_s
                # Robots only leave this list while the world waits (they answer, die or
                # freeze; none is revived before the next tick): it is filtered, not rebuilt.
                waiting = eng.alive_ids
                while not self.stop.is_set():
                    robots = eng.robots
                    waiting = [
                        rid
                        for rid in waiting
                        if not robots[rid].answered and robots[rid].alive and self.faults.observed(rid)
                    ]
                    if not waiting:
                        break
                    if time.monotonic() >= (until := self._answer_deadline(waiting, deadline, thaw_deadline)):
                        self.misses += len(waiting)
                        for rid in waiting:
                            eng.robots[rid].command = (0.0, 0.0)  # missed: stopped this tick
                            if rid in self.faults.thawing:
                                self.faults.thawing.discard(rid)
                                print(
                                    f"world: robot {rid} did not answer within {self.role.peers_timeout_s:g} s "
                                    f"of its thaw at t={eng.time_s:.2f} s; a miss",
                                    flush=True,
                                )
                        break
                    self._drain(until=until)
                self.wait_s += time.perf_counter() - t_wait
            else:
                self._drain(until=0.0)
            if now >= next_status or (self.mode == "realtime" and len(self.sc.robots) <= STATUS_EVERY_TICK_UP_TO):
                self._publish_status(status_pub, "running")
                next_status = now + STATUS_PERIOD_S
            for link in self.cmd_links.values():  # commands held back until this tick
                for held in link.due(eng.tick):
                    self._apply_command(held)
            self._take_truth()
            if self.mode == "realtime":  # no one waits for the next tick's observations: now
                self._publish_truth(truth_pub)
            eng.step(eng.time_s if self.mode == "lockstep" else self.wall_s)
        return 0

    def _answer_deadline(self, waiting: list[int], deadline: float, thaw_deadline: float) -> float:
        thawing = self.faults.thawing
        return thaw_deadline if thawing and any(rid in thawing for rid in waiting) else deadline

    def _process_faults(self) -> None:
        """The fault calls of this tick, published before its observations and
        applied to the world; then the robots whose agent is back are re-admitted."""
        faults = self.faults
        for call in faults.due(self.engine.tick):
            self._publish_call(call)
            faults.execute(call, self._wall_s())
            if call.action == START and self.mode == "lockstep" and call.robot in faults.starting:
                self._await_fresh_agent(call)
        for rid in faults.returned():
            if self.mode == "lockstep" and not self.obs_pubs[rid].matching_status.matching:
                continue  # its observations would be lost: next tick
            faults.readmit(rid, self._wall_s())
            # A fresh agent counts its messages from 1; what its predecessor's link
            # still held would be taken for newer than all of them.
            self.last_cmd[rid] = (-1, -1)
            self.applied[rid] = (-1, -1)
            self.cmd_links[rid].forget_held()
            print(f"world: robot {rid} is back at t={self.engine.time_s:.2f} s", flush=True)

    def _publish_call(self, call: Call) -> None:
        if self.fault_pub is not None:
            msg = FaultCall(
                sender=WORLD_ID,
                seq=self._next_seq("faults"),
                tick=self.engine.tick,
                time_s=self.engine.time_s,
                action=call.action,
                process=call.fault.target,
                index=call.index,
            )
            self.fault_pub.put(msg.to_bytes())

    def _await_fresh_agent(self, call: Call) -> None:
        """Lockstep, at a restart's "start": wait until the fresh agent's token is
        there and its observations are subscribed (bounded by --peers-timeout)."""
        rid = call.robot
        if rid is None:  # only agents restart (formation_swarm.common.faults)
            return
        deadline = time.monotonic() + self.role.peers_timeout_s
        while not self.stop.is_set():
            self._drain(until=0.0)
            if self.faults.back(rid) and self.obs_pubs[rid].matching_status.matching:
                return
            if time.monotonic() >= deadline:
                self.faults.not_back(rid, self._wall_s())
                print(
                    f"world: no fresh agent for robot {rid} within {self.role.peers_timeout_s:g} s of its restart "
                    f"at t={self.engine.time_s:.2f} s ('{call.fault}'); it stays stopped",
                    flush=True,
                )
                return
            self._drain(until=deadline)

    def stats(self, wall_s: float) -> dict[str, Any]:
        out = self.engine.summary()
        out.update(
            {
                "mode": self.mode,
                "wall_time_s": wall_s,
                "loop_wall_time_s": self.loop_wall_s,
                "answer_wait_s": self.wait_s,
                "ticks_per_s": self.engine.tick / self.loop_wall_s if self.loop_wall_s > 0 else math.nan,
                "lockstep_misses": self.misses,
                "late_answers": self.late_answers,
                "late_ticks": self.late_ticks,
                "wake_ups": self.wakes,  # deadlines, clock ticks, liveliness, stop: not commands
                "max_tick_lateness_s": self.max_tick_lateness_s,
                "p99_tick_lateness_s": percentile(self.lateness_s, 99.0),
                "cpu_s": time.process_time(),  # the process's CPU time so far (user + system, all threads)
                "loop_cpu_s": self.loop_cpu_s,
                **self.faults.stats(),  # deaths, fault_log, rejoins, recoveries
                "leader_done": self.leader_done,
                "end_reason": self.end_reason,
                "ended_at_s": self.ended_at_s,
                "messages": dict(self.counts),
                "cmd_links": {lk.name: lk.stats() for lk in self.cmd_links.values()},
                "rejected": dict(self.rejections.by_reason),
            }
        )
        return out


DESCRIPTION = """\
Run the world of one run by hand: the clock, the robots' physics and their
cameras. It waits for one agent per robot of the scenario (and for the
logger, with --expect-logger), then ticks until the leader reaches its last
waypoint or the scenario's duration runs out, and tells every process of
the run that it is done.

By default it is also the run's Zenoh router: start the agents and the
logger with --connect to one of its --listen endpoints. Behind a router of
your own, give it --zenoh-mode client --connect ROUTER.

It prints one line when its session is open, one when the run starts and
one when it ends (why, and where its stats and summary went)."""


def build_parser() -> cliargs.Parser:
    ap = cliargs.Parser(
        prog="swarm world",
        description=DESCRIPTION,
        epilog=role_mod.EXIT_CODES_HELP,
    )
    ap.add_argument(
        "--scenario",
        required=True,
        metavar="FILE|NAME",
        help="the scenario: a TOML file or a shipped scenario's name (see swarm scenarios)",
    )
    ap.add_argument(
        "--run",
        required=True,
        metavar="ID",
        help="run id: the same for every process of the run; every key starts with it",
    )
    ap.add_argument(
        "--mode",
        choices=("lockstep", "realtime"),
        default="lockstep",
        help="lockstep: each tick waits for every agent's answer; realtime: ticks follow the wall "
        "clock, 1/dt per second (default lockstep)",
    )
    ap.add_argument(
        "--seed",
        type=cliargs.seed,
        default=None,
        metavar="N",
        help="random seed of camera noise, link drops and the faults' draws (default: the scenario's)",
    )
    ap.add_argument("--stats", metavar="FILE", help="write the world's metrics here at the end (JSON)")
    ap.add_argument(
        "--out",
        metavar="DIR",
        help="write the run's summary.json and the scenario as run (scenario.toml) into DIR, as swarm run does",
    )
    ap.add_argument("--expect-logger", action="store_true", help="also wait for the logger before the first tick")
    ap.add_argument(
        "--rt-priority",
        type=cliargs.integer(0, 99),
        default=REALTIME_PRIORITY,
        metavar="0-99",
        help="realtime mode: run the world in Linux's real-time scheduling class at this priority, so that "
        "its ticks start on time however busy the agents keep the cores; 0 leaves it in the normal class. "
        "Without the right to (root or CAP_SYS_NICE, or an RLIMIT_RTPRIO of at least this) it stays "
        f"normal and says so (default {REALTIME_PRIORITY})",
    )
    ap.add_argument(
        "--process-faults",
        action="store_true",
        help="a process of the run (swarm run's launcher) executes the scenario's process faults (kill, restart, "
        "freeze) on the world's calls: wait for its token too before the first tick. Without it the world "
        "refuses a scenario with process faults",
    )
    role_mod.add_arguments(ap, waits_for="an agent per robot (and the logger)")
    session.add_arguments(ap, default_mode="router")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    role = role_mod.Role("world", args.peers_timeout)
    started = time.monotonic()
    sc = role.load(args)
    if isinstance(sc, int):
        return sc
    if (procs := [str(f) for f in sc.faults if f.process is not None]) and not args.process_faults:
        role.complain(
            f"the scenario has process faults ({', '.join(procs)}) and nothing here executes them: swarm run "
            "does; by hand, remove them from [[faults]], or pass --process-faults with an executor of your own"
        )
        return role_mod.EXIT_USAGE
    # Before the session: Zenoh's threads, started with it, take the same class
    # (the commands they receive are as urgent as the ticks).
    scheduling = proc.realtime_priority(args.rt_priority) if args.mode == "realtime" else "normal"
    if scheduling.startswith("normal ("):
        role.say(f"scheduling: {scheduling}; under load its ticks may start late")
    sess_cm = role.connect(args, login="world")  # as the router its --auth holds no login: not checked
    if isinstance(sess_cm, int):
        return sess_cm
    if args.seed is not None:
        sc = sc.with_seed(args.seed)
    run_dir = Path(args.out) if args.out else None
    if run_dir is not None:
        run_dir.mkdir(parents=True, exist_ok=True)
        (run_dir / "scenario.toml").write_text(scenario_files.dumps(sc.raw))
    where = role_mod.describe_session(args)
    with sess_cm as sess:
        waits = f"agents {', '.join(map(str, sc.robots))}" + (" and the logger" if args.expect_logger else "")
        role.say(f"{where}; run {args.run}: waiting up to {role.peers_timeout_s:g} s for {waits}")
        world = World(sess, sc, args.run, sc.seed, args.mode, args.expect_logger, role, where, args.process_faults)
        code = world.run()
        if code == role_mod.EXIT_DUPLICATE:
            return code  # the run's stats and summary are the other world's: nothing written over them
        stats = world.stats(time.monotonic() - started)
        stats["exit_code"] = code
        stats["scheduling"] = scheduling
        write_json(args.stats, stats)
        written = [f"stats in {args.stats}"] if args.stats else []
        if run_dir is not None:
            written.append(f"summary in {_write_summary(run_dir, args, sc, stats, code, world)}")
        if code == role_mod.EXIT_NO_PEERS:
            return code  # the line that gave up was the last word
        why = summary_mod.describe_end(world.end_reason, world.ended_at_s)
        if world.end_reason == summary_mod.INTERRUPTED:
            at = "before the run started" if world.ended_at_s is None else f"at t={world.ended_at_s:.2f} s"
            why = f"{role.stopped_by()} {at}"
        role.say(
            f"run {args.run} ended ({why}), "
            f"exit code {code}, {world.engine.tick} ticks; "
            + ("; ".join(written) or "nothing written (no --stats, no --out)")
        )
    return code


def _write_summary(
    run_dir: Path, args: argparse.Namespace, sc: scenario_mod.Scenario, stats: dict[str, Any], code: int, world: World
) -> Path:
    """summary.json of a run whose processes were started by hand: the world's
    own stats (the others' are in their --stats files)."""
    summary = summary_mod.build(
        run_id=args.run,
        sc=sc,
        mode=args.mode,
        parts={"world": stats},
        exit_code=code,
        end_reason=world.end_reason,
        ended_at_s=world.ended_at_s,
        interrupted=world.end_reason == summary_mod.INTERRUPTED,
        timed_out=False,
        processes={"world": {"pid": os.getpid(), "exit_code": code, "exit_after_stop_s": None}},
        events=[],
        recording=None,
    )
    return summary_mod.write(run_dir, summary)


if __name__ == "__main__":
    exit_after_main(main())
