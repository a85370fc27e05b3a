"""The logger process: the run's key space streamed to Rerun (formation_swarm.nodes.logger.recorder).

    swarm logger --scenario S.toml --run RUN --out recording.rrd [--live URL] [--serve-web]
                 [--wire-spool FILE] [--stats FILE] [--peers-timeout S] --connect ENDPOINT

The recording file is complete whatever live outputs are added: they are fed
by a second Rerun stream, which is never waited on while the run lasts
(formation_swarm.nodes.logger.recording.Recording).

It subscribes to the world's keys, every follower's telemetry and the leader's
codes (its switches, for the event log); with ``--wire-spool`` it appends each
to its spool (runtime.spool). It holds a token the world waits
for and watches the world's: it gives up when the world has not appeared within
``--peers-timeout`` and ends when the world says "done" or leaves.

Data is buffered and sent as columns every 0.25 s of wall time and the file
is flushed every 0.5 s; the file takes the rows in batches of 2 s of sim time
(10 s beyond a dozen robots: formation_swarm.nodes.logger.columns), which a
logger killed with SIGKILL loses.
"""

from __future__ import annotations

import contextlib
import math
import os
import queue
import sys
import threading
import time
from pathlib import Path
from typing import Any

import zenoh

from formation_swarm.nodes.logger.ledger import LoopCpu, Peers, TickLedger
from formation_swarm.nodes.logger.recorder import Recorder
from formation_swarm.nodes.logger.recording import open_recording
from formation_swarm.protocol import session
from formation_swarm.protocol.batch import pack_batch
from formation_swarm.protocol.codec import WORLD_ID, Rejections
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import FaultCall, FormationCode, Status, Telemetry, Truth
from formation_swarm.runtime import cliargs
from formation_swarm.runtime import process as process_mod
from formation_swarm.runtime import spool as spool_mod
from formation_swarm.runtime.memory import steady_collector
from formation_swarm.runtime.proc import exit_after_main, write_json
from formation_swarm.spec import scenario as scenario_mod

# Each send costs about 17 Rerun calls per robot up to a dozen robots; beyond,
# a few for the whole swarm, each robot's series going with the file's batches
# (formation_swarm.nodes.logger.crowd).
SEND_PERIOD_S = 0.25
FLUSH_PERIOD_S = 0.5
# After "done", at most this long for the followers' last telemetry: each one's
# end-of-stream mark, or its agent's leaving (a killed agent sends no mark).
# Long, for a machine that starves the logger (nice 10): what is still on its
# way when the logger closes is not recorded.
END_WAIT_S = 10.0
# How far past the run's last tick a message may be stamped: a follower's last
# telemetry may follow the world's "done" by a tick. Not a bound relative to the
# last truth taken: truth and telemetry travel in separate batches from separate
# processes, and on a loaded machine telemetry came 100+ ticks ahead of the truth
# the logger had taken (lockstep fig9, 91 of 880 ticks of a follower refused).
TICKS_PAST_END = 2
END_OF_STREAM = pack_batch([])  # what protocol.batch.BatchPublisher.close sends


class Logger:
    """The process loop: messages are queued as they arrive and handed to the
    Recorder, which sends them as Rerun columns, every SEND_PERIOD_S."""

    def __init__(
        self,
        sess: zenoh.Session,
        sc: scenario_mod.Scenario,
        run_id: str,
        recorder: Recorder,
        role: process_mod.Process,
        *,
        where: str = "",
        wire: spool_mod.SpoolWriter | None = None,
    ) -> None:
        self.session = sess
        self.sc = sc
        self.keys = Keys(run_id)
        self.recorder = recorder
        self.role = role
        self.stop = role.stop
        self.where = where  # the session's endpoints, for messages
        self.wake = threading.Event()  # set by a stop, the run's status, a stream's end or the world's token
        self.stop.add_waker(self.wake.set)
        self.wire = wire  # every message taken, spooled for wire.mcap (None: not recorded)
        self.inbox: queue.SimpleQueue[tuple[str, bytes, int]] = queue.SimpleQueue()
        self.rejections = Rejections()
        self.peers = Peers()
        self.counts = {"truth": 0, "telemetry": 0, "fault_calls": 0, "other": 0}
        self.started = False  # the run's first status or truth has been handled
        self.done = False
        self.ticks = TickLedger(sc.ticks + TICKS_PAST_END)  # per sender (WORLD_ID: truth), the ticks taken
        self.end_note = "not started"  # why the loop ended, for the last report line
        self.cpu = LoopCpu()
        self.send_period_s = SEND_PERIOD_S

    def _on_sample(self, sample: zenoh.Sample) -> None:
        key, payload = str(sample.key_expr), sample.payload.to_bytes()
        self.inbox.put((key, payload, time.time_ns()))  # received now: the wire recording's publish time
        if key == self.keys.status or payload == END_OF_STREAM:
            self.wake.set()  # the end of the run is handled at once, the rest per send

    def _on_agent_alive(self, sample: zenoh.Sample) -> None:
        rid = str(sample.key_expr).rpartition("/")[2]
        if rid.isdigit():
            self.peers.agent(int(rid), present=sample.kind == zenoh.SampleKind.PUT)
            self.wake.set()  # a follower gone sends no more telemetry: the end may be here

    def _on_world_alive(self, sample: zenoh.Sample) -> None:
        self.peers.world(present=sample.kind == zenoh.SampleKind.PUT)
        self.wake.set()

    def _subscribe(self) -> None:
        for key in (self.keys.world_all, self.keys.all_telemetry, self.keys.codes):
            self.session.declare_subscriber(key, self._on_sample)

    def run(self) -> int:
        s, k = self.session, self.keys
        self.recorder.log_static()
        self._subscribe()
        s.liveliness().declare_subscriber(k.alive("world", 0), self._on_world_alive, history=True)
        # Its token goes after its last telemetry (same link, in order): a follower
        # gone has nothing more on its way.
        s.liveliness().declare_subscriber(k.alive_all("agent"), self._on_agent_alive, history=True)
        steady_collector()  # start-up objects (numpy, scipy, zenoh) leave the collector's scans
        token = s.liveliness().declare_token(k.alive("logger", 0))
        last_send = last_flush = time.monotonic()
        cpu0 = time.process_time()
        try:
            # Messages are handled in one go per send, not as they come: the
            # logger then wakes 4 times a second instead of at every batch,
            # out of the way of the run's own processes. After "done", each
            # follower flushes its last telemetry and marks the end of its
            # stream: wait for those (bounded: a killed one never will), then
            # close the file. The world leaving ends it too: nothing more
            # can come (the world is usually the router).
            followers, end_by = set(self.sc.follower_ids), math.inf
            while (
                not self.stop.is_set()
                and not self.peers.world_gone
                and not (self.done and (self.peers.all_ended(followers) or time.monotonic() > end_by))
            ):
                if not self.peers.world_seen and self.role.left_s() <= 0:
                    self.end_note = "gave up waiting for the world"
                    return self.role.gave_up(
                        f"no world of run {self.keys.run_id!r} ({self.where}); {process_mod.CHECK_PEERS}"
                    )
                self.wake.wait(max(0.0, min(last_send + self.send_period_s, end_by) - time.monotonic()))
                self.wake.clear()
                t0 = time.thread_time()
                self._drain()
                self.cpu.drain_s += time.thread_time() - t0
                now = time.monotonic()
                if self.done and end_by == math.inf:
                    end_by = now + END_WAIT_S
                if now - last_send >= self.send_period_s:
                    t0 = time.thread_time()
                    self.recorder.send()
                    self.cpu.send_s += time.thread_time() - t0
                    last_send = now
                if now - last_flush >= FLUSH_PERIOD_S:
                    self.recorder.flush(timeout_s=0.2)
                    if self.wire is not None:
                        self.wire.flush()
                    last_flush = now
            # Handle what already arrived, then close the file properly.
            self._drain()
            self.recorder.send(final=True)
            self.recorder.flush(timeout_s=1.0)
        finally:
            self.cpu.loop_s = time.process_time() - cpu0
            token.undeclare()
        return self._exit_code()

    def _exit_code(self) -> int:
        code, self.end_note = self.role.follower_end(self.keys.run_id, self.done, self.started)
        return code

    def _drain(self) -> None:
        wire = self.wire
        while True:
            try:
                key, payload, received_ns = self.inbox.get_nowait()
            except queue.Empty:
                return
            self._handle(key, payload)
            if wire is not None:  # at the logger's sim time: the newest truth tick it has taken
                wire.add(key, payload, self.ticks.last.get(WORLD_ID), received_ns=received_ns)

    def _handle(self, key: str, payload: bytes) -> None:
        rk = self.keys.parse_robot(key)
        if key == self.keys.truth:
            truths = [t for t in self.rejections.decode_batch(Truth, payload, sender=WORLD_ID) or [] if self._fresh(t)]
            self.counts["truth"] += len(truths)
            self.recorder.add_truths(truths)
            self._start()
        elif rk is not None and rk.kind == "telemetry":
            tels = self.rejections.decode_batch(Telemetry, payload, sender=rk.robot_id)
            if tels == []:
                self.peers.ended.add(rk.robot_id)
            elif tels is not None:
                tels = [t for t in tels if self._fresh(t)]
                self.counts["telemetry"] += len(tels)
                self.recorder.add_telemetry(tels)
        elif key == self.keys.status:
            st = self.rejections.decode(Status, payload, sender=WORLD_ID)
            if st is not None:
                self._start()
                self.done = self.done or st.state == "done"
        elif key == self.keys.codes:
            code = self.rejections.decode(FormationCode, payload, sender=self.sc.leader.robot_id)
            if code is not None and not self.ticks.past_end(code.tick):
                self.recorder.add_leader_code(code)
        elif key == self.keys.faults:
            call = self.rejections.decode(FaultCall, payload, sender=WORLD_ID)
            if call is not None:
                self.counts["fault_calls"] += 1
                self.recorder.log_fault_call(call)
        else:
            self.counts["other"] += 1

    def _fresh(self, msg: Truth | Telemetry) -> bool:
        """A tick of the run the sender has not given yet, in any order
        (formation_swarm.nodes.logger.ledger.TickLedger); counts what is refused."""
        if self.ticks.past_end(msg.tick):
            self.rejections.reject("tick past the run's end")
            return False
        if not self.ticks.take(msg.sender, msg.tick):
            self.rejections.reject("replayed or reordered")
            return False
        return True

    def _start(self) -> None:
        if not self.started:
            self.started = True
            self.role.say(f"run {self.keys.run_id} started")

    def tick_stats(self) -> dict[str, dict[str, Any]]:
        """Per sender: the first and last tick taken, how many were missing between and where."""
        return self.ticks.stats()

    def stats(self) -> dict[str, Any]:
        recorded = self.recorder.stats()
        return {
            "wire": None if self.wire is None else self.wire.stats(),
            "messages": {**self.counts, **self.recorder.counts},
            "last_sim_time_s": recorded["last_sim_time_s"],
            "target_errors": recorded["target_errors"],
            "rejected": dict(self.rejections.by_reason),
            "ticks": self.tick_stats(),
            "cpu_s": time.process_time(),  # the process's CPU time so far (user + system, all threads)
            "loop_cpu_s": self.cpu.loop_s,  # of it, over the loop
            # Of the loop thread's CPU: taking messages apart and checking them; sending them to Rerun.
            "drain_cpu_s": self.cpu.drain_s,
            "send_cpu_s": self.cpu.send_s,
        }


DESCRIPTION = """\
Run the logger of one run by hand: it records the run to a Rerun file
(and, if asked, streams it to a viewer): the robots' true poses and
trajectories, each follower's measured, estimated and true target point,
V_N, wheel speeds and errors, and the formation changes, on the run's sim
time.

It connects, as a client, to the world or to the run's router, waits for
the world, and closes the recording when the world says the run is done or
leaves. Start it before the world's first tick (the world waits for it
with --expect-logger): what is sent before it is there is not recorded.

It prints one line when its session is open, one when the run starts and
one when it ends (why, and where the recording and its stats went); with
--serve-web, the address that opens the web viewer on the run; with --live,
whether a viewer answered there (one that does not is left out at once:
the recording goes on, never slowed by the viewer)."""


def build_parser() -> cliargs.Parser:
    ap = cliargs.Parser(
        prog="swarm logger",
        description=DESCRIPTION,
        epilog=process_mod.EXIT_CODES_HELP,
    )
    cliargs.add_run_arguments(ap, seeds=None, stats="the logger's counters")
    ap.add_argument("--out", required=True, metavar="FILE", help="the Rerun recording to write (.rrd)")
    spool_mod.add_arguments(ap)
    ap.add_argument(
        "--live", metavar="URL", help="also stream to a Rerun viewer, e.g. rerun+http://127.0.0.1:9876/proxy"
    )
    ap.add_argument("--serve-web", action="store_true", help="also serve the Rerun web viewer (see the two ports)")
    ap.add_argument(
        "--grpc-port", type=int, default=9876, metavar="PORT", help="--serve-web: the gRPC port (default 9876)"
    )
    ap.add_argument(
        "--web-port", type=int, default=9090, metavar="PORT", help="--serve-web: the web viewer's port (default 9090)"
    )
    ap.add_argument(
        "--nice",
        type=int,
        default=10,
        metavar="N",
        help="lower the logger's CPU priority by this much (default 10; 0 keeps it)",
    )
    process_mod.add_arguments(ap, waits_for="the world")
    session.add_arguments(ap, default_mode="client")
    return ap


def _serve(
    args: Any, sc: scenario_mod.Scenario, rec: Any, role: process_mod.Process, wire: spool_mod.SpoolWriter | None
) -> tuple[int, Logger] | int:
    """The logger's loop in its session: its exit code and the logger, or the code of a session that did not open."""
    sess_cm = role.connect(args, login="logger")
    if isinstance(sess_cm, int):
        return sess_cm
    where = process_mod.describe_session(args)
    with sess_cm as sess:
        role.say(
            f"{where}; run {args.run}: recording to {args.out}; waiting up to {role.peers_timeout_s:g} s for the world"
        )
        logger = Logger(sess, sc, args.run, Recorder(rec, sc), role, where=where, wire=wire)
        code = logger.run()
        write_json(args.stats, logger.stats())
    return code, logger


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    role = process_mod.Process("logger", args.peers_timeout)
    if args.nice:
        # Off the lockstep critical path: yield the cores to the world and the
        # agents; the logger buffers and catches up in their slack.
        with contextlib.suppress(OSError):
            os.nice(args.nice)
    sc = role.load(args)
    if isinstance(sc, int):
        return sc
    try:  # before connecting: a recording that cannot be written fails at once
        rec = open_recording(
            args.run, Path(args.out), sc, args.live, (args.grpc_port, args.web_port) if args.serve_web else None
        )
    except (OSError, RuntimeError) as exc:
        role.complain(f"cannot record to {args.out}: {exc}")
        return process_mod.EXIT_FAILED
    if rec.dropped:
        role.say(f"{rec.dropped}: not streaming there; the run is recorded to {args.out} only")
    if rec.web:
        role.say(f"web viewer: {rec.web}")
    try:
        wire = spool_mod.open_spool(args, role.complain)
    except OSError as exc:
        role.complain(f"cannot spool the wire to {args.wire_spool}: {exc}")
        rec.close()
        return process_mod.EXIT_FAILED
    try:
        served = _serve(args, sc, rec, role, wire)
    finally:
        if wire is not None:  # what it buffers, whatever ended the loop (a stop signal included)
            wire.close()
    if isinstance(served, int):
        return served
    code, logger = served
    delivered = rec.close()
    if code != process_mod.EXIT_NO_PEERS:
        written = f"stats in {args.stats}" if args.stats else "no --stats: counters not written"
        role.say(
            f"run {args.run} ended ({logger.end_note}), exit code {code}, {logger.counts['truth']} ticks "
            f"recorded in {args.out}; {written}"
        )
    if not delivered:
        # Rerun waits 5 s for a viewer that is not there when its stream is
        # dropped; the file is closed already: leave without waiting.
        role.say("the live viewer did not take the end of the run; leaving without it")
        sys.stdout.flush()
        sys.stderr.flush()
        os._exit(code)
    return code


if __name__ == "__main__":
    exit_after_main(main())
