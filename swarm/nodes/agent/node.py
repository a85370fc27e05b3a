"""One robot's agent process (``swarm agent``, nodes.agent.main): the thin process around its role.

The robot's decisions are its role's (agents.leader_role, agents.follower_role,
built by nodes.agent.setup): a follower turns each observation into wheel
speeds with its controller and obeys the formation codes its leader sends;
the leader flies its path and repeats the formation code to its followers.
This process owns the rest: the session, the subscribers and publishers
(nodes.agent.wire decodes what arrives for the role and publishes what it
answers), the liveliness tokens (nodes.agent.peers), the stats file
(nodes.agent.stats), a watchdog for a step that does not return
(nodes.agent.watch) and the waits at the start and the end.

The agent answers every observation it receives, even one its link layer
loses or holds back (then with the newest reading the link did hand over,
if any), so that lockstep never waits on a link fault (protocol.links).
Before it announces itself (its liveliness token) it waits, up to
``--peers-timeout``, for the world's token and for its command publisher to
match (the leader: also its code publisher, a follower's inbox), each such
change waking the wait. It exits when the world says the run is done, when
the world's token has been gone for ``--world-grace`` seconds (default: the
peers timeout) once the run started, or on SIGINT/SIGTERM; however it stops,
it then calls its controller's or policy's ``close()`` (agents.hooks). A dropped session
(a freeze beyond the Zenoh lease, a cut, a router restart) comes back by
itself: the client reconnects, declares the agent's subscribers and token
again, and the world re-admits the robot.

Observations and formation codes reach the loop through a Zenoh FIFO
channel read on the loop's own thread: no callback thread, no second queue
(~25% more ticks/s on the bare exchange). What would end the loop (the run's
end, the world's departure, a stop signal) closes that channel.
"""

from __future__ import annotations

import contextlib
import gc
import math
import os
import signal
import threading
import time
from dataclasses import dataclass
from typing import Any

import zenoh

from formation_swarm.agents.role_base import RoleBase
from formation_swarm.nodes.agent.hold import Hold
from formation_swarm.nodes.agent.peers import Peers
from formation_swarm.nodes.agent.stats import KEYS as STATS_KEYS
from formation_swarm.nodes.agent.stats import StatsFile
from formation_swarm.nodes.agent.watch import StepWatch
from formation_swarm.nodes.agent.wire import Outbox, Router
from formation_swarm.protocol.codec import Rejections
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import Status
from formation_swarm.runtime import process as process_mod
from formation_swarm.runtime import spool as spool_mod
from formation_swarm.runtime.memory import FloodRelief
from formation_swarm.runtime.proc import wait_for
from formation_swarm.spec import scenario as scenario_mod

# Lockstep holds at most a tick's observation and a few codes here; when full,
# Zenoh waits for the loop (back-pressure) rather than dropping. It bounds what
# a flood can make the agent hold: 256 messages of at most 40 KiB (the size filter).
INBOX_CAPACITY = 256
# After "done", a follower's longest wait for the logger to leave (its own
# wait for the followers' last telemetry, logger.END_WAIT_S, ends first).
LOGGER_WAIT_S = 12.0


@dataclass(frozen=True, kw_only=True)
class Options:
    """How the process runs, from its flags."""

    run_id: str
    where: str = ""  # the session's endpoints, for messages
    world_grace_s: float = math.inf  # how long a world lost mid-run is waited for
    stats_path: str | None = None
    # In lockstep the telemetry may hold back the run rather than be lost: a
    # dropped batch took up to 200 ticks out of the recording and its metrics.
    lockstep: bool = False
    wire_spool: str | None = None  # where to spool every message taken, for wire.mcap (runtime.spool)
    share: int = 1  # the robots whose agents share this process (nodes.agent.shared): its CPU time is split


class Agent:
    def __init__(
        self, sess: zenoh.Session, sc: scenario_mod.Scenario, brain: RoleBase, role: process_mod.Process, opts: Options
    ) -> None:
        self.session = sess
        self.sc = sc
        self.brain = brain  # the robot's decisions
        self.role = role  # the process's name, stop signals and deadline
        self.opts = opts
        self.keys = Keys(opts.run_id)
        self.spool = spool_mod.open_path(opts.wire_spool, opts.run_id, role.complain)
        self.router = Router(self.keys, brain, self.spool)
        self.peers = Peers(role.say, opts.world_grace_s, self._close_inbox)
        self.stats_file = StatsFile(opts.stats_path, len(sc.robots), (e for lk in brain.links for e in lk.fault_ends))
        self.status_rejections = Rejections()  # counted on the status callback's thread
        self.relief = FloodRelief()
        self.inbox: zenoh.Subscriber | None = None
        self._inbox_lock = threading.RLock()  # a stop signal may arrive while a callback closes it
        self.started = False  # a message of the run has arrived
        self.done = False
        self.end_note = "not started"  # why the loop ended, for the last report line
        self.busy_s = 0.0  # time handling messages in the loop, summed
        self.loop_cpu_s = 0.0  # CPU time of this process over the loop (all its threads)
        self.hold = Hold()  # a process shared by several robots freezes and kills one of them here

    # -- callbacks: short; they only set a flag and end the loop's wait ----------
    def _on_status(self, sample: zenoh.Sample) -> None:
        st = self.status_rejections.decode(Status, sample.payload.to_bytes())
        if st is not None and st.state == "done":
            self.done = True
            self._close_inbox()

    def _on_world_alive(self, sample: zenoh.Sample) -> None:
        self.peers.world(sample.kind == zenoh.SampleKind.PUT, started=self.started, done=self.done)

    def _on_logger_alive(self, sample: zenoh.Sample) -> None:
        self.peers.logger(sample.kind == zenoh.SampleKind.PUT)

    def _close_inbox(self) -> None:
        """End the loop: its ``recv`` raises once the messages already queued are read."""
        with self._inbox_lock, contextlib.suppress(zenoh.ZError):  # a stop may come after the session closed
            if self.inbox is not None:
                inbox, self.inbox = self.inbox, None
                inbox.undeclare()

    def run(self) -> int:
        """The agent's life: its start, its loop, its end; then its controller's
        or policy's ``close()`` (agents.hooks), whatever ended it."""
        try:
            return self._run()
        finally:
            if not self.killed:
                self.brain.close()  # a close that raises is a failure in the stats, its note in the log
            if self.brain.notes and not self.killed:
                self._say_notes()

    @property
    def killed(self) -> bool:
        return self.hold.killed

    def freeze(self, frozen: bool) -> None:
        """Pause (True) or resume the loop, as SIGSTOP and SIGCONT do a process of its own."""
        if frozen:
            self.hold.running.clear()
        else:
            self.brain.step_times.continued()
            self.hold.running.set()

    def kill(self) -> None:
        """End the robot as SIGKILL ends a process of its own: its loop ends and
        its token goes (the world sees it die), nothing more sent nor written.
        The loop's thread closes the session: two closes at once clash in Zenoh."""
        self.hold.killed = True
        self._close_inbox()
        self.hold.running.set()

    def _run(self) -> int:
        s, k, rid = self.session, self.keys, self.brain.robot_id
        self.inbox = s.declare_subscriber(
            k.inbox(rid), zenoh.handlers.FifoChannel(INBOX_CAPACITY), allowed_origin=zenoh.Locality.REMOTE
        )
        self.role.stop.add_waker(self._close_inbox)
        s.declare_subscriber(k.status, self._on_status)
        s.liveliness().declare_subscriber(k.alive("world", 0), self._on_world_alive, history=True)
        if self.brain.SENDS_TELEMETRY:  # it stays until the logger has its last telemetry (_await_logger)
            s.liveliness().declare_subscriber(k.alive("logger", 0), self._on_logger_alive, history=True)
        outbox = self._declare_outbox()
        # Announce ourselves only once the world can hear our commands.
        code = self._wait_matched(outbox)
        if code is not None:
            return code
        if self._already_flying():
            self.end_note = "another agent flies this robot"
            self.role.complain(
                f"robot {rid} already has an agent in run {k.run_id!r} ({self.opts.where}); "
                "two agents would both drive it: not starting"
            )
            return process_mod.EXIT_DUPLICATE
        gc.freeze()  # start-up objects (numpy, scipy, zenoh) leave the collector's scans
        token = s.liveliness().declare_token(k.alive("agent", rid))
        try:
            return self._loop(outbox)
        finally:
            self.peers.stop_waiting()
            if not self.killed:
                outbox.close()  # the logger waits for this end-of-stream mark
                self._await_logger()
            token.undeclare()

    def _declare_outbox(self) -> Outbox:
        """The publishers. Control messages are never dropped by Zenoh itself
        (only by our link layer); telemetry, for the logger only, travels in
        batches: in real time droppable (a stalled logger must not stall a
        robot), in lockstep not. One put per code reaches every follower: the
        router copies it to each inbox."""
        s, k, rid = self.session, self.keys, self.brain.robot_id
        block = zenoh.CongestionControl.BLOCK
        cmd = s.declare_publisher(k.cmd(rid), congestion_control=block)
        tel_cc = block if self.opts.lockstep else zenoh.CongestionControl.DROP
        tel = s.declare_publisher(k.telemetry(rid), congestion_control=tel_cc)
        codes = s.declare_publisher(k.codes, congestion_control=block) if self.brain.SENDS_CODES else None
        return Outbox(rid, len(self.sc.robots), cmd, tel, codes)

    def _await_logger(self) -> None:
        """After "done", until the logger has left (bounded, LOGGER_WAIT_S; not at
        all without a logger, or after a stop). The logger leaves once it holds
        every follower's end-of-stream mark, so then our telemetry has arrived
        whole. Leaving first could lose its last batches on their way (in one
        test suite, two runs lost their followers' last 5 and 11 ticks, with
        this process's kernel already emptied): most likely a process that
        exits with input unread resets its connection, and the router then
        drops what it had not yet read from it."""
        stop = self.role.stop
        if not (self.done and self.peers.logger_present) or stop.is_set():
            return
        stop.add_waker(self.peers.logger_left.set)
        if not wait_for(self.peers.logger_left, LOGGER_WAIT_S) and not stop.is_set():
            self.role.say(f"the logger was still there {LOGGER_WAIT_S:g} s after the run's end; leaving anyway")

    def _wait_matched(self, outbox: Outbox) -> int | None:
        """Until the world's token is seen and our command publisher matched and,
        for a leader with followers, its code publisher matched a follower's
        inbox; each change (or a stop) ends a wait. None when all are there,
        else the exit code. The token is what proves the world: our own inbox
        subscriber (robot/<id>/*) matches our command key too.

        The leader need not wait for every follower: the world starts the run
        only once it holds every agent's token, which an agent declares after
        its inbox, so the router knows every inbox before the first code."""
        changed, stop = self.peers.changed, self.role.stop
        stop.add_waker(changed.set)
        pubs = [outbox.cmd] + ([outbox.code] if outbox.code is not None else [])
        listeners = [p.declare_matching_listener(lambda _status: changed.set()) for p in pubs]
        try:
            while True:
                missing = self._missing_peers(outbox)
                if not missing:
                    return None
                if stop.is_set():
                    self.end_note = f"{self.role.stopped_by()} before the run started"
                    return stop.exit_code
                if self.role.left_s() <= 0:
                    self.end_note = "gave up waiting for its peers"
                    return self.role.gave_up(f"{' and '.join(missing)} ({self.opts.where}); {process_mod.CHECK_PEERS}")
                wait_for(changed, self.role.left_s())
                changed.clear()
        finally:
            for listener in listeners:
                listener.undeclare()

    def _missing_peers(self, outbox: Outbox) -> list[str]:
        """What the start still waits for, in words (none: nothing)."""
        missing = []
        if not (self.peers.world_seen and outbox.cmd.matching_status.matching):
            missing.append(f"no world of run {self.keys.run_id!r}")
        followers = self.sc.follower_ids
        if followers and not (outbox.code is None or outbox.code.matching_status.matching):
            missing.append(f"no agent for any of its followers ({', '.join(map(str, followers))})")
        return missing

    def _already_flying(self) -> bool:
        """Whether another process holds this robot's liveliness token (asked of
        the router, bounded: role.DUPLICATE_QUERY_S)."""
        key = self.keys.alive("agent", self.brain.robot_id)
        replies = self.session.liveliness().get(key, timeout=process_mod.DUPLICATE_QUERY_S)
        return any(reply.ok is not None for reply in replies)

    def _loop(self, outbox: Outbox) -> int:
        inbox = self.inbox
        if inbox is None:  # closed before we got here
            return self._exit_code()
        # The handler, not the subscriber: closing the subscriber from another
        # thread must not wait for this recv.
        channel = inbox.handler
        self.role.stop.add_waker(self.hold.running.set)  # a frozen robot hears a stop signal
        cpu0 = time.process_time()
        if threading.current_thread() is threading.main_thread():  # a freeze's SIGCONT: its step's time is no step's
            signal.signal(signal.SIGCONT, lambda _sig, _frame: self.brain.step_times.continued())
        try:
            with StepWatch(self.brain.step_times, self.stats_file, self):
                self._serve(channel, outbox)
        finally:
            self.loop_cpu_s = time.process_time() - cpu0
            if self.spool is not None:  # what it buffers, whatever ended the loop (a stop signal included)
                self.spool.close()
        return self._exit_code()

    def _serve(self, channel: Any, outbox: Outbox) -> None:
        stop, brain, take = self.role.stop, self.brain, self.router.take
        # The loop ends when recv raises, not on "done": what arrived before
        # "done" (the leader's code of the last tick, while we answered it) is
        # counted, so a run's link counts do not depend on when the status
        # callback ran.
        while not stop.is_set():
            try:
                sample = channel.recv()
            except zenoh.ZError:
                break  # closed by _close_inbox, once what was queued is read
            if not self.hold.running.is_set():
                self.hold.wait(channel)  # a freeze (nodes.agent.hold): a stop signal ends it too
            if self.killed:
                break
            if not self.started:
                self.started = True
                self.role.say(f"run {self.keys.run_id} started")
            t0 = time.perf_counter()
            # Everything that has arrived: codes in order, and only the newest
            # observation is answered (the role keeps it, with the newest reading).
            while sample is not None:
                take(str(sample.key_expr), sample.payload.to_bytes())
                try:
                    sample = self.hold.next(channel)  # what came while frozen first
                except zenoh.ZError:
                    sample = None  # closed by _close_inbox: answer what we have, then recv ends the loop
            if self.done:
                continue  # the run is over: counted, not answered
            answer = brain.answer()
            if answer is not None and not self.killed:
                outbox.send(answer)
                brain.prepare()
            noted = bool(brain.notes) and self._say_notes()
            self.busy_s += time.perf_counter() - t0
            self.stats_file.after(None if answer is None else answer.command.tick, self.stats, now=noted)
            self.relief.check(brain.rejections.total)  # a flood's memory, given back once it ends

    def over(self) -> bool:
        """Whether the run is over for this agent: the world said done, or a stop signal came."""
        return self.done or self.role.stop.is_set()

    def who(self) -> str:
        """What decides the robot's steps, for the log: "controller pkg.mod:Cls", "policy path"."""
        law = getattr(self.brain, "law", None)  # a follower's law, the leader's policy
        if not law:
            return f"the {self.brain.NAME}'s policy"
        return f"{'policy' if self.brain.SENDS_CODES else 'controller'} {law}"

    def complain(self, text: str) -> None:
        self.role.complain(text)

    def leave_hung(self, call: dict[str, Any]) -> None:
        """The run is over and ``call`` (nodes.agent.watch) has not returned:
        the controller hung. Say so, write the last stats with it, and end
        the process (on the watchdog's thread: the loop's is held by the call)."""
        self.end_note = f"{self.who()} hung in its {call['call']} of tick {call['tick']}"
        self.role.complain(
            f"{self.who()} hung: still in its {call['call']} of tick {call['tick']} after {call['for_s']:.1f} s, "
            "past the run's end; leaving without it"
        )
        ident = {"robot": self.brain.robot_id, "role": self.brain.NAME}
        self.stats_file.close({**ident, **(self.stats_file.last or {}), "in_step": {**call, "left": True}})
        code = process_mod.EXIT_HUNG
        self.role.say(f"run {self.keys.run_id} ended ({self.end_note}), exit code {code}")
        os._exit(code)

    def _say_notes(self) -> bool:
        """Print what the role noted (a controller's failure and its traceback,
        telemetry it cannot send) in this process's log; True."""
        for note in self.brain.notes:
            self.role.complain(note)
        self.brain.notes.clear()
        return True  # the stats file is written now: a failure is in it even if this process is killed next

    def _exit_code(self) -> int:
        code, self.end_note = self.role.follower_end(self.keys.run_id, self.done, self.started)
        return code

    def stats(self) -> dict[str, Any]:
        own = {
            "robot": self.brain.robot_id,
            "role": self.brain.NAME,
            "lockstep": self.opts.lockstep,  # its telemetry waits for the logger (lockstep) or may be dropped
            "busy_s": self.busy_s,
            # The process's CPU time (user + system, all threads), so far and over the loop; shared: its share.
            "cpu_s": time.process_time() / self.opts.share,
            "loop_cpu_s": self.loop_cpu_s / self.opts.share,
            "in_step": self.brain.step_times.in_call(),  # a call under way (nodes.agent.watch)
            "world_back_after_s": self.peers.world_back_after_s,  # per loss of the world's token mid-run (None: never)
            "rejected": dict(self.brain.rejections.by_reason + self.status_rejections.by_reason),
            "memory_given_back": self.relief.given_back,
        }
        both = {**self.brain.stats(), **own}
        return {key: both[key] for key in STATS_KEYS}
