"""Where the world judges a Command, the one place it is judged.

:meth:`CommandGate.decode` takes a payload from the wire: a robot of the run
must have sent it (the robot its key names: "unknown robot"), it must decode
(protocol.codec: shape, types, finite numbers, the header's ranges) and its
sender must be that robot ("sender mismatch"). :meth:`CommandGate.admit`
then asks what no robot can do and what no honest agent sends: wheel speeds
beyond the motors ("wheel speed out of bounds"), a formation the run does
not have ("unknown formation"), a tick the world has not published ("tick
ahead of the world"), a command not newer than the last one taken
("replayed or reordered"). :meth:`CommandGate.fresh` orders what the command
link hands over the same way, and :meth:`CommandGate.wheels` gives the
speeds the motors run. Each rejection is counted by its reason
(``rejections``); the engine executes what passes, unchecked.

A "done" is judged on the world's own truth (:meth:`CommandGate.done`): from
a follower it is "done from a follower"; from the leader it counts only when
the world sees the leader at its last waypoint (:func:`at_last_waypoint`),
else "done before the last waypoint". Either way the whole command is
rejected, as one that could not be true: what a stolen login sends cannot
take the place of the agent's own answer.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

from formation_swarm.protocol.codec import Rejections
from formation_swarm.protocol.messages import Command
from formation_swarm.world.kinematics import Pose
from formation_swarm.world.setup import WorldSetup

# A speed this close beyond the limit is rounding (an agent's own clamp in
# another language, say): clamped to the limit and counted, not rejected.
WHEEL_TOLERANCE = 1e-9

NEVER = (-1, -1)  # (tick, seq) older than every command

# The leader is at its last waypoint for the world within this many of its
# look-ahead distances of it (leader.lookahead_m): its pilot ends within half
# of one (agents.pilot), and in real time it may roll on for a tick or two.
DONE_WITHIN_LOOKAHEADS = 1.0


def at_last_waypoint(pose: Pose, waypoints: Sequence[Sequence[float]], within_m: float) -> bool:
    """Whether a leader at ``pose`` has reached the last of ``waypoints``, as
    its pilot ends a path: within ``within_m`` of it, or past it (its
    projection on the last leg beyond the end; a pilot turned wide ends
    there, metres to the side), the last leg being the leg nearest to it
    (the first of equally near ones), so that a path which comes back on
    itself is not done where it began."""
    x, y = pose[0], pose[1]
    pts = [(float(p[0]), float(p[1])) for p in waypoints]
    pts = [p for i, p in enumerate(pts) if i == 0 or p != pts[i - 1]]
    (ex, ey) = pts[-1]
    if math.hypot(ex - x, ey - y) <= within_m:
        return True
    if len(pts) < 2:
        return False
    legs = list(zip(pts[:-1], pts[1:], strict=True))
    nearest = min(range(len(legs)), key=lambda i: (_distance_to_leg(x, y, *legs[i]), i))
    (ax, ay) = pts[-2]
    return nearest == len(legs) - 1 and (x - ex) * (ex - ax) + (y - ey) * (ey - ay) > 0.0


def _distance_to_leg(x: float, y: float, a: tuple[float, float], b: tuple[float, float]) -> float:
    dx, dy = b[0] - a[0], b[1] - a[1]
    length2 = dx * dx + dy * dy
    t = 0.0 if length2 == 0.0 else max(0.0, min(1.0, ((x - a[0]) * dx + (y - a[1]) * dy) / length2))
    return math.hypot(a[0] + t * dx - x, a[1] + t * dy - y)


class CommandGate:
    """The world's checks of the commands of one run's robots."""

    def __init__(self, setup: WorldSetup) -> None:
        self.rejections = Rejections()
        self.robots = frozenset(setup.robots)
        self.max_wheel_mps = setup.max_wheel_mps
        self.wheel_limit_mps = setup.max_wheel_mps * (1.0 + WHEEL_TOLERANCE)
        self.formations = len(setup.formation_names)
        self.leader = setup.leader.robot_id
        self.waypoints = tuple(setup.leader.waypoints)
        self.done_within_m = DONE_WITHIN_LOOKAHEADS * setup.leader.lookahead_m
        self.clamped = 0  # commands admitted within the tolerance beyond the limit, run at the limit
        # Per robot, (tick, seq) of the last command taken, and of the last one its
        # cmd link handed over and was applied: each must be newer, in that order.
        self.last: dict[int, tuple[int, int]] = dict.fromkeys(setup.robots, NEVER)
        self.applied: dict[int, tuple[int, int]] = dict.fromkeys(setup.robots, NEVER)

    def decode(self, robot_id: int | None, payload: bytes) -> Command | None:
        """The Command a payload on robot ``robot_id``'s command key holds (None:
        the key names no robot of the run), or None with the reason counted."""
        if robot_id is None or robot_id not in self.robots:
            self.rejections.reject("unknown robot")
            return None
        return self.rejections.decode(Command, payload, sender=robot_id)

    def admit(self, msg: Command, world_tick: int) -> bool:
        """Whether a decoded command may be taken while the world is at
        ``world_tick``; taken, it is the newest of its robot."""
        # What no robot can do first, then what no honest agent sends: a command
        # answers an observation the world published, so never a tick to come,
        # never one older than (or the same message as) the last one taken.
        if not (abs(msg.left_mps) <= self.wheel_limit_mps and abs(msg.right_mps) <= self.wheel_limit_mps):
            self.rejections.reject("wheel speed out of bounds")
            return False
        if msg.formation >= self.formations:
            self.rejections.reject("unknown formation")
            return False
        if msg.tick > world_tick:
            self.rejections.reject("tick ahead of the world")
            return False
        # Ordered by (tick, seq), the tick bounded by the world's own: a command
        # with a huge seq (a stolen login, say) cannot make the agent's real ones
        # look replayed beyond the tick it answers, as ordering by seq alone did.
        order = (msg.tick, msg.seq)
        if order <= self.last[msg.sender]:
            self.rejections.reject("replayed or reordered")
            return False
        self.last[msg.sender] = order
        return True

    def done(self, msg: Command, leader_pose: Pose) -> bool:
        """Whether a command that says "done" may be taken: only the leader's,
        and only while the world sees the leader (at ``leader_pose``) at its
        last waypoint; else rejected and counted."""
        if msg.sender != self.leader:
            self.rejections.reject("done from a follower")
            return False
        if not at_last_waypoint(leader_pose, self.waypoints, self.done_within_m):
            self.rejections.reject("done before the last waypoint")
            return False
        return True

    def fresh(self, msg: Command) -> bool:
        """Whether a command its link hands over (now, or held until this tick)
        is newer than the last one applied; else (a duplicate, one held behind
        a newer one) "replayed or reordered"."""
        order = (msg.tick, msg.seq)
        if order <= self.applied[msg.sender]:
            self.rejections.reject("replayed or reordered")
            return False
        self.applied[msg.sender] = order
        return True

    def wheels(self, msg: Command) -> tuple[float, float]:
        """The wheel speeds the robot runs for an admitted command: as sent, or
        at the limit for one within the tolerance beyond it (counted)."""
        left, right, limit = msg.left_mps, msg.right_mps, self.max_wheel_mps
        if not (-limit <= left <= limit and -limit <= right <= limit):
            self.clamped += 1  # the robot's motors cannot do more, whatever it is told
            left = min(max(left, -limit), limit)
            right = min(max(right, -limit), limit)
        return left, right

    def forget(self, rid: int) -> None:
        """Robot ``rid``'s agent is a fresh one: it counts its messages from 1."""
        self.last[rid] = NEVER
        self.applied[rid] = NEVER
