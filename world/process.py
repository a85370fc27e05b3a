"""The world process: clock, physics and sensors of one run over Zenoh.

    swarm world --scenario S.toml --run RUN [--mode lockstep|realtime] [--seed N]
                [--stats FILE] [--expect-logger] [zenoh flags]

By default it is also the run's Zenoh router (``--zenoh-mode router --listen ...``):
agents and the logger connect to it as clients.

Lockstep: tick k is published to every live agent; tick k+1 starts when
every live agent has answered tick k, or when ``lockstep_deadline_s`` passes
(the miss is counted, that robot's command is not renewed). Real time: ticks
follow the wall clock at 1/dt Hz; the latest command is held; a robot whose
command is older than ``stale_after_s`` is stopped.

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
import sys
import threading
import time
from collections.abc import Callable
from typing import Any

import zenoh

from formation_swarm import scenario as scenario_mod
from formation_swarm.proc import StopEvent, install_stop_handlers, role_inputs, write_json
from formation_swarm.protocol import session
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.links import Link, link_name
from formation_swarm.protocol.messages import BatchPublisher, Command, Observation, Rejections, Status, Truth
from formation_swarm.world.engine import WorldEngine

STARTUP_TIMEOUT_S = 60.0
STATUS_PERIOD_S = 0.25
LINGER_S = 2.0  # after "done", at most this long for the others to leave
# Lockstep holds at most one command per robot here; when full, Zenoh waits
# for the loop (back-pressure) rather than dropping.
CMD_CAPACITY = 1024


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
        stop: StopEvent,
    ) -> None:
        self.session = sess
        self.sc = sc
        self.keys = Keys(run_id)
        self.mode = mode
        self.expect_logger = expect_logger
        self.stop = stop
        self.engine = WorldEngine(sc, seed)
        self.rejections = Rejections()
        # A sequence per stream (each robot's observations, truth, status): the number
        # an observation's link drop is decided on must not depend on how many status
        # messages the wall clock sent before it.
        self.seqs: collections.Counter[str] = collections.Counter()
        self.events: collections.deque[tuple[str, bool]] = collections.deque()  # liveliness, from its callback
        self.wakes = 0
        self.cmd_links = {rid: Link(link_name("cmd", rid, 0), sc.links.cmd_drop, seed) for rid in sc.robots}
        self.misses = 0
        self.late_answers = 0
        self.late_ticks = 0
        self.max_tick_lateness_s = 0.0
        self.agents_seen: set[int] = set()
        self.logger_seen = False
        self.present: set[str] = set()  # alive keys of the agents and the logger
        self.finished = False  # "done" sent: agents leaving now are not deaths
        self.deaths: list[dict[str, Any]] = []
        self.leader_done = False
        self.wall_s = 0.0
        self.loop_wall_s = 0.0
        self.wait_s = 0.0  # lockstep: time waiting for the agents' answers
        self.counts = {"obs_sent": 0, "cmd_received": 0, "truth_sent": 0}

    # -- Zenoh callback: short, hands the event to the loop and wakes it -------
    def _on_alive(self, sample: zenoh.Sample) -> None:
        self.events.append((str(sample.key_expr), sample.kind == zenoh.SampleKind.PUT))
        self._wake()

    def _wake(self) -> None:
        with contextlib.suppress(zenoh.ZError):  # a stop signal may come after the session closed
            self.wake_pub.put(b"")

    def run(self) -> int:
        s, k, sc = self.session, self.keys, self.sc
        block = zenoh.CongestionControl.BLOCK  # Zenoh never drops an observation; our link layer may
        obs_pubs = {rid: s.declare_publisher(k.obs(rid), congestion_control=block) for rid in sc.robots}
        truth_pub = BatchPublisher(s.declare_publisher(k.truth))  # for the logger only: batched
        status_pub = s.declare_publisher(k.status)
        self.wake_pub = s.declare_publisher(k.world_wake, congestion_control=block)
        self.cmds = s.declare_subscriber(k.all_cmd, zenoh.handlers.FifoChannel(CMD_CAPACITY))
        self.alarm = Alarm(self._wake)
        self.stop.add_waker(self._wake)
        s.liveliness().declare_subscriber(f"{k.prefix}/alive/*/*", self._on_alive, history=True)
        token = s.liveliness().declare_token(k.alive("world", 0))
        try:
            if not self._wait_ready(obs_pubs):
                return 2 if not self.stop.is_set() else 130
            self._publish_status(status_pub, "running")
            gc.freeze()  # start-up objects leave the collector's scans
            t0 = time.monotonic()
            code = self._loop(obs_pubs, truth_pub, status_pub)
            self.loop_wall_s = time.monotonic() - t0
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
        on "done", so that their last messages still get routed. Bounded."""
        end = time.monotonic() + LINGER_S
        while self.present and not self.stop.is_set() and time.monotonic() < end:
            self._drain(until=end)

    def _wait_ready(self, obs_pubs: dict[int, zenoh.Publisher]) -> bool:
        """Every agent's token (declared after its subscribers and after its
        command publisher matched us) and every observation publisher matched."""
        deadline = time.monotonic() + STARTUP_TIMEOUT_S
        want = set(self.sc.robots)
        while not self.stop.is_set():
            self._drain(until=time.monotonic() + 0.05)  # matching status changes wake nobody: look again
            matched = all(p.matching_status.matching for p in obs_pubs.values())
            if self.agents_seen >= want and matched and (self.logger_seen or not self.expect_logger):
                return True
            if time.monotonic() > deadline:
                missing = sorted(want - self.agents_seen)
                print(
                    f"world: gave up after {STARTUP_TIMEOUT_S:.0f} s waiting for agents {missing}"
                    + ("" if self.logger_seen or not self.expect_logger else " and the logger"),
                    file=sys.stderr,
                )
                return False
        return False

    def _next_seq(self, stream: str) -> int:
        self.seqs[stream] += 1
        return self.seqs[stream]

    def _publish_status(self, pub: zenoh.Publisher, state: str) -> None:
        seq = self._next_seq("status")
        pub.put(Status(0, seq, self.engine.tick, self.engine.time_s, state, self.sc.ticks).to_bytes())

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
        if key == self.keys.world_wake:
            self.wakes += 1
            return
        rk = self.keys.parse_robot(key)
        if rk is None or rk.robot_id not in self.engine.robots:
            self.rejections.reject("unknown robot")
            return
        msg = self.rejections.decode(Command, sample.payload.to_bytes(), sender=rk.robot_id)
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
        elif role == "agent" and ident.isdigit() and int(ident) in self.engine.robots:
            rid = int(ident)
            if present:
                self.agents_seen.add(rid)
            elif self.engine.robots[rid].alive and not self.finished:
                self.engine.kill(rid)
                self.deaths.append({"robot": rid, "tick": self.engine.tick, "time_s": self.engine.time_s,
                                    "pose": list(self.engine.robots[rid].pose)})  # fmt: skip
                print(f"world: robot {rid} lost its agent at t={self.engine.time_s:.2f} s; stopped", flush=True)

    def _on_command(self, msg: Command) -> None:
        eng = self.engine
        r = eng.robots[msg.sender]
        self.counts["cmd_received"] += 1
        if self.mode == "lockstep" and msg.tick != eng.tick:
            self.late_answers += 1
            return
        r.answered = True
        if msg.done and msg.sender == self.sc.leader.robot_id:
            self.leader_done = True
        if not self.cmd_links[msg.sender].accept(msg.seq):
            return
        if not r.alive:
            return
        now = eng.time_s if self.mode == "lockstep" else self.wall_s
        eng.set_command(msg.sender, msg.left_mps, msg.right_mps, msg.formation, now)

    def _publish_tick(self, obs_pubs: dict[int, zenoh.Publisher], truth_pub: BatchPublisher) -> None:
        eng = self.engine
        tick, t = eng.tick, eng.time_s
        for rid in eng.alive_ids:
            eng.robots[rid].answered = False
            pose, readings, obstacles = eng.observation(rid)
            seq = self._next_seq(link_name("obs", 0, rid))
            obs_pubs[rid].put(Observation(0, seq, tick, t, pose, tuple(readings), tuple(obstacles)).to_bytes())
            self.counts["obs_sent"] += 1
        robots = tuple((rid, *r.pose, r.alive) for rid, r in eng.robots.items())
        targets = tuple((rid, *eng.true_target(rid)) for rid in self.sc.follower_ids)
        truth_pub.put(Truth(0, self._next_seq("truth"), tick, t, robots, targets).to_bytes())
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
                return 130
            tick_start = start + eng.tick * period
            now = time.monotonic()
            if self.mode == "realtime":
                # Wait for this tick's time, handling commands meanwhile.
                while now < tick_start and not self.stop.is_set():
                    self._drain(until=tick_start)
                    now = time.monotonic()
                lateness = now - tick_start
                self.max_tick_lateness_s = max(self.max_tick_lateness_s, lateness)
                if lateness > 0.5 * period:
                    self.late_ticks += 1
                self.wall_s = now - start
            self._publish_tick(obs_pubs, truth_pub)
            eng.record()  # the last tick's metrics, while the agents work on this one
            if self.mode == "lockstep":
                t_wait = time.perf_counter()
                deadline = time.monotonic() + sc.lockstep_deadline_s
                while not self.stop.is_set():
                    waiting = [rid for rid in eng.alive_ids if not eng.robots[rid].answered]
                    if not waiting:
                        break
                    if time.monotonic() >= deadline:
                        self.misses += len(waiting)
                        for rid in waiting:
                            eng.robots[rid].command = (0.0, 0.0)  # missed: stopped this tick
                        break
                    self._drain(until=deadline)
                self.wait_s += time.perf_counter() - t_wait
            else:
                self._drain(until=0.0)
            if self.mode == "realtime" or now >= next_status:
                self._publish_status(status_pub, "running")
                next_status = now + STATUS_PERIOD_S
            eng.step(eng.time_s if self.mode == "lockstep" else self.wall_s)
        return 0

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
                "deaths": self.deaths,
                "leader_done": self.leader_done,
                "messages": dict(self.counts),
                "cmd_links": {
                    lk.name: {"received": lk.received, "dropped": lk.dropped} for lk in self.cmd_links.values()
                },
                "rejected": dict(self.rejections.by_reason),
            }
        )
        return out


def build_parser() -> argparse.ArgumentParser:
    ap = argparse.ArgumentParser(
        prog="swarm world", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    ap.add_argument("--scenario", required=True)
    ap.add_argument("--run", required=True, help="run id: the first segment of every key")
    ap.add_argument("--mode", choices=("lockstep", "realtime"), default="lockstep")
    ap.add_argument("--seed", type=int, default=None, help="overrides the scenario's seed")
    ap.add_argument("--stats", help="write the world's metrics (JSON) here at the end")
    ap.add_argument("--expect-logger", action="store_true", help="wait for the logger before tick 0")
    session.add_arguments(ap, default_mode="router")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    stop = install_stop_handlers()
    started = time.monotonic()
    inputs = role_inputs(args, "world")
    if inputs is None:
        return 2
    sc, sess_cm = inputs
    seed = sc.seed if args.seed is None else args.seed
    with sess_cm as sess:
        world = World(sess, sc, args.run, seed, args.mode, args.expect_logger, stop)
        code = world.run()
        wall = time.monotonic() - started
        stats = world.stats(wall)
        stats["exit_code"] = code
        write_json(args.stats, stats)
    return code


if __name__ == "__main__":
    sys.exit(main())
