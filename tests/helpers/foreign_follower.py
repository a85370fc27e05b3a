"""A follower agent written from docs/protocol.md alone.

    python tests/helpers/foreign_follower.py --id 2 --scenario S.toml --run RUN --connect tcp/HOST:PORT
                                     [--auth LOGIN.json] [--seed N] [--stats FILE]

It imports nothing of formation_swarm: raw ``zenoh`` and ``msgpack``, the
standard library, and the scenario file read with ``tomllib``. It stands for
an agent in another language, so it follows the document, not our code:
the client's configuration (the endpoint, the connect timeout and retry,
scouting off, the login file), the keys, the envelope and the checks it
needs, the start-up order (and the check for another agent of its robot),
the lockstep answer, the formation-code rule, the link-fault draws and the
end of the run (draining its sends). Its Zenoh session keeps Zenoh's default
transport (ours use the low-latency one), as a foreign agent would.

Its control law is a plain pursuit, not the paper's fuzzy controller: the
virtual target from the reading (docs/protocol.md, "Formation codes") goes
to the world frame through the robot's own pose, an alpha-beta filter
smooths it and estimates its velocity, and a point ``LOOKAHEAD_M`` ahead
of the robot tracks the target shifted as far along the reference's
heading (feedback linearisation of the unicycle).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import math
import queue
import signal
import struct
import sys
import time
import tomllib
from pathlib import Path
from typing import Any

import msgpack
import zenoh

# -- the wire (docs/protocol.md, "Messages") -----------------------------------
VERSION = 1
TAG_OBSERVATION, TAG_COMMAND, TAG_FORMATION_CODE, TAG_STATUS, TAG_BATCH = 1, 2, 3, 6, 100
FIELDS = {TAG_OBSERVATION: 4, TAG_FORMATION_CODE: 1, TAG_STATUS: 3}  # fields after the header
MAX_PAYLOAD_BYTES = 32 * 1024
MAX_ROBOT_ID = 10_000
MAX_TICK = 2**53
WORLD_ID = 0
STARTUP_TIMEOUT_S = 60.0  # for the router (connect), then for the world
RETRY = {"period_init_ms": 50, "period_max_ms": 500, "period_increase_factor": 2}  # while the router is not up
DRAIN_S = 5.0  # at the end, the longest wait for the router to have read our last messages
EXIT_DUPLICATE = 4
# A login's settings that name a file: relative to the login file's folder (docs/protocol.md).
FILE_SETTINGS = ("root_ca_certificate",)


# -- the control law ---------------------------------------------------------------
LOOKAHEAD_M = 0.3
GAIN_PER_S = 2.0
FILTER_G, FILTER_H = 0.4, 0.1  # alpha-beta filter on the target's world position
MAX_WHEEL_MPS = 3.5
LOST_AFTER_S = 1.0


class Rejected(Exception):
    def __init__(self, reason: str) -> None:
        super().__init__(reason)
        self.reason = reason


def _int(v: Any, lo: int, hi: int) -> int:
    if isinstance(v, bool) or not isinstance(v, int):
        raise Rejected("wrong type")
    if not lo <= v <= hi:
        raise Rejected("out of range")
    return v


def _float(v: Any) -> float:
    if isinstance(v, bool) or not isinstance(v, (int, float)):
        raise Rejected("wrong type")
    if not math.isfinite(v):
        raise Rejected("not finite")
    return float(v)


def decode(payload: bytes, tag: int, sender: int) -> list[Any]:
    """The fields after the header, ``[sender, seq, tick, ...]``, of a message
    of type ``tag`` from ``sender``; Rejected with the document's reason."""
    if len(payload) > MAX_PAYLOAD_BYTES:
        raise Rejected("oversized")
    try:
        raw = msgpack.unpackb(payload, raw=False)
    except (ValueError, msgpack.ExtraData, msgpack.FormatError, msgpack.StackError):
        raise Rejected("not msgpack") from None
    if not isinstance(raw, list) or len(raw) < 5:
        raise Rejected("wrong type")
    if raw[0] != tag:
        raise Rejected("wrong message type")
    if raw[1] != VERSION:
        raise Rejected("unknown version")
    if len(raw) != 5 + FIELDS[tag]:
        raise Rejected("wrong length")
    _int(raw[2], 0, MAX_ROBOT_ID)
    _int(raw[3], 0, MAX_TICK)
    _int(raw[4], 0, MAX_TICK)
    if raw[2] != sender:
        raise Rejected("out of range" if sender == WORLD_ID else "sender mismatch")
    return raw[2:]


def observation(payload: bytes) -> tuple[int, int, tuple[float, float, float], list[tuple[int, float, float, float]]]:
    """(seq, tick, pose, readings) of an Observation."""
    _, seq, tick, time_s, pose, readings, obstacles = decode(payload, TAG_OBSERVATION, WORLD_ID)
    _float(time_s)
    if not isinstance(pose, list) or len(pose) != 3:
        raise Rejected("wrong shape")
    x, y, th = (_float(v) for v in pose)
    if not isinstance(readings, list) or not isinstance(obstacles, list):
        raise Rejected("wrong type")
    out = []
    for rec in readings:
        if not isinstance(rec, list) or len(rec) != 4:
            raise Rejected("wrong shape")
        out.append((_int(rec[0], 1, MAX_ROBOT_ID), _float(rec[1]), _float(rec[2]), _float(rec[3])))
    return seq, tick, (x, y, th), out


def command(rid: int, seq: int, tick: int, left: float, right: float, code: int) -> bytes:
    return msgpack.packb([TAG_COMMAND, VERSION, rid, seq, tick, float(left), float(right), code, False])


# -- link faults (docs/protocol.md, "Link faults") -------------------------------
def link_uniform(seed: int, link: str, seq: int) -> float:
    h = hashlib.blake2b(digest_size=8, key=struct.pack("<q", seed))
    h.update(link.encode())
    h.update(struct.pack("<Q", seq % 2**64))
    return struct.unpack("<Q", h.digest())[0] / 2.0**64


class LinkIn:
    """Receiver side of one link: whether message ``seq`` got through."""

    def __init__(self, name: str, p: float, seed: int) -> None:
        self.name, self.p, self.seed, self.dropped = name, p, seed, 0

    def keeps(self, seq: int) -> bool:
        if self.p > 0 and link_uniform(self.seed, self.name, seq) < self.p:
            self.dropped += 1
            return False
        return True


# -- the scenario (docs/protocol.md, "Scenario values" and "Formation codes") ----
def formation_slots(sc: dict[str, Any]) -> list[dict[int, tuple[int, tuple[float, float]]]]:
    """Per formation code: follower id -> (reference id, offset (x_m, y_m))."""
    first = sc.get("leader", {}).get("id", 1)
    ids = list(range(first, first + sc["run"]["robots"]))
    out = []
    for spec in sc["formations"].values():  # file order: code 0, 1, ...
        shape = spec["shape"]
        if shape == "custom":
            slots = {
                int(r): (s["reference"], (float(s["offset"][0]), float(s["offset"][1])))
                for r, s in spec["slots"].items()
            }
        else:
            place, refs = _places(shape, spec, first, len(ids))
            slots = {
                rid: (ref, (place[rid][0] - place[ref][0], place[rid][1] - place[ref][1])) for rid, ref in refs.items()
            }
        out.append(slots)
    return out


def _places(
    shape: str, spec: dict[str, Any], first: int, n: int
) -> tuple[dict[int, tuple[float, float]], dict[int, int]]:
    """Every robot's place in the leader's frame, and every follower's reference."""
    lat, back = float(spec.get("lateral_m", 1.5)), float(spec.get("back_m", 1.5))
    spacing = float(spec.get("spacing_m", 1.5))
    place, refs = {first: (0.0, 0.0)}, {}
    if shape == "grid":
        cols = int(spec.get("columns", 3))
        c0 = (cols - 1) / 2
        order = sorted(range(cols), key=lambda c: (abs(c - c0), c))
        at = {}
        for k in range(n - 1):
            row, c = 1 + k // cols, order[k % cols]
            rid = first + 1 + k
            place[rid], at[row, c] = ((c - c0) * lat, -back * row), rid
            if row > 1:
                refs[rid] = at[row - 1, c]
            else:
                refs[rid] = first if abs(c - c0) <= 0.5 else at[1, c + 1 if c < c0 else c - 1]
        return place, refs
    for i in range(1, n):
        rank, side = (i + 1) // 2, (-1.0 if i % 2 == 1 else 1.0)
        if shape == "line":
            skip = 2 if spec.get("follow", "ahead") == "pairs" and i > 2 else 1
            place[first + i], refs[first + i] = (0.0, -spacing * i), first + i - skip
        elif shape == "abreast":
            place[first + i] = (side * spacing * rank, 0.0)
            refs[first + i] = first if rank == 1 else first + i - 2
        else:  # wedge
            place[first + i] = (side * lat * rank, -back * rank)
            refs[first + i] = first if i == 1 else first + 1 if i == 2 else first + i - 2
    return place, refs


# -- the control law -------------------------------------------------------------
class Pursuit:
    def __init__(self, dt_s: float, width_m: float, marker_offset_m: float) -> None:
        self.dt, self.width, self.d = dt_s, width_m, marker_offset_m
        self.p: tuple[float, float] | None = None  # target, world frame, m
        self.v = (0.0, 0.0)  # its velocity, m/s
        self.heading = 0.0  # the reference's heading, rad
        self.since_reading_s = math.inf

    def step(
        self, pose: tuple[float, float, float], reading: tuple[float, float, float] | None, offset: tuple[float, float]
    ) -> tuple[float, float]:
        x, y, th = pose
        if self.p is not None:  # predict
            self.p = (self.p[0] + self.v[0] * self.dt, self.p[1] + self.v[1] * self.dt)
        if reading is not None:
            rho, phi, beta = reading
            # The reference's centre, then the target, in our frame (x right, y ahead).
            cx, cy = rho * math.sin(beta) - self.d * math.sin(phi), rho * math.cos(beta) + self.d * math.cos(phi)
            ox, oy = offset
            bx = cx + ox * math.cos(phi) - oy * math.sin(phi)
            by = cy + ox * math.sin(phi) + oy * math.cos(phi)
            mx = x + bx * math.sin(th) + by * math.cos(th)
            my = y - bx * math.cos(th) + by * math.sin(th)
            if self.p is None:
                self.p = (mx, my)
            else:
                rx, ry = mx - self.p[0], my - self.p[1]
                self.p = (self.p[0] + FILTER_G * rx, self.p[1] + FILTER_G * ry)
                self.v = (self.v[0] + FILTER_H * rx / self.dt, self.v[1] + FILTER_H * ry / self.dt)
            self.heading = th + phi
            self.since_reading_s = 0.0
        else:
            self.since_reading_s += self.dt
        if self.p is None or self.since_reading_s > LOST_AFTER_S:
            return 0.0, 0.0
        # Track the point LOOKAHEAD_M ahead of us onto the target shifted as far ahead.
        qx, qy = x + LOOKAHEAD_M * math.cos(th), y + LOOKAHEAD_M * math.sin(th)
        gx = self.p[0] + LOOKAHEAD_M * math.cos(self.heading)
        gy = self.p[1] + LOOKAHEAD_M * math.sin(self.heading)
        ux, uy = self.v[0] + GAIN_PER_S * (gx - qx), self.v[1] + GAIN_PER_S * (gy - qy)
        v = ux * math.cos(th) + uy * math.sin(th)
        w = (-ux * math.sin(th) + uy * math.cos(th)) / LOOKAHEAD_M
        left, right = v - 0.5 * w * self.width, v + 0.5 * w * self.width
        scale = max(1.0, abs(left) / MAX_WHEEL_MPS, abs(right) / MAX_WHEEL_MPS)
        return left / scale, right / scale


# -- the agent ----------------------------------------------------------------------
class Agent:
    """One follower's answers to its inbox, with no I/O: ``on_formation`` queues
    a code, ``on_observation`` returns the command. Both raise Rejected."""

    def __init__(self, sc: dict[str, Any], rid: int, seed: int) -> None:
        self.leader = sc.get("leader", {}).get("id", 1)
        if not self.leader < rid < self.leader + sc["run"]["robots"]:
            raise ValueError(f"robot {rid} is not a follower of this scenario")
        self.rid = rid
        links = sc.get("links", {})
        self.obs_link = LinkIn(f"obs:0>{rid}", links.get("obs_drop", 0.0), seed)
        self.code_link = LinkIn(f"formation:{self.leader}>{rid}", links.get("formation_drop", 0.0), seed)
        self.slots = formation_slots(sc)
        self.code = list(sc["formations"]).index(sc["leader"]["formation"])
        self.reference, self.offset = self.slots[self.code][rid]
        robot = sc.get("robot", {})
        self.max_wheel = float(robot.get("max_wheel_mps", 3.0))
        self.law = Pursuit(sc["run"].get("dt_s", 0.05), robot.get("width_m", 0.5), robot.get("marker_offset_m", 0.1))
        self.pending: list[tuple[int, int]] = []  # (tick, code), in arrival order
        self.seq = 0
        self.stats: dict[str, Any] = {"robot": rid, "answered": 0, "no_reading": 0, "codes_received": 0}
        self.stats |= {"changes": [], "rejected": {}, "exit": None}

    def reject(self, reason: str) -> None:
        self.stats["rejected"][reason] = self.stats["rejected"].get(reason, 0) + 1

    def on_formation(self, payload: bytes) -> None:
        _, seq, tick, code = decode(payload, TAG_FORMATION_CODE, self.leader)
        _int(code, 0, 255)
        self.stats["codes_received"] += 1
        if not self.code_link.keeps(seq):
            return
        if code >= len(self.slots):
            raise Rejected("unknown formation")
        if self.rid not in self.slots[code]:
            raise Rejected("no slot in formation")
        self.pending.append((tick, code))

    def on_observation(self, payload: bytes) -> bytes:
        seq, tick, pose, readings = observation(payload)
        # Codes stamped before this tick take effect now (docs/protocol.md, "Formation codes").
        while self.pending and self.pending[0][0] < tick:
            _, code = self.pending.pop(0)
            if code != self.code:
                self.code = code
                self.reference, self.offset = self.slots[code][self.rid]
                self.stats["changes"].append({"tick": tick, "code": code})
        reading = None
        if self.obs_link.keeps(seq):  # a dropped observation is still answered, without its reading
            reading = next(((rho, phi, beta) for i, rho, phi, beta in readings if i == self.reference), None)
        self.stats["no_reading"] += reading is None
        left, right = self.law.step(pose, reading, self.offset)
        left, right = (max(-self.max_wheel, min(self.max_wheel, v)) for v in (left, right))  # beyond: rejected
        self.seq += 1
        self.stats["answered"] += 1
        return command(self.rid, self.seq, tick, left, right, self.code)


# -- the process -------------------------------------------------------------------
def client_config(endpoint: str, login: str | None) -> zenoh.Config:
    """A client of the run's router (docs/protocol.md, "The client's configuration")."""
    conf = zenoh.Config()
    conf.insert_json5("mode", '"client"')
    conf.insert_json5("connect/endpoints", json.dumps([endpoint]))
    conf.insert_json5("connect/timeout_ms", json.dumps(int(STARTUP_TIMEOUT_S * 1000)))  # the router may come later
    conf.insert_json5("connect/retry", json.dumps(RETRY))
    conf.insert_json5("scouting/multicast/enabled", "false")
    if login is not None:  # a JSON object: Zenoh configuration path -> value
        settings = json.loads(Path(login).read_text())
        for path, value in settings.items():
            if path.rsplit("/", 1)[-1] in FILE_SETTINGS and not Path(value).is_absolute():
                value = str(Path(login).absolute().parent / value)
            conf.insert_json5(path, json.dumps(value))
    return conf


def already_flown(session: zenoh.Session, key: str) -> bool:
    """Whether another session holds our robot's token (asked of the router)."""
    return any(reply.ok is not None for reply in session.liveliness().get(key, timeout=1.0))


def drain(session: zenoh.Session, key: str) -> None:
    """Until the router has read what we sent: it answers a query after the
    messages sent before it on our link (docs/protocol.md, "Leaving")."""
    for _ in session.liveliness().get(key, timeout=DRAIN_S):
        pass


def run(agent: Agent, run_id: str, endpoint: str, login: str | None, ask_first: bool = True) -> int:
    """Start-up, the inbox loop and the end of the run (docs/protocol.md); the exit code."""
    events: queue.SimpleQueue[tuple[Any, ...]] = queue.SimpleQueue()  # every callback hands its sample here
    for sig in (signal.SIGINT, signal.SIGTERM):
        signal.signal(sig, lambda *_: events.put(("stop",)))
    prefix, rid, stats = f"swarm/{run_id}", agent.rid, agent.stats
    with zenoh.open(client_config(endpoint, login)) as session:
        # 1. Subscribers: the inbox (remote origin: not our own puts), the status, the world's token.
        inbox = session.declare_subscriber(
            f"{prefix}/robot/{rid}/*",
            lambda s: events.put(("inbox", str(s.key_expr), s.payload.to_bytes())),
            allowed_origin=zenoh.Locality.REMOTE,
        )
        session.declare_subscriber(f"{prefix}/world/status", lambda s: events.put(("status", s.payload.to_bytes())))
        session.liveliness().declare_subscriber(
            f"{prefix}/alive/world/0", lambda s: events.put(("world", s.kind == zenoh.SampleKind.PUT)), history=True
        )
        # 2. Publishers. 3. The token once the world hears our commands, if no one else flies the robot.
        block = zenoh.CongestionControl.BLOCK
        cmd_pub = session.declare_publisher(f"{prefix}/robot/{rid}/cmd", congestion_control=block)
        tel_pub = session.declare_publisher(f"{prefix}/robot/{rid}/telemetry", congestion_control=block)
        cmd_pub.declare_matching_listener(lambda st: events.put(("matched", st.matching)))
        token_key = f"{prefix}/alive/agent/{rid}"
        matched, token = cmd_pub.matching_status.matching, None
        deadline = time.monotonic() + STARTUP_TIMEOUT_S
        code = 0
        while stats["exit"] is None:
            if matched and token is None:
                if ask_first and already_flown(session, token_key):
                    print(f"foreign follower {rid}: robot {rid} already has an agent", file=sys.stderr)
                    stats["exit"] = "another agent flies the robot"
                    return EXIT_DUPLICATE
                token = session.liveliness().declare_token(token_key)
            try:
                event = events.get(timeout=None if token else max(0.0, deadline - time.monotonic()))
            except queue.Empty:
                print(f"foreign follower {rid}: the world never matched our commands", file=sys.stderr)
                stats["exit"], code = "no world", 2
                break
            code = handle(agent, event, cmd_pub, code)
            matched = matched or (event[0] == "matched" and event[1])
        # The end: no more input, the end of our (empty) telemetry stream, our token, then drain.
        inbox.undeclare()
        tel_pub.put(msgpack.packb([TAG_BATCH, VERSION, []]))
        if token is not None:
            token.undeclare()
        drain(session, f"{prefix}/alive/world/0")
    return code


def handle(agent: Agent, event: tuple[Any, ...], cmd_pub: zenoh.Publisher, code: int) -> int:
    """One event of the loop; the exit code so far."""
    kind, stats = event[0], agent.stats
    if kind == "stop":
        stats["exit"] = "signal"
        return 130
    if kind == "world":
        stats["world_seen"] = stats.get("world_seen", False) or event[1]
        if stats["world_seen"] and not event[1]:
            stats["exit"] = "world gone"
        return code
    if kind not in ("status", "inbox"):
        return code
    try:
        if kind == "status":
            _, _, tick, _, state, _ = decode(event[1], TAG_STATUS, WORLD_ID)
            if state == "done":
                stats["exit"], stats["done_tick"] = "done", tick
        elif event[1].rsplit("/", 1)[-1] == "obs":
            cmd_pub.put(agent.on_observation(event[2]))
        elif event[1].rsplit("/", 1)[-1] == "formation":
            agent.on_formation(event[2])
        else:
            raise Rejected("unexpected key")
    except Rejected as exc:
        agent.reject(exc.reason)
    return code


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("--id", type=int, required=True)
    ap.add_argument("--scenario", required=True, help="the scenario file (TOML)")
    ap.add_argument("--run", required=True)
    ap.add_argument("--connect", required=True, metavar="ENDPOINT")
    ap.add_argument("--auth", metavar="LOGIN.json", help="the robot's login: Zenoh settings, path -> value (JSON)")
    ap.add_argument("--seed", type=int, help="overrides the scenario's run.seed (link faults)")
    ap.add_argument("--stats", help="write the agent's counters (JSON) here at exit")
    ap.add_argument(
        "--fly-beside",
        action="store_true",
        help="skip the query for another agent of the robot (for a test of the world's own rule only)",
    )
    args = ap.parse_args(argv)
    sc = tomllib.loads(Path(args.scenario).read_text())
    try:
        agent = Agent(sc, args.id, sc["run"].get("seed", 0) if args.seed is None else args.seed)
    except ValueError as exc:
        print(f"foreign follower: {exc}", file=sys.stderr)
        return 2
    code = run(agent, args.run, args.connect, args.auth, ask_first=not args.fly_beside)
    agent.stats.update(obs_dropped=agent.obs_link.dropped, formation_dropped=agent.code_link.dropped, code=agent.code)
    if args.stats:
        Path(args.stats).write_text(json.dumps(agent.stats, indent=2))
    return code


if __name__ == "__main__":
    sys.exit(main())
