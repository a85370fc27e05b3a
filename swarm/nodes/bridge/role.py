"""The ROS 2 bridge's decisions, as a plain object: the run's messages and the
ROS robots' Twists in, what to publish out. No Zenoh: nodes.bridge.node
declares the subscribers and publishers and hands everything to one loop.

Each tick's ground truth becomes the topics of formation_swarm.ros2.topics
(but ``/clock``, said here); what each robot's camera saw comes from the
world's sightings of that tick (every robot's observation, protocol.sightings).
A robot left to ROS is answered for as its agent would: a Twist on
``/robotN/cmd_vel`` becomes wheel speeds (the robot's drive model,
``twist_to_wheels``) in a Command the world judges as any agent's.

Lockstep: ``/clock`` says tick t once tick t - 1's topics are out (the
world sends tick t - 1's truth while it waits for tick t's answers), and
the first Twist that comes after it answers tick t. So a ROS node answers
tick t from the poses of tick t - 1, whatever the timing: two runs give one
digest. Real time: ``/clock`` says tick t as its observation comes, and
each tick's command carries the latest Twist, while it is younger than
``run.stale_after_s`` (a ROS node gone: the world then stops the robot).
"""

from __future__ import annotations

import collections
import math
import time
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from typing import Any

from formation_swarm.protocol import sightings as sightings_mod
from formation_swarm.protocol.codec import Rejections
from formation_swarm.protocol.messages import Command, FormationCode, Observation, Truth
from formation_swarm.ros2 import messages as ros_messages
from formation_swarm.ros2 import topics
from formation_swarm.spec.ros2 import Ros2Settings
from formation_swarm.spec.scenario import Scenario

TAKEN, REJECTED, UNAWAITED = "taken", "rejected", "unawaited"  # a Twist's fates, per robot
MAX_SPEED_MPS = 1e3  # a Twist beyond this (or a turn rate beyond it in rad/s) is no robot's: rejected
SIGHTINGS_KEPT = 4  # ticks of sightings kept for their truth (lockstep: it comes a tick after them)


@dataclass(frozen=True)
class RosOut:
    """A ROS message to publish."""

    topic: str
    msgtype: str
    msg: Any


@dataclass(frozen=True)
class CmdOut:
    """A command to publish on a ROS robot's command key."""

    robot: int
    command: Command


@dataclass
class Counts:
    """What the bridge took and gave, for its stats."""

    ticks_published: int = 0  # truths turned into topics
    messages_published: int = 0
    commands_sent: int = 0
    twists: dict[int, collections.Counter[str]] = field(default_factory=dict)  # robot -> TAKEN/REJECTED/UNAWAITED


class BridgeRole:
    """The bridge of one run; ``robots``: those left to ROS (followers only)."""

    def __init__(
        self,
        sc: Scenario,
        settings: Ros2Settings,
        robots: Iterable[int],
        *,
        lockstep: bool,
        clock: Callable[[], float] = time.monotonic,
    ) -> None:
        self.sc = sc
        self.settings = settings
        self.robots = tuple(robots)
        if sc.leader.robot_id in self.robots:
            raise ValueError(f"robot {sc.leader.robot_id} is the leader: only followers may be driven from ROS")
        self.lockstep = lockstep
        self.rejections = Rejections()  # the run's messages that do not decode or do not fit, by reason
        self.counts = Counts(twists={r: collections.Counter() for r in self.robots})
        self.codes: list[tuple[int, int]] = []  # (tick, code) of the leader's codes, in arrival order
        self.start_code = sc.code_of(sc.leader.formation)
        self.last_truth: Truth | None = None  # the tick before, for the odometry's twist
        self.world_tick = -1  # the newest tick observed
        self.truth_tick = -1  # the newest tick whose topics are out
        self.clock_tick = -1  # the newest tick /clock said
        self.awaiting: dict[int, int] = {}  # lockstep: robot -> the tick its next Twist answers
        self.clock = clock  # real time: a Twist's age
        self.latest: dict[int, tuple[float, float, float]] = {}  # real time: robot -> its latest Twist: wheels, when
        self.observed: dict[int, int] = {}  # robot -> the newest tick it was observed at
        self.readings: dict[int, dict[int, tuple[Any, ...]]] = {}  # tick -> robot -> its camera's readings
        self.seq = dict.fromkeys(self.robots, 0)
        self.done = False

    # -- the run's messages ------------------------------------------------------------
    def take_code(self, payload: bytes) -> None:
        fc = self.rejections.decode(FormationCode, payload)
        if fc is None:
            return
        if fc.sender != self.sc.leader.robot_id:
            self.rejections.reject("sender mismatch")
        elif fc.code >= len(self.sc.formation_names):
            self.rejections.reject("unknown formation")
        else:
            self.codes.append((fc.tick, fc.code))
            del self.codes[:-64]  # the newest are enough: codes are repeated

    def take_obs(self, robot: int, payload: bytes) -> list[RosOut | CmdOut]:
        """Robot ``robot``'s observation: the world is at its tick."""
        obs = self.rejections.decode(Observation, payload)
        if obs is None or robot not in self.seq:
            return []
        self.world_tick = max(self.world_tick, obs.tick)
        self.observed[robot] = obs.tick
        if not self.lockstep:
            out: list[RosOut | CmdOut] = self._clock(obs.tick)
            left, right, at = self.latest.get(robot, (0.0, 0.0, -math.inf))
            if self.clock() - at <= self.sc.stale_after_s:
                out.append(self._command(robot, obs.tick, left, right))
            return out
        if self.clock_tick == obs.tick:  # /clock said it already (another robot's observation came first)
            self.awaiting[robot] = obs.tick
            return []
        return self._clock_due()

    def take_sightings(self, payload: bytes) -> None:
        """Some robots' observations of a tick (protocol.sightings): what their cameras saw."""
        robots = self.sc.robots
        for rid, obs in sightings_mod.unpack(payload, self.rejections):
            if rid not in robots:
                self.rejections.reject("unknown robot")
            elif obs.tick > self.truth_tick:  # a tick whose topics are out: too late to show
                self.readings.setdefault(obs.tick, {})[rid] = obs.readings
        for old in [t for t in self.readings if t <= self.truth_tick or t < self.newest_tick - SIGHTINGS_KEPT]:
            del self.readings[old]

    @property
    def newest_tick(self) -> int:
        """The newest tick the bridge knows of: observed, published or said by /clock."""
        return max(self.world_tick, self.truth_tick, self.clock_tick, max(self.readings, default=-1))

    def take_truth(self, payload: bytes) -> list[RosOut | CmdOut]:
        """A batch of ground truth: each tick's topics, then (lockstep) /clock if due."""
        out: list[RosOut | CmdOut] = []
        for truth in self.rejections.decode_batch(Truth, payload) or []:
            if truth.tick <= self.truth_tick:
                self.rejections.reject("replayed or reordered")
                continue
            if not self.seq:  # no robot left to ROS: /clock goes with the truth
                out += self._clock(truth.tick)
            out += self._topics(truth)
        if self.seq and self.lockstep:
            out += self._clock_due()
        return out

    # -- the ROS robots' Twists ------------------------------------------------------------
    def take_twist(self, robot: int, linear_x: float, angular_z: float) -> list[RosOut | CmdOut]:
        """A Twist on robot ``robot``'s cmd_vel (its forward speed and turn rate)."""
        counts = self.counts.twists[robot]
        if not all(math.isfinite(v) and abs(v) <= MAX_SPEED_MPS for v in (linear_x, angular_z)):
            counts[REJECTED] += 1
            self.rejections.reject("twist not finite or out of bounds")
            return []
        wheels = topics.twist_to_wheels(linear_x, angular_z, self.sc.width_m, self.sc.max_wheel_mps)
        if not self.lockstep:
            counts[TAKEN] += 1
            self.latest[robot] = (*wheels, self.clock())
            return []
        tick = self.awaiting.pop(robot, None)
        if tick is None:  # before /clock said the tick it would answer: not an answer
            counts[UNAWAITED] += 1
            return []
        counts[TAKEN] += 1
        return [self._command(robot, tick, *wheels)]

    def rejected_twist(self, robot: int, reason: str) -> None:
        """A sample on robot ``robot``'s cmd_vel that was no Twist (it did not decode) or not finite."""
        self.counts.twists[robot][REJECTED] += 1
        self.rejections.reject(reason)

    # -- what goes out ------------------------------------------------------------------
    def _clock_due(self) -> list[RosOut | CmdOut]:
        """Lockstep: /clock for the world's tick once the tick before is published."""
        t = self.world_tick
        if t <= self.clock_tick or (t > 0 and self.truth_tick < t - 1):
            return []
        out = self._clock(t)
        for robot, tick in self.observed.items():
            if tick == t:
                self.awaiting[robot] = t
        return out

    def _clock(self, tick: int) -> list[RosOut | CmdOut]:
        if tick <= self.clock_tick:
            return []
        self.clock_tick = tick
        msg = ros_messages.build(topics.CLOCK, self.settings.distro, clock=ros_messages.stamp(tick * self.sc.dt_s))
        self.counts.messages_published += 1
        return [RosOut(topics.topic("clock", self.settings.namespace), topics.CLOCK, msg)]

    def _command(self, robot: int, tick: int, left_mps: float, right_mps: float) -> CmdOut:
        self.seq[robot] += 1
        self.counts.commands_sent += 1
        cmd = Command(
            sender=robot,
            seq=self.seq[robot],
            tick=tick,
            left_mps=left_mps,
            right_mps=right_mps,
            formation=self._code_for(robot, tick),
            done=False,
        )
        return CmdOut(robot, cmd)

    def _code_for(self, robot: int, tick: int) -> int:
        """The formation robot ``robot`` flies at ``tick``: the leader's newest code
        stamped before it with a slot for the robot (the ones stamped at ``tick``
        may or may not have come yet: left out, so that timing cannot choose)."""
        code = self.start_code
        for at, c in sorted(self.codes):
            if at < tick and robot in self.sc.formation_by_code(c).slots:
                code = c
        return code

    def _topics(self, truth: Truth) -> list[RosOut | CmdOut]:
        state = self.tick_state(truth)
        msgs = topics.tick_messages(state, self.settings.namespace, self.settings.distro)
        out: list[RosOut | CmdOut] = [RosOut(t, m, msg) for t, m, msg in msgs if m != topics.CLOCK]
        self.truth_tick = truth.tick
        self.last_truth = truth
        self.counts.ticks_published += 1
        self.counts.messages_published += len(out)
        return out

    def tick_state(self, truth: Truth) -> topics.TickState:
        """One tick's plain numbers from its truth: poses, the twist since the tick
        before (when that truth came), the followers' formation error, what the
        ROS robots' cameras saw, the leader's code."""
        dt = self.sc.dt_s
        before = self.last_truth
        prev = {r[0]: r for r in before.robots} if before is not None and before.tick == truth.tick - 1 else {}
        targets = {rid: (x, y) for rid, x, y in truth.targets}
        seen = self.readings.pop(truth.tick, {})
        robots = []
        for rid, x, y, theta, _alive in truth.robots:
            v = omega = 0.0
            if (p := prev.get(rid)) is not None:
                v = ((x - p[1]) * math.cos(p[3]) + (y - p[2]) * math.sin(p[3])) / dt
                omega = math.remainder(theta - p[3], math.tau) / dt
            error = None if rid not in targets else math.hypot(x - targets[rid][0], y - targets[rid][1])
            sightings = seen.get(rid, ())
            robots.append(
                topics.RobotTick(
                    robot=rid,
                    x_m=x,
                    y_m=y,
                    theta_rad=theta,
                    v_mps=v,
                    omega_rps=omega,
                    sightings=sightings,
                    formation_error_m=error,
                )
            )
        code = self.start_code
        for at, c in sorted(self.codes):
            if at <= truth.tick:
                code = c
        return topics.TickState(time_s=truth.time_s, robots=tuple(robots), formation=code)

    def stats(self) -> dict[str, Any]:
        c = self.counts
        return {
            "robots": list(self.robots),
            "ticks_published": c.ticks_published,
            "messages_published": c.messages_published,
            "commands_sent": c.commands_sent,
            "twists": {str(r): {k: n[k] for k in (TAKEN, REJECTED, UNAWAITED)} for r, n in c.twists.items()},
            "rejected": dict(self.rejections.by_reason),
        }
