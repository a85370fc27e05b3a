"""rmw_zenoh's wire format, for a process that is not ROS: keys, attachments,
liveliness tokens, and a publisher and a subscriber that a ROS 2 node running
``rmw_zenoh_cpp`` (Jazzy, Kilted) sees and hears as its own kind.

As rmw_zenoh's docs/design.md gives them:

    topic_key(domain, topic, msgtype, distro)
        "<domain>/<topic without leading slash>/<pkg::msg::dds_::Name_>/RIHS01_<hex>"
    attachment(seq, stamp_ns, gid) -> 33 bytes
        int64 LE sequence number, int64 LE source timestamp (ns since the
        epoch), one byte 16 (the GID's length), the 16-byte GID
    parse_attachment(data) -> Attachment(seq, stamp_ns, gid); ValueError if malformed
    node_key(NodeInfo(domain, zid, name, node_id=0, namespace="", enclave=""))
        "@ros2_lv/<domain>/<zid>/<node id>/<node id>/NN/<enclave>/<namespace>/<name>"
    entity_key(kind, node_info, entity_id, topic, msgtype, qos=..., distro=...)
        "@ros2_lv/<domain>/<zid>/<node id>/<entity id>/<MP|MS>/<enclave>/<namespace>/<name>/
         <topic>/<type>/<hash>/<qos>"

Inside a token a name's ``/`` is ``%`` and an empty name is ``%``; ``zid`` is
the Zenoh session id in hex. ``<qos>`` is rmw_zenoh's compact form, each
field empty where it equals rmw_zenoh's default (reliable, volatile, keep
last 42): ``::,10:,:,:,,`` is a depth of 10.

Objects (zenoh-python; each undeclares what it declared on ``close()``):

    Node(session, name, namespace="", domain=0, distro="jazzy")   an NN token
    Publisher(node, topic, msgtype, depth=10, block=False)
        an MP token; .put(msg, stamp_ns=None); ``block``: Zenoh's congestion control
        BLOCK (a sample waits for room on a congested link) instead of DROP (its default)
    Subscriber(node, topic, msgtype, callback, depth=10, raw=None)
        an MS token; callback(msg, Attachment | None) for each sample that decodes,
        on Zenoh's receiving thread in the order samples came (keep it short);
        .received and .rejected count the samples; a sample that does not decode,
        or that ``check`` refuses (default: any non-finite float), is counted in
        .rejected and dropped, never raised into Zenoh's thread. With
        ``raw(payload, attachment)``, Zenoh's thread hands it each sample's bytes
        instead, and its owner decodes them later by ``.intake.take``
    Intake(msgtype, callback, check=finite)       that receiving end alone, .take(payload, attachment)

A relative topic is put under the node's namespace.
"""

from __future__ import annotations

import hashlib
import itertools
import math
import struct
import threading
import time
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any, NamedTuple

import numpy as np
import zenoh

from formation_swarm.ros2 import messages

ADMIN_SPACE = "@ros2_lv"
GID_BYTES = 16
ATTACHMENT_BYTES = 8 + 8 + 1 + GID_BYTES
_ATTACHMENT = struct.Struct("<qqB16s")
DEFAULT_DEPTH = 42  # rmw_zenoh's default history depth: the QoS field left empty
KINDS = ("MP", "MS")  # message publisher, message subscription


class Attachment(NamedTuple):
    seq: int
    stamp_ns: int
    gid: bytes


def qualify(topic: str, namespace: str = "") -> str:
    """The fully qualified name of ``topic`` (``/a/b``); a relative one is put
    under ``namespace``. ValueError for a name ROS would refuse."""
    ns = "/" + namespace.strip("/") if namespace.strip("/") else ""
    full = topic if topic.startswith("/") else f"{ns}/{topic}"
    parts = full[1:].split("/")
    if not topic or not all(p and (p[0].isalpha() or p[0] == "_") for p in parts):
        raise ValueError(f"topic must be a ROS name (/a/b, tokens that start with a letter), got {topic!r}")
    if not all((c.isascii() and c.isalnum()) or c in "_/" for c in full):
        raise ValueError(f"topic may hold letters, digits, _ and / only, got {topic!r}")
    return full


def mangle(name: str) -> str:
    """A name inside a liveliness token: ``/`` as ``%``; an empty name is ``%``."""
    return name.replace("/", "%") if name else "%"


def topic_key(domain: int, topic: str, msgtype: str, distro: str = messages.DEFAULT_DISTRO) -> str:
    """The Zenoh key rmw_zenoh puts the samples of ``topic`` (fully qualified) on."""
    name, hashed = messages.dds_type_name(msgtype), messages.type_hash(msgtype, distro)
    return f"{_domain(domain)}/{qualify(topic)[1:]}/{name}/{hashed}"


def qos_key(depth: int = 10, *, best_effort: bool = False, transient_local: bool = False) -> str:
    """rmw_zenoh's compact QoS field of a token (qos_to_keyexpr)."""
    if not 0 < depth < 2**31:
        raise ValueError(f"depth must be within 1..2**31-1, got {depth!r}")
    reliability = "2" if best_effort else ""  # RMW_QOS_POLICY_RELIABILITY_BEST_EFFORT
    durability = "1" if transient_local else ""  # RMW_QOS_POLICY_DURABILITY_TRANSIENT_LOCAL
    history = "" if depth == DEFAULT_DEPTH else str(depth)
    return f"{reliability}:{durability}:,{history}:,:,:,,"


@dataclass(frozen=True, slots=True, kw_only=True)
class NodeInfo:
    """What a node's tokens say of it; ``zid``: its Zenoh session id in hex."""

    domain: int
    zid: str
    name: str
    node_id: int = 0
    namespace: str = ""
    enclave: str = ""


def node_key(info: NodeInfo) -> str:
    """The liveliness token of a node (entity kind NN)."""
    head = (ADMIN_SPACE, _domain(info.domain), info.zid, str(info.node_id), str(info.node_id), "NN")
    names = (mangle(info.enclave.rstrip("/")), mangle(_namespace(info.namespace)), _node_name(info.name))
    return "/".join(head + names)


def entity_key(
    kind: str,
    node: NodeInfo,
    entity_id: int,
    topic: str,
    msgtype: str,
    *,
    qos: str = "::,10:,:,:,,",
    distro: str = messages.DEFAULT_DISTRO,
) -> str:
    """The liveliness token of a publisher (``MP``) or subscription (``MS``) of
    ``node`` on a fully qualified ``topic``."""
    if kind not in KINDS:
        raise ValueError(f"kind must be one of {', '.join(KINDS)}, got {kind!r}")
    parts = node_key(node).split("/")
    parts[4:6] = [str(entity_id), kind]
    fields = (mangle(qualify(topic)), messages.dds_type_name(msgtype), messages.type_hash(msgtype, distro), qos)
    return "/".join(parts + list(fields))


def attachment(seq: int, stamp_ns: int, gid: bytes) -> bytes:
    """The 33 bytes rmw_zenoh attaches to each sample."""
    if len(gid) != GID_BYTES:
        raise ValueError(f"gid must be {GID_BYTES} bytes, got {len(gid)}")
    return _ATTACHMENT.pack(seq, stamp_ns, GID_BYTES, bytes(gid))


def parse_attachment(data: bytes | bytearray | memoryview) -> Attachment:
    """The fields of a sample's attachment; ValueError unless it is the 33 bytes."""
    if len(data) != ATTACHMENT_BYTES:
        raise ValueError(f"an attachment is {ATTACHMENT_BYTES} bytes, got {len(data)}")
    seq, stamp_ns, n, gid = _ATTACHMENT.unpack(bytes(data))
    if n != GID_BYTES:
        raise ValueError(f"an attachment's GID length byte must be {GID_BYTES}, got {n}")
    return Attachment(seq, stamp_ns, gid)


def gid_of(token_key: str) -> bytes:
    """An entity's 16-byte GID, a hash of its token (rmw_zenoh hashes the same
    text with XXH3-128; only its uniqueness matters to a receiver)."""
    return hashlib.blake2b(token_key.encode(), digest_size=GID_BYTES).digest()


def finite(msg: Any) -> bool:
    """Whether every float in ``msg`` (nested messages and arrays too) is finite."""
    stack = [msg]
    while stack:
        value = stack.pop()
        if isinstance(value, float):
            if not math.isfinite(value):
                return False
        elif isinstance(value, np.ndarray):
            if value.dtype.kind == "f" and not np.isfinite(value).all():
                return False
        elif isinstance(value, list):
            stack.extend(value)
        elif hasattr(value, "__dataclass_fields__"):
            stack.extend(getattr(value, f) for f in value.__dataclass_fields__ if f != "__msgtype__")
    return True


def _domain(domain: int) -> str:
    if isinstance(domain, bool) or not isinstance(domain, int) or not 0 <= domain <= 232:
        raise ValueError(f"domain must be a ROS domain id within 0..232, got {domain!r}")
    return str(domain)


def _namespace(namespace: str) -> str:
    return "/" + namespace.strip("/") if namespace.strip("/") else ""


def _node_name(name: str) -> str:
    if not name or not (name[0].isalpha() or name[0] == "_") or not all(c.isalnum() or c == "_" for c in name):
        raise ValueError(f"node name must be letters, digits and _, starting with a letter, got {name!r}")
    return name


class Node:
    """A ROS 2 node as rmw_zenoh announces it: its NN token on ``session``."""

    def __init__(
        self,
        session: zenoh.Session,
        name: str,
        *,
        namespace: str = "",
        domain: int = 0,
        distro: str = messages.DEFAULT_DISTRO,
        node_id: int = 0,
    ) -> None:
        messages.typestore(distro)  # an unknown distro fails here
        self.session = session
        self.name = name
        self.namespace = _namespace(namespace)
        self.domain = domain
        self.distro = distro
        self.node_id = node_id
        self.zid = str(session.zid())
        self.info = NodeInfo(domain=domain, zid=self.zid, name=name, node_id=node_id, namespace=self.namespace)
        self.key = node_key(self.info)
        self._ids = itertools.count(node_id + 1)  # entity ids unique within the session
        self._token = session.liveliness().declare_token(self.key)

    def entity(self, kind: str, topic: str, msgtype: str, qos: str) -> str:
        """A new entity's token key."""
        return entity_key(kind, self.info, next(self._ids), topic, msgtype, qos=qos, distro=self.distro)

    def close(self) -> None:
        self._token.undeclare()


class Publisher:
    """A ROS 2 publisher of ``msgtype`` on ``topic``: samples with the attachment
    ROS subscribers expect, the sequence number counting from 1."""

    def __init__(self, node: Node, topic: str, msgtype: str, *, depth: int = 10, block: bool = False) -> None:
        self.topic = qualify(topic, node.namespace)
        self.msgtype = msgtype
        self.distro = node.distro
        self.key = topic_key(node.domain, self.topic, msgtype, node.distro)
        self.token_key = node.entity("MP", self.topic, msgtype, qos_key(depth))
        self.gid = gid_of(self.token_key)
        self.seq = 0
        congestion = zenoh.CongestionControl.BLOCK if block else zenoh.CongestionControl.DROP
        self._pub = node.session.declare_publisher(self.key, congestion_control=congestion)
        self._token = node.session.liveliness().declare_token(self.token_key)

    def put(self, msg: Any, stamp_ns: int | None = None) -> None:
        """Serializes ``msg`` and puts it; ``stamp_ns``: its source timestamp
        (default: the wall clock, as rmw_zenoh stamps)."""
        self.put_bytes(messages.encode(self.msgtype, msg, self.distro), stamp_ns)

    def put_bytes(self, payload: bytes, stamp_ns: int | None = None) -> None:
        """Puts an already serialized message (CDR with its header)."""
        self.seq += 1
        when = time.time_ns() if stamp_ns is None else stamp_ns
        self._pub.put(payload, attachment=attachment(self.seq, when, self.gid))

    @property
    def matched(self) -> bool:
        """Whether a subscriber's declaration has reached this publisher (Zenoh's
        matching status): a ROS node's liveliness token may come before it."""
        return bool(self._pub.matching_status.matching)

    def close(self) -> None:
        self._token.undeclare()
        self._pub.undeclare()


class Intake:
    """A subscription's receiving end, without Zenoh: decodes, checks, counts and
    hands a sample on; nothing it is given raises."""

    def __init__(
        self,
        msgtype: str,
        callback: Callable[[Any, Attachment | None], None],
        *,
        distro: str = messages.DEFAULT_DISTRO,
        check: Callable[[Any], bool] = finite,
    ) -> None:
        self.msgtype = msgtype
        self.distro = distro
        self.received = 0
        self.rejected = 0
        self._callback = callback
        self._check = check
        self._lock = threading.Lock()  # Zenoh may call from more than one thread

    def take(self, payload: bytes, raw_attachment: bytes | None) -> bool:
        """One sample's bytes: True when it decoded and passed the check (and was
        handed to the callback), else counted in ``rejected``."""
        with self._lock:
            self.received += 1
        try:
            msg = messages.decode(self.msgtype, payload, self.distro)
            meta = None if raw_attachment is None else parse_attachment(raw_attachment)
        except ValueError:
            msg = None
        if msg is None or not self._check(msg):
            with self._lock:
                self.rejected += 1
            return False
        self._callback(msg, meta)
        return True


class Subscriber:
    """A ROS 2 subscription of ``msgtype`` on ``topic``: its samples go through an
    :class:`Intake` (``received``, ``rejected``)."""

    def __init__(
        self,
        node: Node,
        topic: str,
        msgtype: str,
        callback: Callable[[Any, Attachment | None], None],
        *,
        depth: int = 10,
        check: Callable[[Any], bool] = finite,
        raw: Callable[[bytes, bytes | None], None] | None = None,
    ) -> None:
        self.topic = qualify(topic, node.namespace)
        self.msgtype = msgtype
        self.key = topic_key(node.domain, self.topic, msgtype, node.distro)
        self.token_key = node.entity("MS", self.topic, msgtype, qos_key(depth))
        self.intake = Intake(msgtype, callback, distro=node.distro, check=check)
        self._raw = raw
        # On the thread that received the sample, not one thread per subscriber
        # (zenoh-python's default): a node's subscriptions then see the samples of
        # a link in the order they came (/robotN/odom of tick t - 1 before /clock t).
        handler = zenoh.handlers.Callback(self._on_sample, indirect=False)
        self._sub = node.session.declare_subscriber(self.key, handler)
        self._token = node.session.liveliness().declare_token(self.token_key)

    @property
    def received(self) -> int:
        return self.intake.received

    @property
    def rejected(self) -> int:
        return self.intake.rejected

    def _on_sample(self, sample: zenoh.Sample) -> None:
        att = sample.attachment
        payload, attached = sample.payload.to_bytes(), None if att is None else att.to_bytes()
        if self._raw is not None:
            self._raw(payload, attached)
        else:
            self.intake.take(payload, attached)

    def close(self) -> None:
        self._token.undeclare()
        self._sub.undeclare()
