"""One robot's agent process: its brain on the run's Zenoh key space.

    swarm agent --id N --scenario S.toml --run RUN [--seed N] [--stats FILE] [--peers-timeout S]
                [--world-grace S] --connect ENDPOINT

A follower turns each observation into wheel speeds with the paper's
controller (agents.follower) and obeys the formation codes its leader sends.
The leader flies its scripted path, watches for obstacles and repeats the
formation code to its followers, one put for all of them (each follower's
end of its one-way link applies that link's faults): every tick for
``leader.code_burst_s`` after a change, then every ``leader.code_period_s``
(agents.leader.CodeRepeats).

The agent answers every observation it receives, even one its link layer
loses or holds back (then with the newest reading the link did hand over,
if any), so that lockstep never waits on a link fault (protocol.links).
Before it announces itself (its liveliness token) it waits, up to
``--peers-timeout``, for the world's token and for its command publisher to
match (the leader: also its code publisher, a follower's inbox), each such
change waking the wait. It exits when the world says the run is done, when
the world's token has been gone for ``--world-grace`` seconds (default: the
peers timeout) once the run started, or on SIGINT/SIGTERM. A session the
router dropped (the agent frozen beyond the Zenoh lease, a network cut, a
router restart) comes back by itself: the Zenoh client reconnects and
declares the agent's subscribers and token again (measured with Zenoh 1.10),
the world's token returns, and the world re-admits the robot.

Observations and formation codes reach the loop through a Zenoh FIFO
channel, received on the loop's own thread: no Python callback thread and no
second queue between the network and the controller (measured on the bare
exchange: ~25% more ticks/s than callback + queue). What would end the loop
(the run's end, the world's departure, a stop signal) closes that channel.
"""

from __future__ import annotations

import collections
import contextlib
import gc
import math
import threading
import time
from typing import Any

import zenoh

from formation_swarm.agents.follower import Decision, Follower
from formation_swarm.agents.inbox import InboxChecks
from formation_swarm.agents.leader import CodeRepeats, FormationSwitch
from formation_swarm.agents.pilot import PathPilot
from formation_swarm.protocol import session, trust
from formation_swarm.protocol.batch import BatchPublisher
from formation_swarm.protocol.codec import Rejections
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.links import COUNTS_FINAL_AFTER_TICKS, Link, faults_on, link_name
from formation_swarm.protocol.messages import Command, FormationCode, Observation, Status, Telemetry
from formation_swarm.runtime import cliargs
from formation_swarm.runtime import role as role_mod
from formation_swarm.runtime.proc import SEND_DRAIN_S, JsonWriter, exit_after_main, wait_for, wait_sent
from formation_swarm.spec import scenario as scenario_mod
from formation_swarm.world.kinematics import Pose

WORLD_ID = 0
# Lockstep holds at most a tick's observation and a few codes here; when full,
# Zenoh waits for the loop (back-pressure) rather than dropping.
INBOX_CAPACITY = 1024
# After "done", a follower's longest wait for the logger to leave (its own
# wait for the followers' last telemetry, logger.END_WAIT_S, ends first).
LOGGER_WAIT_S = 12.0
# Wall time between two writes of the counters while the run goes on: one
# write (JSON, then a rename over the old file) costs 0.3-1 ms of CPU here, so
# beyond 25 robots it is spaced out to STATS_S_PER_ROBOT per robot (4 s for 100).
STATS_PERIOD_S = 1.0
STATS_S_PER_ROBOT = 0.04
# Telemetry is for the logger only. Up to TELEMETRY_BATCH_ABOVE robots each
# tick's goes out at once (protocol.batch's 20 ms window); beyond, a follower
# sends every TELEMETRY_TICKS ticks, on a tick set by its id so that the
# followers' sends spread over the ticks: every tick's telemetry is still sent,
# in a fifth of the puts (each one routed by the router and taken by the logger).
TELEMETRY_BATCH_ABOVE = 25
TELEMETRY_TICKS = 5
TELEMETRY_WINDOW_S = 0.02
PENDING_CODES = 64  # formation codes waiting for their tick
MAX_HOLDS = 100  # holds listed in a follower's stats (all are counted in held_ticks)


class Agent:
    def __init__(
        self,
        sess: zenoh.Session,
        sc: scenario_mod.Scenario,
        rid: int,
        run_id: str,
        seed: int,
        role: role_mod.Role,
        where: str = "",
        world_grace_s: float = math.inf,
        stats_path: str | None = None,
        lockstep: bool = False,
    ) -> None:
        # The counters go to stats_path at exit and every STATS_PERIOD_S meanwhile, so
        # a SIGKILLed agent (a kill or restart fault) leaves what it counted until then.
        self.stats_path = stats_path
        # In lockstep the telemetry may hold back the run rather than be lost: a
        # dropped batch took up to 200 ticks out of the recording and its metrics.
        self.lockstep = lockstep
        self.stats_written_at = time.monotonic()
        self.stats_writer = JsonWriter(stats_path, name="stats-writer")
        self.stats_period_s = max(STATS_PERIOD_S, STATS_S_PER_ROBOT * len(sc.robots))
        if rid not in sc.robots:
            raise ValueError(f"--id {rid} is not a robot of this scenario; robots are {list(sc.robots)}")
        self.session = sess
        self.sc = sc
        self.rid = rid
        self.keys = Keys(run_id)
        self.codes_key = self.keys.codes  # compared with every inbox message's key: built once
        self.role = role
        self.stop = role.stop
        self.where = where  # the session's endpoints, for messages
        self.is_leader = rid == sc.leader.robot_id
        self.tel_every = 1 if len(sc.robots) <= TELEMETRY_BATCH_ABOVE else TELEMETRY_TICKS  # ticks per telemetry put
        self.rejections = Rejections()
        self.status_rejections = Rejections()  # counted on the status callback's thread
        self.inbox: zenoh.Subscriber | None = None
        self._inbox_lock = threading.RLock()  # a stop signal may arrive while a callback closes it
        self.seq = 0
        self.code = sc.code_of(sc.leader.formation)
        # The receiving ends of our links, with the faults the run's schedule puts on them.
        self.obs_link: Link[Observation] = Link(
            link_name("obs", WORLD_ID, rid), sc.links.obs_drop, seed, faults_on(sc.faults, "obs", rid), sc.dt_s
        )
        self.formation_link: Link[FormationCode] = Link(
            link_name("formation", sc.leader.robot_id, rid),
            sc.links.formation_drop,
            seed,
            faults_on(sc.faults, "formation", rid),
            sc.dt_s,
        )
        # A link fault's counts are final a little after its window ends: the stats
        # are written then, so an agent a later fault kills leaves them whole.
        self.stats_at_ticks = collections.deque(
            sorted(
                {end + COUNTS_FINAL_AFTER_TICKS for lk in (self.obs_link, self.formation_link) for end in lk.fault_ends}
            )
        )
        self.world_seen = False
        self.world_gone = False
        self.world_grace_s = world_grace_s  # how long a world lost mid-run is waited for
        self.world_lost: threading.Timer | None = None  # running while the world's token is away
        self.world_lost_at = 0.0
        self.world_back_after_s: list[float | None] = []  # per loss of the world: how long it was away
        self.peers_changed = threading.Event()  # a matching change, the world's token or a stop
        self.logger_present = False  # the run's logger holds its token
        self.logger_left = threading.Event()  # ... and has undeclared it (or a stop came)
        self.started = False  # a message of the run has arrived
        self.done = False
        self.end_note = "not started"  # why the loop ended, for the last report line
        self.answered = 0
        self.answered_tick: int | None = None  # the tick of the last observation a follower answered
        self.last_tick: int | None = None  # the tick of the last observation answered, leader or follower
        self.busy_s = 0.0  # time handling messages in the loop, summed
        self.loop_cpu_s = 0.0  # CPU time of this process over the loop (all its threads)
        self.formation_changes: list[dict[str, Any]] = []
        # Codes taken, each with the tick it is stamped with or, if the link held it, released at.
        self.pending_codes: collections.deque[tuple[int, FormationCode]] = collections.deque(maxlen=PENDING_CODES)
        self.checks = InboxChecks(
            sc.robots, sc.camera.range_m, sc.camera.sigma_rho_m, sc.leader.sensing_range_m, sc.dt_s
        )
        self.superseded = 0  # observations skipped because a newer one was already there
        # The follower's holds at a standing reference: ticks held, and [first, last] tick of each hold.
        self.held_ticks = 0
        self.waited_ticks = 0  # ticks stopped ahead of its target (controller.wait_ahead)
        self.holds: list[list[int]] = []
        self._hold_span: list[int] | None = None  # the hold under way, if it is recorded
        if self.is_leader:
            ld = sc.leader
            self.pilot = PathPilot(
                ld.waypoints, ld.speed_mps, sc.width_m, ld.lookahead_m, ld.turn_rate_rps, corners=ld.corners
            )
            avoid = None if ld.avoid_formation is None else sc.code_of(ld.avoid_formation)
            self.switch = FormationSwitch(self.code, avoid, ld.clear_after_s, sc.dt_s)
            self.repeats = CodeRepeats(ld.code_burst_s, ld.code_period_s, sc.dt_s)
            self.last_cmd = (0.0, 0.0)
        else:
            slot = sc.formation_by_code(self.code).slots[rid]
            self.reference = slot.reference
            self.follower = Follower(sc.followers[rid], slot.offset)

    # -- callbacks: short; they only set a flag and end the loop's wait ----------
    def _on_status(self, sample: zenoh.Sample) -> None:
        st = self.status_rejections.decode(Status, sample.payload.to_bytes())
        if st is not None and st.state == "done":
            self.done = True
            self._close_inbox()

    def _on_world_alive(self, sample: zenoh.Sample) -> None:
        if sample.kind == zenoh.SampleKind.PUT:
            self.world_seen = True
            self.peers_changed.set()
            if self.world_lost is not None:  # back: our session was dropped and regained
                self.world_lost.cancel()
                self.world_lost = None
                self.world_back_after_s[-1] = away = time.monotonic() - self.world_lost_at
                self.role.say(f"the world is back after {away:.2f} s")
        elif self.done:
            pass  # the run is over: the world leaves after "done", as it should
        elif self.world_seen and self.started and self.world_lost is None and not self.world_gone:
            # Mid-run: the world, or only our session to it, may come back.
            self.world_lost_at = time.monotonic()
            self.world_back_after_s.append(None)
            self.role.say(f"lost the world; waiting up to {self.world_grace_s:g} s for it to come back")
            self.world_lost = threading.Timer(self.world_grace_s, self._world_left)
            self.world_lost.daemon = True
            self.world_lost.start()
        elif self.world_seen and not self.started:
            self._world_left()  # before the run: the world gave up

    def _world_left(self) -> None:
        self.world_gone = True
        self._close_inbox()

    def _close_inbox(self) -> None:
        """End the loop: its ``recv`` raises once the messages already queued are read."""
        with self._inbox_lock, contextlib.suppress(zenoh.ZError):  # a stop may come after the session closed
            if self.inbox is not None:
                inbox, self.inbox = self.inbox, None
                inbox.undeclare()

    def run(self) -> int:
        s, k = self.session, self.keys
        self.inbox = s.declare_subscriber(
            k.inbox(self.rid), zenoh.handlers.FifoChannel(INBOX_CAPACITY), allowed_origin=zenoh.Locality.REMOTE
        )
        self.stop.add_waker(self._close_inbox)
        s.declare_subscriber(k.status, self._on_status)
        s.liveliness().declare_subscriber(k.alive("world", 0), self._on_world_alive, history=True)
        if not self.is_leader:  # a follower stays until the logger has its last telemetry (_await_logger)
            s.liveliness().declare_subscriber(k.alive("logger", 0), self._on_logger_alive, history=True)
        # Control messages are never dropped by Zenoh itself (only by our link
        # layer); telemetry, for the logger only, travels in batches: in real
        # time droppable (a stalled logger must not stall a robot), in lockstep not.
        block = zenoh.CongestionControl.BLOCK
        self.cmd_pub = s.declare_publisher(k.cmd(self.rid), congestion_control=block)
        tel_cc = block if self.lockstep else zenoh.CongestionControl.DROP
        self.tel_pub = self.telemetry_publisher(s.declare_publisher(k.telemetry(self.rid), congestion_control=tel_cc))
        # One put per code reaches every follower: the router copies it to each inbox.
        self.code_pub = s.declare_publisher(k.codes, congestion_control=block) if self.is_leader else None
        # Announce ourselves only once the world can hear our commands.
        code = self._wait_matched()
        if code is not None:
            return code
        if self._already_flying():
            self.end_note = "another agent flies this robot"
            self.role.complain(
                f"robot {self.rid} already has an agent in run {self.keys.run_id!r} ({self.where}); "
                "two agents would both drive it: not starting"
            )
            return role_mod.EXIT_DUPLICATE
        gc.freeze()  # start-up objects (numpy, scipy, zenoh) leave the collector's scans
        token = s.liveliness().declare_token(k.alive("agent", self.rid))
        try:
            return self._loop()
        finally:
            if self.world_lost is not None:
                self.world_lost.cancel()
            self.tel_pub.close()  # the logger waits for this end-of-stream mark
            self._await_logger()
            token.undeclare()

    def _on_logger_alive(self, sample: zenoh.Sample) -> None:
        self.logger_present = sample.kind == zenoh.SampleKind.PUT
        if not self.logger_present:
            self.logger_left.set()

    def _await_logger(self) -> None:
        """After "done", until the logger has left (bounded, LOGGER_WAIT_S; not at
        all without a logger, or after a stop). The logger leaves once it holds
        every follower's end-of-stream mark, so then our telemetry has arrived
        whole. Leaving first could lose its last batches on their way (in one
        test suite, two runs lost their followers' last 5 and 11 ticks, with
        this process's kernel already emptied): most likely a process that
        exits with input unread resets its connection, and the router then
        drops what it had not yet read from it."""
        if not (self.done and self.logger_present) or self.stop.is_set():
            return
        self.stop.add_waker(self.logger_left.set)
        if not wait_for(self.logger_left, LOGGER_WAIT_S) and not self.stop.is_set():
            self.role.say(f"the logger was still there {LOGGER_WAIT_S:g} s after the run's end; leaving anyway")

    def telemetry_publisher(self, pub: Any) -> BatchPublisher:
        """The telemetry's batches onto ``pub``: by wall time (every tick at
        20 Hz), or, beyond TELEMETRY_BATCH_ABOVE robots, flushed by tick (in _follow)."""
        return BatchPublisher(pub, window_s=TELEMETRY_WINDOW_S if self.tel_every == 1 else math.inf)

    def _wait_matched(self) -> int | None:
        """Until the world's token is seen and our command publisher matched and,
        for a leader with followers, its code publisher matched a follower's
        inbox; each change (or a stop) ends a wait. None when all are there,
        else the exit code. The token is what proves the world: our own inbox
        subscriber (robot/<id>/*) matches our command key too.

        The leader need not wait for every follower: the world starts the run
        only once it holds every agent's token, which an agent declares after
        its inbox, so the router knows every inbox before the first code."""
        changed = self.peers_changed
        self.stop.add_waker(changed.set)
        pubs = [self.cmd_pub] + ([self.code_pub] if self.code_pub is not None else [])
        listeners = [p.declare_matching_listener(lambda _status: changed.set()) for p in pubs]
        try:
            while True:
                no_world = not (self.world_seen and self.cmd_pub.matching_status.matching)
                no_followers = bool(self.sc.follower_ids) and not (
                    self.code_pub is None or self.code_pub.matching_status.matching
                )
                if not no_world and not no_followers:
                    return None
                if self.stop.is_set():
                    self.end_note = f"{self.role.stopped_by()} before the run started"
                    return self.stop.exit_code
                if self.role.left_s() <= 0:
                    missing = [f"no world of run {self.keys.run_id!r}"] if no_world else []
                    if no_followers:
                        followers = self.sc.follower_ids
                        missing.append(f"no agent for any of its followers ({', '.join(map(str, followers))})")
                    self.end_note = "gave up waiting for its peers"
                    return self.role.gave_up(f"{' and '.join(missing)} ({self.where}); check --run and --connect")
                wait_for(changed, self.role.left_s())
                changed.clear()
        finally:
            for listener in listeners:
                listener.undeclare()

    def _already_flying(self) -> bool:
        """Whether another process holds this robot's liveliness token (asked of
        the router, bounded: role.DUPLICATE_QUERY_S)."""
        replies = self.session.liveliness().get(self.keys.alive("agent", self.rid), timeout=role_mod.DUPLICATE_QUERY_S)
        return any(reply.ok is not None for reply in replies)

    def _loop(self) -> int:
        inbox = self.inbox
        if inbox is None:  # closed before we got here
            return self._exit_code()
        # The handler, not the subscriber: closing the subscriber from another
        # thread must not wait for this recv.
        channel = inbox.handler
        cpu0 = time.process_time()
        try:
            self._serve(channel)
        finally:
            self.loop_cpu_s = time.process_time() - cpu0
        return self._exit_code()

    def _serve(self, channel: Any) -> None:
        while not self.stop.is_set() and not self.done:
            try:
                sample = channel.recv()
            except zenoh.ZError:
                break  # closed by _close_inbox
            if not self.started:
                self.started = True
                self.role.say(f"run {self.keys.run_id} started")
            t0 = time.perf_counter()
            # Everything that has arrived: codes in order, and only the newest
            # observation is answered (after a stall, the older ones are stale),
            # with the newest reading the observation link has handed over.
            newest = reading = None
            while sample is not None:
                got = self._on_message(str(sample.key_expr), sample.payload.to_bytes())
                if got is not None:
                    self.superseded += newest is not None
                    newest = got[0]
                    reading = got[1] if got[1] is not None else reading
                try:
                    sample = channel.try_recv()
                except zenoh.ZError:
                    sample = None  # closed by _close_inbox: answer what we have, then recv ends the loop
            if newest is not None:
                self._on_observation(newest, reading)
            self.busy_s += time.perf_counter() - t0
            fault_over = False
            while newest is not None and self.stats_at_ticks and self.stats_at_ticks[0] <= newest.tick:
                self.stats_at_ticks.popleft()
                fault_over = True
            if self.stats_path and (fault_over or time.monotonic() - self.stats_written_at >= self.stats_period_s):
                self.stats_writer.offer(self.stats())  # written by its own thread: a slow disk stalls no tick
                self.stats_written_at = time.monotonic()

    def _exit_code(self) -> int:
        code, self.end_note = self.role.follower_end(self.keys.run_id, self.done, self.started)
        return code

    def _on_message(self, key: str, payload: bytes) -> tuple[Observation, Observation | None] | None:
        """Take a formation code; return an observation for the loop to answer,
        with the newest observation its link handed over (None: no reading:
        lost, held, or only replays). Anything else is counted and dropped.

        What arrives is checked first (a message that could not be true is
        neither answered nor given to the link layer); what the link layer
        hands over is checked again for order (a duplicate or a message it
        held back behind a newer one is "replayed or reordered")."""
        if key == self.codes_key:
            if self.is_leader:
                self.rejections.reject("unexpected key")
            else:
                self._on_code(payload)
            return None
        rk = self.keys.parse_robot(key)
        if rk is None or rk.robot_id != self.rid:
            self.rejections.reject("unknown key")
            return None
        if rk.kind == "obs":
            msg = self.rejections.decode(Observation, payload, sender=WORLD_ID)
            if msg is not None:
                if (why := self.checks.observation(msg)) is not None:
                    self.rejections.reject(why)
                    return None
                if not self.is_leader:  # codes the formation link held until this tick
                    self._take_codes(self.formation_link.due(msg.tick), msg.tick)
                reading = None
                for got in self.obs_link.deliver(msg.seq, msg.tick, msg):
                    if (why := self.checks.reading(got)) is not None:
                        self.rejections.reject(why)
                    else:
                        reading = got
                return msg, reading
        else:
            self.rejections.reject("unexpected key")
        return None

    def _on_code(self, payload: bytes) -> None:
        fc = self.rejections.decode(FormationCode, payload, sender=self.sc.leader.robot_id)
        if fc is not None:
            if (why := self.checks.code(fc)) is not None:
                self.rejections.reject(why)
            else:
                self._take_codes(self.formation_link.deliver(fc.seq, fc.tick, fc), fc.tick)

    def _take_codes(self, codes: list[FormationCode], release_tick: int) -> None:
        """Codes the formation link handed over at ``release_tick``: one it held
        takes effect as if stamped with the tick of its release."""
        for fc in codes:
            if (why := self.checks.handed_code(fc)) is not None:
                self.rejections.reject(why)
            elif fc.code >= len(self.sc.formation_names):
                self.rejections.reject("unknown formation")
            elif self.rid not in self.sc.formation_by_code(fc.code).slots:
                self.rejections.reject("no slot in formation")
            else:
                self.pending_codes.append((max(fc.tick, release_tick), fc))

    def _apply_formation(self, fc: FormationCode) -> None:
        if fc.code == self.code:
            return
        slot = self.sc.formation_by_code(fc.code).slots[self.rid]
        self.code = fc.code
        if slot.reference != self.reference:
            self.follower.new_reference()
        self.reference = slot.reference
        self.follower.set_offset(slot.offset)
        self.formation_changes.append({"tick": fc.tick, "code": fc.code, "name": self.sc.formation_names[fc.code]})

    def _on_observation(self, obs: Observation, reading: Observation | None) -> None:
        """Answer ``obs`` (its tick) with what ``reading`` says (None: nothing)."""
        if self.is_leader:
            self._lead(obs, reading)
        else:
            self._follow(obs, reading)
        self.answered += 1
        self.last_tick = obs.tick

    def _send_cmd(self, tick: int, left: float, right: float, done: bool = False) -> None:
        self.seq += 1
        self.cmd_pub.put(Command(self.rid, self.seq, tick, left, right, self.code, done).to_bytes())

    def _lead(self, obs: Observation, reading: Observation | None) -> None:
        if reading is not None:
            self.code = self.switch.step(reading.obstacles)
            self.last_cmd = self.pilot.step(Pose(*reading.pose))
        if self.repeats.due(self.code) and self.code_pub is not None:
            self.seq += 1
            self.code_pub.put(FormationCode(self.rid, self.seq, obs.tick, self.code).to_bytes())
        self._send_cmd(obs.tick, *self.last_cmd, done=self.pilot.finished)

    def _follow(self, obs: Observation, reading_obs: Observation | None) -> None:
        # The leader answers tick k with its code for k; that code can reach us before
        # or after our own observation k (the world publishes them one by one), so it
        # is applied from tick k + 1 on: never earlier, and in lockstep never later,
        # since the world publishes k + 1 only after the leader's answer to k.
        # Codes are taken in the order of their ticks, so one stamped far ahead
        # cannot hold back the others. A code the link held back counts from
        # the tick of its release (so it too takes effect on the tick after).
        if self.pending_codes and min(t for t, _ in self.pending_codes) < obs.tick:
            due = sorted((p for p in self.pending_codes if p[0] < obs.tick), key=lambda p: (p[0], p[1].seq))
            self.pending_codes = collections.deque(
                (p for p in self.pending_codes if p[0] >= obs.tick), maxlen=PENDING_CODES
            )
            for _, fc in due:
                self._apply_formation(fc)
        reading = None
        if reading_obs is not None:  # this tick's, or an older one the link held back (stale, as delays are)
            for rid, rho, phi, beta in reading_obs.readings:
                if rid == self.reference:
                    reading = (rho, phi, beta)
                    break
        # The ticks since the last one answered: more than one where observations
        # were skipped (real time, a busy machine) or the agent was frozen.
        ticks = 1 if self.answered_tick is None else max(1, obs.tick - self.answered_tick)
        self.answered_tick = obs.tick
        d: Decision = self.follower.step(reading, ticks)
        self._send_cmd(obs.tick, d.left_mps, d.right_mps)
        self._count_hold(obs.tick, d.holding)
        self.waited_ticks += d.waiting
        cov = (
            None
            if d.estimate_cov is None
            else (float(d.estimate_cov[0, 0]), float(d.estimate_cov[0, 1]), float(d.estimate_cov[1, 1]))
        )
        self.seq += 1
        self.tel_pub.put(
            Telemetry(
                self.rid,
                self.seq,
                obs.tick,
                obs.time_s,
                self.reference,
                self.code,
                None if d.measured is None else tuple(d.measured),
                None if d.estimate is None else tuple(d.estimate),
                cov,
                _opt(d.rho_m),
                _opt(d.alpha_rad),
                _opt(d.vn),
                d.left_mps,
                d.right_mps,
                int(d.steering_to),
                d.changing,
                self.obs_link.lost,
                self.formation_link.lost,
                self.rejections.total,
            ).to_bytes()
        )
        if self.tel_every > 1 and (obs.tick + self.rid) % self.tel_every == 0:
            self.tel_pub.flush()
        self.follower.prepare()  # the next tick's EKF prediction, before its observation comes

    def _count_hold(self, tick: int, holding: bool) -> None:
        if not holding:
            self._hold_span = None
            return
        self.held_ticks += 1
        if self._hold_span is not None:
            self._hold_span[1] = tick
        elif len(self.holds) < MAX_HOLDS:
            self._hold_span = [tick, tick]
            self.holds.append(self._hold_span)

    def stats(self) -> dict[str, Any]:
        return {
            "robot": self.rid,
            "role": "leader" if self.is_leader else "follower",
            "lockstep": self.lockstep,  # its telemetry waits for the logger (lockstep) or may be dropped
            "answered": self.answered,
            "last_tick": self.last_tick,  # of the newest observation answered (None: none yet)
            "superseded": self.superseded,
            "ekf_resets": 0 if self.is_leader else self.follower.ekf.resets,
            "held_ticks": self.held_ticks,  # a follower's ticks held at a standing reference
            "holds": self.holds,  # [first, last] tick of each hold, the first MAX_HOLDS
            "waited_ticks": self.waited_ticks,  # a follower's ticks stopped ahead of its target
            "busy_s": self.busy_s,
            "cpu_s": time.process_time(),  # the process's CPU time so far (user + system, all threads)
            "loop_cpu_s": self.loop_cpu_s,
            "formation": self.sc.formation_names[self.code],
            "formation_changes": self.formation_changes,
            "world_back_after_s": self.world_back_after_s,  # per loss of the world's token mid-run (None: never)
            "links": {
                lk.name: lk.stats()
                for lk in ((self.obs_link,) if self.is_leader else (self.obs_link, self.formation_link))
            },
            "rejected": dict(self.rejections.by_reason + self.status_rejections.by_reason),
        }


def _opt(x: float) -> float | None:
    return None if x != x else x  # NaN -> None (the wire carries no NaN)


DESCRIPTION = """\
Run one robot's agent by hand: its controller, on the run's Zenoh key
space. A follower turns the world's camera observations into wheel speeds
with the paper's EKF and fuzzy controller and obeys its leader's formation
codes; the leader flies the scenario's path and sends the codes.

It connects, as a client, to the world or to the run's router, waits for
the world (the leader also for its followers), answers every tick, and
exits when the world says the run is done or leaves.

It prints one line when its session is open, one when the run starts and
one when it ends (why, and where its stats went)."""


def build_parser() -> cliargs.Parser:
    ap = cliargs.Parser(
        prog="swarm agent",
        description=DESCRIPTION,
        epilog=role_mod.EXIT_CODES_HELP,
    )
    ap.add_argument("--id", type=int, required=True, metavar="N", help="the robot id, one of the scenario's robots")
    ap.add_argument(
        "--scenario",
        required=True,
        metavar="FILE|NAME",
        help="the scenario: a TOML file or a shipped scenario's name; the same as the world's",
    )
    ap.add_argument("--run", required=True, metavar="ID", help="run id: the same as the world's")
    ap.add_argument(
        "--seed",
        type=cliargs.seed,
        default=None,
        metavar="N",
        help="random seed of the link drops and link faults (default: the scenario's); the same as the world's",
    )
    ap.add_argument("--stats", metavar="FILE", help="write this agent's counters here at exit (JSON)")
    ap.add_argument(
        "--lockstep",
        action="store_true",
        help="the world runs in lockstep: telemetry waits for the logger, never dropped",
    )
    role_mod.add_arguments(ap, waits_for="the world (and, for the leader, its followers)")
    ap.add_argument(
        "--world-grace",
        type=role_mod.seconds,
        default=None,
        metavar="S",
        help="once the run started, how long to wait for the world's token to come back after it went (our "
        "session dropped by the router, a network cut, a router restart) before leaving (default: the peers "
        "timeout)",
    )
    session.add_arguments(ap, default_mode="client")
    return ap


def main(argv: list[str] | None = None) -> int:
    args = build_parser().parse_args(argv)
    role = role_mod.Role(f"agent {args.id}", args.peers_timeout)
    sc = role.load(args)
    if isinstance(sc, int):
        return sc
    if args.id not in sc.robots:
        role.complain(f"--id {args.id} is not a robot of this scenario; its robots are {list(sc.robots)}")
        return role_mod.EXIT_USAGE
    sess_cm = role.connect(args, login=trust.agent_user(args.id))
    if isinstance(sess_cm, int):
        return sess_cm
    seed = sc.seed if args.seed is None else args.seed
    where = role_mod.describe_session(args)
    with sess_cm as sess:
        grace = args.peers_timeout if args.world_grace is None else args.world_grace
        agent = Agent(
            sess, sc, args.id, args.run, seed, role, where, grace, stats_path=args.stats, lockstep=args.lockstep
        )
        part = "leader" if agent.is_leader else f"follower of robot {agent.reference}"
        waits = "the world and its followers" if agent.is_leader else "the world"
        role.say(f"{where}; run {args.run}, {part}: waiting up to {role.peers_timeout_s:g} s for {waits}")
        code = agent.run()
        # Our last telemetry and its end-of-stream mark may still be in our kernel
        # (the router reads them only as fast as the logger takes them): leaving
        # now could throw them away (swarm.proc.wait_sent).
        if (unsent := wait_sent(SEND_DRAIN_S)) > 0:
            role.say(f"{unsent} bytes not yet taken by the router after {SEND_DRAIN_S:g} s; leaving anyway")
        agent.stats_writer.close(agent.stats())  # the last write, after any older snapshot
        if code != role_mod.EXIT_NO_PEERS:
            written = f"stats in {args.stats}" if args.stats else "no --stats: counters not written"
            role.say(
                f"run {args.run} ended ({agent.end_note}), exit code {code}, "
                f"{agent.answered} observations answered; {written}"
            )
    return code


if __name__ == "__main__":
    exit_after_main(main())
