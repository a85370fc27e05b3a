"""The world process around its tick: the session, the publishers, the
liveliness tokens, the inbox and the clock.

:class:`World` waits, up to ``--peers-timeout``, for an agent per robot (and
the logger, the ROS 2 bridge and the executor of process faults when promised): their
liveliness tokens and the matching of every observation publisher, each
change waking the loop. Then its loop runs the tick (world.tick) on its
clock (nodes.world.clock) and publishes what the tick returns; at a process
fault's tick it publishes the FaultCall on ``Keys.faults`` before the tick's
observations, and in lockstep it waits at a restart for the fresh agent.
After "done" it stays up (it may be the router) until the others have left.
"""

from __future__ import annotations

import gc
import math
import time
from dataclasses import dataclass
from typing import Any

import zenoh

from formation_swarm.nodes.world import waits
from formation_swarm.nodes.world.clock import CLOCKS
from formation_swarm.nodes.world.inbox import Inbox
from formation_swarm.nodes.world.outbox import TRUTH_WINDOW_S, Outbox, Peers
from formation_swarm.nodes.world.sessions import SESSION_CLOSED, LoginWatch
from formation_swarm.protocol.keys import Keys
from formation_swarm.runtime import process as process_mod
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.runtime.memory import FloodRelief
from formation_swarm.world.process_faults import Call
from formation_swarm.world.setup import WorldSetup
from formation_swarm.world.tick import WorldTick

LINGER_S = 2.0  # after "done", at most this long for the agents to leave
# ... and for the logger, which leaves once it has every follower's last
# telemetry: a router that left first would lose what it had not yet forwarded.
# Longer, for a logger the machine starves (it runs at nice 10).
LINGER_LOGGER_S = 10.0


@dataclass(frozen=True)
class Options:
    """How this world runs: its run, its seed and mode, whom it waits for."""

    run_id: str
    seed: int
    mode: str = "lockstep"  # or "realtime" (nodes.world.clock.CLOCKS)
    expect_logger: bool = False
    expect_bridge: bool = False  # a ROS 2 bridge publishes every tick: waited for as the logger
    executor: bool = False  # a process executes the fault calls (--process-faults)
    where: str = ""  # the session's endpoints, for messages
    logins: bool = False  # the router with logins: a token kept by a second session is seen
    # Each tick's truth sent at once, never held for the batch's window: a ROS 2
    # bridge answers tick k once it has published tick k - 1 (nodes.bridge).
    truth_every_tick: bool = False
    ros2_robots: tuple[int, ...] = ()  # driven from ROS 2: their commands come from the bridge


class World:
    """The world process of one run."""

    def __init__(self, sess: zenoh.Session, setup: WorldSetup, role: process_mod.Process, opts: Options) -> None:
        self.session = sess
        self.spool: Any = None  # a runtime.spool.SpoolWriter (main sets it): the commands taken, for wire.mcap
        self.logins: LoginWatch | None = None  # with logins, as the router: the sessions that close
        if opts.logins:
            self.logins = LoginWatch(sess, self._now, role.say)
            self.logins.listen()
        self.opts = opts
        self.keys = Keys(opts.run_id)
        self.role = role
        self.t0 = time.monotonic()  # wall clock of the loop's start, for the fault log
        self.tick = WorldTick(setup, opts.seed, lockstep=opts.mode == "lockstep", wall_s=self._wall_s)
        self.clock = CLOCKS[opts.mode](
            self.tick, self._drain, role.stop, deadline_s=setup.lockstep_deadline_s, thaw_s=role.peers_timeout_s
        )
        self.peers = Peers()
        self.waited_for: dict[str, Any] | None = None  # what the world gave up waiting for before tick 0
        self.inbox: Inbox | None = None
        self.out: Outbox | None = None
        self.end_reason = summary_mod.INTERRUPTED
        self.ended_at_s: float | None = None  # sim time when the run ended; None if it never started
        self.loop_wall_s = 0.0
        self.loop_cpu_s = 0.0  # CPU time of this process over the loop (all its threads)
        self.relief = FloodRelief()

    def _wall_s(self) -> float:
        """Wall seconds since the loop started (before: since the world started)."""
        return time.monotonic() - self.t0

    def _now(self) -> dict[str, Any]:
        eng = self.tick.engine
        return {"tick": eng.tick, "time_s": eng.time_s, "wall_s": self._wall_s()}

    def _drain(self, until: float) -> None:
        if self.inbox is not None:
            self.inbox.drain(until)

    def run(self) -> int:
        s, k = self.session, self.keys
        # A second world of the run (started twice by hand or by a service) would
        # step the same robots and say the run is its own: asked of the router first
        # (before our liveliness subscriber: with it, Zenoh 1.10 answered this query empty).
        replies = s.liveliness().get(k.alive("world", 0), timeout=process_mod.DUPLICATE_QUERY_S)
        if any(reply.ok is not None for reply in replies):
            self.role.complain(
                f"run {k.run_id!r} already has a world ({self.opts.where}); two worlds would both step its robots: "
                "not starting"
            )
            return process_mod.EXIT_DUPLICATE
        robots = self.tick.setup.robots
        window_s = 0.0 if self.opts.truth_every_tick else TRUTH_WINDOW_S
        self.out = Outbox.declare(
            s,
            k,
            robots,
            self.clock.truth_congestion,
            calls=self.opts.executor,
            truth_window_s=window_s,
            sightings=self.opts.expect_bridge,
        )
        self.inbox = inbox = Inbox(s, k, robots, self.tick.receive, self._on_alive, spool=self.spool)
        inbox.engine = self.tick.engine  # its tick: the sim time a command is spooled at
        self.role.stop.add_waker(inbox.wake)
        self.out.listen(inbox.wake)
        if self.logins is not None:
            self.logins.wake = lambda: inbox.notify(SESSION_CLOSED)
        s.liveliness().declare_subscriber(k.alive_any, inbox.alive_changed, history=True)
        token = s.liveliness().declare_token(k.alive("world", 0))
        try:
            return self._run(self.out)
        finally:
            inbox.close()
            token.undeclare()

    def _run(self, out: Outbox) -> int:
        stop = self.role.stop
        if not self._wait_ready(out):
            if stop.is_set():
                return stop.exit_code
            self.end_reason = summary_mod.PEERS_TIMEOUT
            return process_mod.EXIT_NO_PEERS
        tick, sc = self.tick, self.tick.setup
        out.status.put(tick.status("running").to_bytes())
        self.role.say(
            f"run {self.keys.run_id} started: {len(sc.robots)} agents"
            f"{' and the logger' if self.opts.expect_logger else ''} present; {self.clock.name}, "
            f"up to {sc.ticks} ticks of {sc.dt_s:g} s"
        )
        gc.freeze()  # start-up objects leave the collector's scans
        self.t0 = time.monotonic()
        cpu0 = time.process_time()
        code = self._loop(out)
        self.loop_wall_s = time.monotonic() - self.t0
        self.loop_cpu_s = time.process_time() - cpu0
        self.ended_at_s = tick.engine.time_s
        if code == 0:
            self.end_reason = summary_mod.LEADER_FINISHED if tick.leader_done else summary_mod.DURATION_REACHED
        self._send_truth()  # the last tick's
        out.truth.flush()  # before "done": the logger stops listening after it
        out.status.put(tick.finish().to_bytes())
        self._linger()
        return code

    def _linger(self) -> None:
        """Stay up (we may be the router) until the agents and the logger have left
        on "done", so that their last messages still get routed. Bounded: the
        agents LINGER_S, the logger LINGER_LOGGER_S."""
        start, logger = time.monotonic(), self.keys.alive("logger", 0)
        while not self.role.stop.is_set():
            now = time.monotonic()
            ends = [start + (LINGER_LOGGER_S if key == logger else LINGER_S) for key in self.peers.present]
            if not ends or now >= max(ends):
                return
            self._drain(until=max(ends))

    def _wait_ready(self, out: Outbox) -> bool:
        """Every agent's token (declared after its subscribers and after its
        command publisher matched us), every observation publisher matched and,
        if expected, the logger's token and the fault executor's (declared after
        its subscriber to the calls); until the role's peers deadline. A token
        or a matching change wakes the loop."""
        want, peers = set(self.tick.setup.robots), self.peers
        while not self.role.stop.is_set():
            self._drain(until=0.0)
            if (
                peers.agents_seen >= want
                and all(out.hears(rid) for rid in out.obs)
                and (peers.logger_seen or not self.opts.expect_logger)
                and (peers.bridge_seen or not self.opts.expect_bridge)
                and (peers.executor_seen or not self.opts.executor)
            ):
                return True
            if self.role.left_s() <= 0:
                self._give_up(want, out)
                return False
            self._drain(until=self.role.deadline)
        return False

    def _give_up(self, want: set[int], out: Outbox) -> None:
        peers, opts = self.peers, self.opts
        absent = sorted(want - peers.agents_seen)
        missing = waits.missed(
            absent,
            opts.ros2_robots,
            logger=opts.expect_logger and not peers.logger_seen,
            bridge=opts.expect_bridge and not peers.bridge_seen,
            executor=opts.executor and not peers.executor_seen,
        )
        if deaf := sorted(r for r in out.obs if r in peers.agents_seen and not out.hears(r)):
            missing.append(f"agents {', '.join(map(str, deaf))} present but not subscribed to their observations")
        said = " and ".join(missing)
        self.waited_for = {"robots": absent, "missing": said, "timeout_s": self.role.peers_timeout_s}
        self.role.gave_up(
            f"{said} in run {self.keys.run_id!r} ({self.opts.where}); "
            f"for the missing processes, {process_mod.CHECK_PEERS}"
        )

    def _on_alive(self, key: str, present: bool) -> None:
        if key == SESSION_CLOSED:
            self._lost_to_second_sessions()
            return
        parsed = self.keys.parse_alive(key)
        if parsed is None:
            return
        role, ident = parsed
        peers = self.peers
        if role in ("agent", "logger", "bridge"):  # after "done", the world stays until they have left
            (peers.present.add if present else peers.present.discard)(key)
        if role == "logger":
            peers.logger_seen = peers.logger_seen or present
            if not present and peers.logger_lost is None and not self.tick.finished:
                eng = self.tick.engine
                peers.logger_lost = {"tick": eng.tick, "time_s": eng.time_s, "wall_s": self._wall_s()}
        elif role == "launcher":
            peers.executor_seen = peers.executor_seen or present
        elif role == "bridge":
            peers.bridge_seen = peers.bridge_seen or present
        elif role == "agent" and ident.isdigit() and int(ident) in self.tick.engine.robots:
            rid = int(ident)
            if present:
                peers.agents_seen.add(rid)
            if lost := self.tick.agent_token(rid, present):
                print(f"world: {lost}", flush=True)

    def _lost_to_second_sessions(self) -> None:
        """After a session closed: a live robot whose token stays but whose
        observations lost their subscriber has lost its agent (nodes.world.sessions)."""
        out, present = self.out, self.peers.present
        if self.logins is None or out is None or self.tick.finished:
            return
        held = [r for r in self.tick.engine.alive_ids if self.keys.alive("agent", r) in present]
        for rid in self.logins.kept([r for r in held if not out.hears(r)]):
            if said := self.tick.agent_token(rid, False):
                print(f"world: {said}", flush=True)

    def _send_truth(self) -> None:
        if self.out is not None and (truth := self.tick.truth()) is not None:
            self.out.truth.put(truth.to_bytes())

    def _loop(self, out: Outbox) -> int:
        tick, clock, stop = self.tick, self.clock, self.role.stop
        clock.begin()
        while tick.running:
            if stop.is_set():
                return stop.exit_code
            now = clock.start_tick()
            tick.start(now - clock.started)
            self._process_faults(out)  # this tick's fault calls and returning agents, before its observations
            encoded = tick.encoded_observations()
            for rid, payload in encoded:
                out.obs[rid].put(payload)
            out.sighted(encoded)
            # While the agents work on this tick: the last tick's ground truth and metrics.
            self._send_truth()
            tick.record()
            clock.answers()
            if clock.status_due(now):
                out.status.put(tick.status("running").to_bytes())
            tick.close()
            clock.before_step(self._send_truth)
            tick.step()
            self.relief.check(tick.gate.rejections.total)  # a flood's memory, given back once it ends
        return 0

    def _process_faults(self, out: Outbox) -> None:
        """The fault calls of this tick, published before its observations and
        applied to the world; then the robots whose agent is back are re-admitted."""
        tick = self.tick
        for call in tick.calls_due():
            if out.faults is not None:
                out.faults.put(tick.call_message(call).to_bytes())
            if (rid := tick.apply_call(call)) is not None:
                self._await_fresh_agent(rid, call, out)
        self._readmit(out)
        if tick.awaited():
            self._hold_for_lost(out)

    def _readmit(self, out: Outbox) -> None:
        for rid in self.tick.readmit(out.hears):
            print(f"world: robot {rid} is back at t={self.tick.engine.time_s:.2f} s", flush=True)

    def _hold_for_lost(self, out: Outbox) -> None:
        """Lockstep: the clock holds at this tick's start while robots lost after
        a stall are awaited (world.stalls): until each is re-admitted or its
        wait (LOST_WAIT_S) ends."""
        tick, started = self.tick, time.monotonic()
        rids = ", ".join(map(str, tick.awaited()))
        print(f"world: holding the clock at t={tick.engine.time_s:.2f} s for robots {rids} to come back", flush=True)
        while tick.awaited() and not self.role.stop.is_set():
            self._drain(until=0.0)
            self._readmit(out)
            for line in tick.overdue():
                print(f"world: {line}", flush=True)
            if tick.awaited():
                self._drain(until=self.t0 + tick.stalls.until())
        tick.stalls.held_s += time.monotonic() - started

    def _await_fresh_agent(self, rid: int, call: Call, out: Outbox) -> None:
        """Lockstep, at a restart's "start": wait until the fresh agent's token is
        there and its observations are subscribed (bounded by --peers-timeout)."""
        timeout_s = self.role.peers_timeout_s
        deadline = time.monotonic() + timeout_s
        while not self.role.stop.is_set():
            self._drain(until=0.0)
            if self.tick.back(rid) and out.hears(rid):
                return
            if time.monotonic() >= deadline:
                self.tick.not_back(rid)
                print(
                    f"world: no fresh agent for robot {rid} within {timeout_s:g} s of its restart "
                    f"at t={self.tick.engine.time_s:.2f} s ('{call.fault}'); it stays stopped",
                    flush=True,
                )
                return
            self._drain(until=deadline)

    def stats(self, wall_s: float) -> dict[str, Any]:
        tick, clock = self.tick, self.clock
        out = tick.summary()
        out.update(
            {
                "mode": clock.name,
                "wall_time_s": wall_s,
                "loop_wall_time_s": self.loop_wall_s,
                "answer_wait_s": clock.wait_s,
                "ticks_per_s": tick.engine.tick / self.loop_wall_s if self.loop_wall_s > 0 else math.nan,
                "lockstep_misses": tick.misses,
                "robot_misses": tick.robot_misses.stats(),  # by robot: misses, by_faults, first_tick (world.misses)
                "late_answers": tick.late_answers,
                "duplicate_agents": {str(rid): n for rid, n in sorted(tick.duplicate_agents.items())},
                "late_ticks": clock.late_ticks,
                "wake_ups": 0 if self.inbox is None else self.inbox.wakes,
                "max_tick_lateness_s": clock.max_tick_lateness_s,
                "p99_tick_lateness_s": clock.p99_lateness_s(),
                "cpu_s": time.process_time(),  # the process's CPU time so far (user + system, all threads)
                "loop_cpu_s": self.loop_cpu_s,
                **tick.faults.stats(),  # deaths, fault_log, rejoins, recoveries
                "robot_digests": tick.robot_digests(),
                "logger_lost": self.peers.logger_lost,
                "waited_for": self.waited_for,  # what it gave up waiting for before tick 0 (None: it did not)
                "second_sessions": [] if self.logins is None else self.logins.records,
                "memory_given_back": self.relief.given_back,
                "stalls": tick.stalls.events,
                "held_for_lost_s": tick.stalls.held_s,
                "leader_done": tick.leader_done,
                "end_reason": self.end_reason,
                "ended_at_s": self.ended_at_s,
                "messages": dict(tick.counts),
                "cmd_links": tick.link_stats(),
                "rejected": tick.rejected(),
            }
        )
        return out
