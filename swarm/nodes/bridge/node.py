"""The ROS 2 bridge process around its role (nodes.bridge.role): the session,
the run's subscribers, the ROS node with its publishers and subscriptions
(formation_swarm.ros2.rmw), and one loop that hands the role each event in
the order it came.

Zenoh's callbacks only queue what arrives, on the thread that received it. For each robot left to ROS the
bridge holds the robot's agent token, so that the world waits for it as for
any agent, but only once a ROS node is there to answer: one that publishes
the robot's ``cmd_vel`` and subscribes to ``/clock`` (their ROS liveliness
tokens), within ``--peers-timeout``.

With a spool (``--wire-spool``), every run message and every ROS sample the
bridge takes in (the truth, the status, the sightings, its robots' inboxes,
the codes, each ``cmd_vel`` sample as its bytes came) is recorded as the loop
takes it, at the newest tick the bridge knew of (docs/replay.md).
"""

from __future__ import annotations

import contextlib
import queue
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

import zenoh

from formation_swarm.nodes.bridge.role import BridgeRole, CmdOut, RosOut
from formation_swarm.protocol.codec import Rejections
from formation_swarm.protocol.keys import Keys, RosKeys
from formation_swarm.protocol.messages import Status
from formation_swarm.ros2 import rmw, topics
from formation_swarm.runtime import process as process_mod
from formation_swarm.runtime.spool import SpoolWriter

NODE_NAME = "swarm_bridge"
QUEUE_CAPACITY = 100_000  # events waiting for the loop; beyond, the newest are dropped and counted
POLL_S = 0.05  # the loop's longest wait: it looks at the stop signal and the subscriptions' counts


@dataclass(frozen=True)
class Options:
    run_id: str
    where: str = ""
    stats_path: str | None = None
    lockstep: bool = False


class Bridge:
    """The bridge process of one run."""

    def __init__(  # noqa: PLR0913 -- the process's parts, each once
        self,
        sess: zenoh.Session,
        brain: BridgeRole,
        role: process_mod.Process,
        opts: Options,
        spool: SpoolWriter | None = None,
    ) -> None:
        self.session = sess
        self.spool = spool
        self.brain = brain
        self.role = role
        self.opts = opts
        self.keys = Keys(opts.run_id)
        self.events: queue.Queue[tuple[Any, ...]] = queue.Queue(QUEUE_CAPACITY)
        self.dropped = 0  # events the queue had no room for
        self.status_rejections = Rejections()
        self.started = False
        self.world_seen = False
        self.end_note = "not started"
        self.waited_for: dict[str, Any] | None = None  # what it waited for in vain before the run (None: it did not)
        self.graph: set[tuple[str, str]] = set()  # (kind, topic) of the other ROS entities' tokens
        self.subs: dict[int, rmw.Subscriber] = {}
        self.malformed: dict[int, int] = {}  # per robot, the cmd_vel samples its subscription refused, said so far
        self.zid = str(sess.zid())  # our own ROS entities' tokens carry it
        self.pubs: dict[str, rmw.Publisher] = {}
        self.cmds: dict[int, zenoh.Publisher] = {}
        self.twists_out: list[RosOut | CmdOut] = []  # what the Twist being taken gave

    # -- callbacks: Zenoh's threads, they only queue ------------------------------------
    def _put(self, kind: str, robot: int, data: Any, key: str = "") -> None:
        """An event for the loop; ``key``: a message's, to spool (its bytes are ``data``)."""
        try:
            self.events.put_nowait((kind, robot, data, key, time.time_ns()))
        except queue.Full:
            self.dropped += 1

    def _on_sample(self, kind: str, robot: int = 0) -> zenoh.handlers.Callback:
        return _direct(lambda sample: self._put(kind, robot, sample.payload.to_bytes(), str(sample.key_expr)))

    def _on_inbox(self, robot: int) -> zenoh.handlers.Callback:
        obs, codes = self.keys.obs(robot), self.keys.codes

        def take(sample: zenoh.Sample) -> None:
            key = str(sample.key_expr)
            kind = "obs" if key == obs else "code" if key == codes else "stray"
            self._put(kind, robot, sample.payload.to_bytes(), key)

        return _direct(take)

    def _on_twist(self, robot: int, key: str) -> Callable[[bytes, bytes | None], None]:
        """A sample on robot ``robot``'s cmd_vel, its bytes as they came: decoded in the loop."""
        return lambda payload, attached: self._put("twist", robot, (payload, attached), key)

    def _took_twist(self, robot: int) -> Callable[[Any, Any], None]:
        """A Twist that decoded (the loop's, in Intake.take): what the role answers."""
        brain = self.brain
        return lambda msg, _meta: self.twists_out.extend(
            brain.take_twist(robot, float(msg.linear.x), float(msg.angular.z))
        )

    def _on_world(self, sample: zenoh.Sample) -> None:
        self._put("world", 0, sample.kind == zenoh.SampleKind.PUT)

    def _on_graph(self, sample: zenoh.Sample) -> None:
        parts = str(sample.key_expr).split("/")
        if len(parts) >= 10 and parts[2] != self.zid:  # another session's publisher or subscription
            entity = (parts[5], parts[9].replace("%", "/"))
            self._put("graph", 0, (entity, sample.kind == zenoh.SampleKind.PUT))

    # -- the process ------------------------------------------------------------------
    def run(self) -> int:
        s, k, brain = self.session, self.keys, self.brain
        settings = brain.settings
        node = rmw.Node(s, NODE_NAME, namespace=settings.namespace, domain=settings.domain_id, distro=settings.distro)
        self.pubs = {
            name: rmw.Publisher(node, name, msgtype, block=blocks(msgtype, lockstep=self.opts.lockstep))
            for name, msgtype in _topics(brain, settings.namespace, settings.distro).items()
        }
        block = zenoh.CongestionControl.BLOCK  # a command is never dropped by Zenoh, as an agent's
        self.cmds = {r: s.declare_publisher(k.cmd(r), congestion_control=block) for r in brain.robots}
        s.declare_subscriber(k.truth, self._on_sample("truth"))
        s.declare_subscriber(k.status, self._on_sample("status"))
        s.declare_subscriber(k.sightings, self._on_sample("sightings"))
        for r in brain.robots:  # its inbox: observations and the leader's codes (not our own commands)
            s.declare_subscriber(k.inbox(r), self._on_inbox(r), allowed_origin=zenoh.Locality.REMOTE)
        if not brain.robots:
            s.declare_subscriber(k.codes, self._on_sample("code"))
        for r in brain.robots:
            twist = topics.cmd_vel(r, settings.namespace)
            key = rmw.topic_key(settings.domain_id, rmw.qualify(twist, node.namespace), topics.TWIST, node.distro)
            self.subs[r] = rmw.Subscriber(
                node, twist, topics.TWIST, self._took_twist(r), check=lambda _m: True, raw=self._on_twist(r, key)
            )
            self.malformed[r] = 0
        s.liveliness().declare_subscriber(k.alive("world", 0), self._on_world, history=True)
        s.liveliness().declare_subscriber(RosKeys(settings.domain_id).graph, self._on_graph, history=True)
        tokens: list[Any] = []
        try:
            if (code := self._wait_ready()) is not None:
                return code
            # Ours (the world waits for it), then our robots' (after their inbox and command publisher).
            tokens = [s.liveliness().declare_token(k.alive("bridge", 0))]
            tokens += [s.liveliness().declare_token(k.alive("agent", r)) for r in brain.robots]
            return self._loop()
        finally:
            for t in tokens:
                with contextlib.suppress(zenoh.ZError):
                    t.undeclare()

    def _ros_ready(self) -> list[str]:
        """What the robots left to ROS still miss of a ROS node: its cmd_vel publisher, its /clock subscription."""
        ns = self.brain.settings.namespace
        missing = [f"no ROS publisher of {topics.cmd_vel(r, ns)}" for r in self._unanswered(with_clock=False)]
        clock = topics.topic("clock", ns)
        if self.brain.robots and ("MS", clock) not in self.graph:
            missing.append(f"no ROS subscription to {clock}")
        elif self.brain.robots and clock in self.pubs and not self.pubs[clock].matched:
            # Its token came before its subscriber reached us: a /clock put now would be lost.
            missing.append(f"no ROS subscription to {clock} matched yet")
        return missing

    def _unanswered(self, *, with_clock: bool = True) -> list[int]:
        """The robots left to ROS no ROS node answers for yet: no publisher of their
        cmd_vel or (``with_clock``) no subscription to /clock, which every answer needs."""
        ns, robots = self.brain.settings.namespace, self.brain.robots
        if with_clock and robots and ("MS", topics.topic("clock", ns)) not in self.graph:
            return list(robots)
        return [r for r in robots if ("MP", topics.cmd_vel(r, ns)) not in self.graph]

    def _gave_up_waiting(self) -> None:
        """What the run's start still lacked of ROS when the bridge stopped waiting, for its stats."""
        self.waited_for = {
            "robots": self._unanswered(),
            "missing": self._ros_ready(),
            "world": self.world_seen,
            "timeout_s": self.role.peers_timeout_s,
        }

    def _wait_ready(self) -> int | None:
        """Until the world is there, hears our commands, and a ROS node answers
        for each robot left to ROS; the exit code if that did not come in time."""
        while not self.role.stop.is_set():
            self._drain(until=time.monotonic() + POLL_S)
            heard = all(p.matching_status.matching for p in self.cmds.values())
            if self.world_seen and heard and not self._ros_ready():
                return None
            if self.role.left_s() <= 0:
                self._gave_up_waiting()
                missing = self._ros_ready() + ([] if self.world_seen else [f"no world of run {self.keys.run_id!r}"])
                said = "; ".join(missing or ["the world never subscribed to our robots' commands"])
                return self.role.gave_up(f"{said} ({self.opts.where}); {process_mod.CHECK_PEERS}")
        self._gave_up_waiting()  # stopped first: the world gave up, say, and the launcher stopped us
        return self.role.stop.exit_code

    def _loop(self) -> int:
        robots = ", ".join(map(str, self.brain.robots)) or "none"
        self.role.say(f"run {self.keys.run_id}: publishing its ROS 2 topics; robots driven from ROS: {robots}")
        self.end_note = "the world left before the run started"
        while not self.role.stop.is_set() and not self.brain.done:
            self._drain(until=time.monotonic() + POLL_S)
            if not self.world_seen and self.started:
                self.end_note = "the world left"
                return process_mod.EXIT_OK
        if self.brain.done:
            self.end_note = "the world said done"
            return process_mod.EXIT_OK
        self.end_note = self.role.stopped_by()
        return self.role.stop.exit_code

    def _drain(self, until: float) -> None:
        """Hand the role the events that came, waiting for one until ``until``;
        publish what it answers, in order."""
        self._count_malformed()
        wait = max(0.0, until - time.monotonic())
        while True:
            try:
                event = self.events.get(timeout=wait) if wait > 0 else self.events.get_nowait()
            except queue.Empty:
                return
            wait = 0.0
            kind, robot, data, key, received_ns = event
            outs = self._handle(kind, robot, data)
            if key and self.spool is not None:
                self._spool(self.spool, kind, data, key, received_ns)
            for out in outs:
                if isinstance(out, RosOut):
                    self.pubs[out.topic].put(out.msg)
                else:
                    self.cmds[out.robot].put(out.command.to_bytes())

    def _spool(self, spool: SpoolWriter, kind: str, data: Any, key: str, received_ns: int) -> None:
        """One message taken, at the newest tick known (a Twist: at the tick it answers, with its sender's seq)."""
        tick = self.brain.newest_tick
        if kind != "twist":
            spool.add(key, data, tick if tick >= 0 else None, None, received_ns)
            return
        payload, attached = data
        try:
            seq = None if attached is None else rmw.parse_attachment(attached).seq
        except ValueError:
            seq = None
        spool.add(key, payload, tick if tick >= 0 else None, seq, received_ns)

    def _handle(self, kind: str, robot: int, data: Any) -> list[RosOut | CmdOut]:
        brain = self.brain
        if kind == "obs":
            self.started = True
            return brain.take_obs(robot, data)
        if kind == "truth":
            self.started = True
            return brain.take_truth(data)
        if kind == "twist":
            self.twists_out = []
            self.subs[robot].intake.take(*data)  # a Twist that decodes: _took_twist
            return self.twists_out
        if kind == "sightings":
            brain.take_sightings(data)
        elif kind == "code":
            brain.take_code(data)
        elif kind == "status":
            st = self.status_rejections.decode(Status, data)
            brain.done = brain.done or (st is not None and st.state == "done")
        elif kind == "world":
            self.world_seen = bool(data)
        elif kind == "graph":
            (self.graph.add if data[1] else self.graph.discard)(data[0])
        else:
            brain.rejections.reject("unexpected key")
        return []

    def _count_malformed(self) -> None:
        """The cmd_vel samples each subscription refused (not a Twist's CDR) since the last look."""
        for r, sub in self.subs.items():
            for _ in range(sub.rejected - self.malformed[r]):
                self.brain.rejected_twist(r, "malformed CDR")
            self.malformed[r] = sub.rejected

    def stats(self) -> dict[str, Any]:
        self._count_malformed()
        out = self.brain.stats()
        out["rejected"] = {**out["rejected"], **dict(self.status_rejections.by_reason)}
        out["events_dropped"] = self.dropped
        out["end"] = self.end_note
        out["waited_for"] = self.waited_for
        return out


def blocks(msgtype: str, *, lockstep: bool) -> bool:
    """Whether a topic's samples wait for room on a congested link (Zenoh's BLOCK)
    rather than being dropped. In lockstep, what a ROS node answers a tick from
    (/clock, /tf, odometry, the cameras, /formation): a /clock dropped is a tick
    unanswered, a pose dropped an answer from an older one, and the run would
    depend on the timing; a slow subscriber then slows the run, as a slow agent
    does. Not the formation errors: a score, no input. In real time nothing
    blocks: the next tick's message supersedes a dropped one, and a bridge held
    back by a slow viewer would make every ROS robot's commands stale."""
    return lockstep and msgtype != topics.ERROR


def _direct(callback: Callable[[zenoh.Sample], None]) -> zenoh.handlers.Callback:
    """``callback`` run on the Zenoh thread that received the sample, not on a
    thread of its own per subscriber (zenoh-python's default): the queue then
    holds the run's messages in the order they came on our link (the leader's
    code of tick k before the observation of tick k + 1, and that before the
    truth of tick k), whatever subscriber took them."""
    return zenoh.handlers.Callback(callback, indirect=False)


def _topics(brain: BridgeRole, namespace: str, distro: str) -> dict[str, str]:
    """Every topic the bridge publishes, by name: those of a tick with every robot (and /clock)."""
    robots = tuple(
        topics.RobotTick(robot=r, x_m=0.0, y_m=0.0, theta_rad=0.0, formation_error_m=0.0) for r in brain.sc.robots
    )
    state = topics.TickState(time_s=0.0, robots=robots, formation=0)
    return {name: msgtype for name, msgtype, _msg in topics.tick_messages(state, namespace, distro)}
