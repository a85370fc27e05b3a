"""A run folder as an MCAP file of ROS 2 messages, as rosbag2 writes them.

The topics are those the live bridge publishes (formation_swarm.ros2.topics),
one message per tick (per robot where per robot), from the run's truth as
``load_run`` reads it: poses, formation errors and the formation flown. The
twist of ``/robotN/odom`` is the true motion since the tick before (zero at
the first), as the bridge gives it. What each robot's camera saw comes from the
observations its agent received in the wire recording (wire.mcap); a run
without one, or a tick its agent did not receive, has an empty MarkerArray.
A run driven from ROS (``swarm run --ros2 --external N``) also has
``/robotN/cmd_vel``: each Twist as the bridge received it (its CDR bytes, at
the tick the bridge was at; one it refused as not finite too), from the same
recording; a sample that does not decode as a Twist is left out.

Profile ``ros2``; each schema is the type's definition with its dependencies
(encoding ``ros2msg``), each message CDR (encoding ``cdr``); log and publish
times are the tick's sim time in ns. Foxglove, ``ros2 bag play`` and Rerun
read it; mcap-ros2-support decodes it.
"""

from __future__ import annotations

import math
import re
import struct
from collections import Counter
from collections.abc import Iterator
from pathlib import Path
from typing import IO

import numpy as np
from mcap.exceptions import McapError
from mcap.records import Channel, Footer, Message
from mcap.stream_reader import StreamReader
from mcap.writer import CompressionType, Writer
from zstandard import ZstdError

from formation_swarm.common.version import __version__
from formation_swarm.protocol.codec import Rejections
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.messages import Observation
from formation_swarm.report.data import RunData
from formation_swarm.ros2 import messages, topics
from formation_swarm.runtime.wirefile import FILE_NAME

PROFILE = "ros2"
SCHEMA_ENCODING = "ros2msg"
MESSAGE_ENCODING = "cdr"
Sightings = dict[tuple[int, int], tuple[tuple[int, float, float, float], ...]]  # (robot, tick) -> readings
Twists = list[tuple[int, int, bytes]]  # (robot, log time ns, CDR) of each Twist the bridge took, in order
# A cmd_vel key of rmw_zenoh (ros2.rmw.topic_key), whatever the domain and namespace.
_CMD_VEL = re.compile(
    r"^\d+/(?:[A-Za-z0-9_]+/)*robot(\d+)/cmd_vel/geometry_msgs::msg::dds_::Twist_/RIHS01_[0-9a-f]{64}$"
)
BRIDGE = "bridge"  # the receiver of the ROS robots' Twists in wire.mcap
# What a damaged or cut wire recording raises as it is read (swarm.replay.wire reads it fully).
_UNREADABLE = (McapError, ValueError, struct.error, UnicodeDecodeError, ZstdError, RuntimeError, MemoryError, OSError)


def ticks(run: RunData, sightings: Sightings | None = None) -> Iterator[topics.TickState]:
    """The run's ticks as the bridge would have seen them."""
    sightings = sightings or {}
    v, w = _motion(run)
    followers = set(run.followers)
    for k, tick in enumerate(run.tick.tolist()):
        robots = tuple(
            topics.RobotTick(
                robot=robot,
                x_m=float(run.pose[i, k, 0]),
                y_m=float(run.pose[i, k, 1]),
                theta_rad=float(run.pose[i, k, 2]),
                v_mps=float(v[i, k]),
                omega_rps=float(w[i, k]),
                sightings=sightings.get((robot, tick), ()),
                formation_error_m=float(run.formation_error_m[i, k]) if robot in followers else None,
            )
            for i, robot in enumerate(run.robots)
        )
        yield topics.TickState(time_s=float(run.time_s[k]), robots=robots, formation=_formation(run.formation[:, k]))


def _motion(run: RunData) -> tuple[np.ndarray, np.ndarray]:
    """Each robot's forward speed and turn rate since the tick before (0 at the first)."""
    v, w = np.zeros(run.pose.shape[:2]), np.zeros(run.pose.shape[:2])
    for i in range(len(run.robots)):
        poses = run.pose[i].tolist()
        for k in range(1, len(poses)):
            dt = float(run.time_s[k] - run.time_s[k - 1]) or run.dt_s
            if all(map(math.isfinite, poses[k - 1] + poses[k])):
                v[i, k], w[i, k] = topics.motion(poses[k - 1], poses[k], dt)
    return v, w


def _formation(codes: np.ndarray) -> int | None:
    """The code most followers fly at a tick (-1: unknown)."""
    known = [int(c) for c in codes.tolist() if 0 <= c <= 255]
    return Counter(known).most_common(1)[0][0] if known else None


def read_sightings(run: RunData) -> Sightings:
    """What each robot's camera saw per tick: the observations its agent
    received, from the run's wire recording ({} without one). A recording cut
    short gives what it holds; one that does not read at all gives {}."""
    return read_wire(run)[0]


def read_wire(run: RunData) -> tuple[Sightings, Twists]:
    """From the run's wire recording: what each robot's camera saw per tick, and
    the Twists the bridge took (none without a recording; what a damaged one holds)."""
    path = run.run_dir / FILE_NAME
    run_id = run.summary.get("run_id")
    if not path.is_file() or not isinstance(run_id, str):
        return {}, []
    keys = Keys(run_id)
    wanted = {keys.obs(robot): robot for robot in run.robots}
    out: Sightings = {}
    twists: Twists = []
    try:
        with path.open("rb") as f:
            _read(f, wanted, out, twists)
    except _UNREADABLE:
        pass  # what was read before the damage holds
    return out, twists


def _read(stream: IO[bytes], wanted: dict[str, int], out: Sightings, twists: Twists) -> None:
    channels: dict[int, int] = {}  # channel id -> robot, of the observations
    cmd_vels: dict[int, int] = {}  # channel id -> robot, of the bridge's Twists
    rejections = Rejections()
    for record in StreamReader(stream, validate_crcs=True).records:
        if isinstance(record, Channel):
            # Every receiver of a robot's observations took the same messages (its
            # agent, a restarted one, a process of several agents, the bridge): the first of a tick holds.
            robot = wanted.get(record.topic)
            if robot is not None:
                channels[record.id] = robot
            elif record.metadata.get("receiver") == BRIDGE and (m := _CMD_VEL.match(record.topic)):
                cmd_vels[record.id] = int(m.group(1))
        elif isinstance(record, Message) and record.channel_id in channels:
            robot = channels[record.channel_id]
            for obs in _observations(rejections, bytes(record.data)):
                out.setdefault((robot, obs.tick), tuple(tuple(r) for r in obs.readings))
        elif isinstance(record, Message) and record.channel_id in cmd_vels:
            twists.append((cmd_vels[record.channel_id], record.log_time, bytes(record.data)))
        elif isinstance(record, Footer):
            return


def _observations(rejections: Rejections, payload: bytes) -> list[Observation]:
    batch = rejections.decode_batch(Observation, payload)
    if batch is not None:
        return batch
    one = rejections.decode(Observation, payload)
    return [] if one is None else [one]


def write_mcap(run: RunData, stream: IO[bytes], distro: str = messages.DEFAULT_DISTRO) -> dict[str, int]:
    """Writes the run's topics to ``stream``; returns the messages per topic."""
    writer = Writer(stream, compression=CompressionType.ZSTD)
    writer.start(profile=PROFILE, library=f"formation_swarm {__version__}")
    schemas: dict[str, int] = {}
    channels: dict[str, int] = {}
    counts: Counter[str] = Counter()

    def add(name: str, msgtype: str, data: bytes, ns: int, seq: int) -> None:
        if name not in channels:
            if msgtype not in schemas:
                text = messages.msgdef(msgtype, distro).encode()
                schemas[msgtype] = writer.register_schema(name=msgtype, encoding=SCHEMA_ENCODING, data=text)
            channels[name] = writer.register_channel(name, MESSAGE_ENCODING, schemas[msgtype])
        writer.add_message(channels[name], log_time=ns, data=data, publish_time=ns, sequence=seq)
        counts[name] += 1

    sightings, received = read_wire(run)
    twists = [t for t in received if _is_twist(t[2], distro)]
    for k, state in enumerate(ticks(run, sightings)):
        ns = round(state.time_s * 1e9)
        for name, msgtype, msg in topics.tick_messages(state, distro=distro):
            add(name, msgtype, messages.encode(msgtype, msg, distro), ns, k)
        while twists and twists[0][1] <= ns:  # the Twists taken by this tick, after its topics
            robot, at, data = twists.pop(0)
            add(topics.topic(f"robot{robot}/cmd_vel"), topics.TWIST, data, at, counts[f"/robot{robot}/cmd_vel"])
    for robot, at, data in twists:  # after the last tick the run recorded
        add(topics.topic(f"robot{robot}/cmd_vel"), topics.TWIST, data, at, counts[f"/robot{robot}/cmd_vel"])
    writer.finish()
    return dict(counts)


def _is_twist(data: bytes, distro: str) -> bool:
    try:
        messages.decode(topics.TWIST, data, distro)
    except ValueError:
        return False
    return True


def export_mcap(run: RunData, path: Path, distro: str = messages.DEFAULT_DISTRO) -> dict[str, int]:
    """Writes ``path`` (beside it first, renamed once whole); the messages per topic."""
    part = path.with_name(f".{path.name}.part")
    try:
        with part.open("wb") as f:
            counts = write_mcap(run, f, distro)
        part.replace(path)
    finally:
        part.unlink(missing_ok=True)
    return counts
