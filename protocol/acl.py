"""Who may say what: one identity per role, and the router's access rules.

The router holds access rules that deny everything not granted
(``default_permission: deny``); each identity is granted its role's keys:

    world     publishes observations, truth, run status and fault calls; subscribes to commands
    agent-N   publishes robot N's command and telemetry (the leader also the
              formation codes, on one key for all followers); subscribes to
              robot N's inbox and the run status; a follower receives the codes
    logger    subscribes to the world's streams and the telemetry; publishes nothing
    observer  (on request) subscribes to the whole run and watches every token;
              publishes nothing, holds no token: a dashboard, a user's own monitor.
              It is not handed the world's wake-ups to itself (robot/wake/cmd)
    launcher  subscribes to the run status and the world's fault calls (it executes
              process faults: kill, start, freeze, thaw) and holds its token; in a
              run placed on machines, queries those hosts and watches their tokens
    host-NAME a machine's ``swarm host``, in a run placed on it: answers queries on
              its own key (swarmhost/NAME/ctl) and nothing else, holds its own
              token, watches the launcher's token; it publishes and subscribes
              nothing (the agents it starts log in with their own agent-N login)
    ros2-bridge (swarm run --ros2) subscribes to the truth, the status and the
              formation codes; for each robot left to ROS it stands in for its
              agent (robot N's inbox, command and token); publishes the ROS
              topics of its domain, but no ``cmd_vel``, and holds ROS tokens
    ros2      (on request) a ROS node's: reads every ROS topic of the domain,
              writes only the ``cmd_vel`` of the robots left to ROS; ROS tokens

Each role may also hold its own liveliness token and watch the tokens it
needs. An identity may also be bound to this machine (``local``: in a run
placed on hosts, the world and the logger beside the launcher, its
router): it is then granted nothing over any other network interface than
loopback, so its login is of no use from another machine. Receivers still check
every message (sender against key, tick window, physical bounds): the rules
stop strangers, the checks stop a role that misbehaves.

Facts measured with eclipse-zenoh 1.10.2: a publisher's puts only leave a
client once the router has told it of a matching subscriber, so every role
may learn the run's subscriber declarations (egress ``declare_subscriber``
on the whole run); rules apply only at the router that holds them.
"""

from __future__ import annotations

import socket
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from typing import Any

from formation_swarm.protocol.keys import HostKeys, Keys, RosKeys, check_host_name, check_robot_id


@dataclass(frozen=True)
class Grants:
    """What one identity may do, as key expressions."""

    publish: tuple[str, ...] = ()
    subscribe: tuple[str, ...] = ()
    # Data it is handed on keys it does not subscribe to by name: a put on a
    # wildcard key (the leader's formation codes) that its subscription matches.
    receive: tuple[str, ...] = ()
    # Keys its subscription matches that it is never handed (a deny rule: it wins over the allows).
    withheld: tuple[str, ...] = ()
    tokens: tuple[str, ...] = ()
    watch: tuple[str, ...] = ()
    serve: tuple[str, ...] = ()  # queryables it declares and answers
    ask: tuple[str, ...] = ()  # queryables it queries
    refused: tuple[str, ...] = ()  # keys it may never put, within those it may (a deny rule)


@dataclass(frozen=True)
class RosAccess:
    """A run's ROS 2 bridge: its domain and namespace, the robots left to ROS,
    and whether a ROS node's login (``ros2``) is let in too."""

    domain_id: int = 0
    namespace: str = ""
    robots: tuple[int, ...] = ()
    login: bool = False


def agent_user(robot_id: int) -> str:
    return f"agent-{check_robot_id(robot_id)}"


def host_user(name: str) -> str:
    return f"host-{check_host_name(name)}"


OBSERVER = "observer"  # the read-only login: swarm secure --observer, swarm run --observer-login
BRIDGE = "ros2-bridge"  # swarm run --ros2's bridge
ROS2 = "ros2"  # a ROS node's login: swarm run --ros2-login


def loopback_interfaces() -> list[str]:
    """This machine's loopback interfaces by name (Linux lo, macOS lo0)."""
    try:
        names = [name for _i, name in socket.if_nameindex() if name.startswith("lo")]
    except OSError:
        names = []
    return names or ["lo"]


def grants(
    run_id: str,
    robots: Sequence[int],
    leader_id: int,
    hosts: Sequence[str] = (),
    *,
    observer: bool = False,
    ros2: RosAccess | None = None,
) -> dict[str, Grants]:
    """Every identity of a run and what it may do (``hosts``: the machines'
    ``swarm host`` the run's agents are placed on; ``observer``: with the
    read-only login; ``ros2``: with the ROS 2 bridge)."""
    k = Keys(run_id)
    out = {
        "world": Grants(
            publish=(*(k.obs(r) for r in robots), k.truth, k.status, k.faults, k.world_wake)
            + ((k.sightings,) if ros2 is not None else ()),
            subscribe=(k.all_cmd,),
            tokens=(k.alive("world", 0),),
            watch=(f"{k.prefix}/alive/*/*",),
        ),
        "logger": Grants(
            subscribe=(k.world_all, k.all_telemetry, k.codes),  # the leader's codes: its switches, for the events
            tokens=(k.alive("logger", 0),),
            watch=(k.alive("world", 0), k.alive_all("agent")),  # the agents': a follower gone sends no more
        ),
        "launcher": Grants(
            subscribe=(k.status, k.faults),
            tokens=(k.alive("launcher", 0),),
            watch=(f"{k.prefix}/alive/*/*", *(HostKeys(h).alive for h in hosts)),
            ask=tuple(HostKeys(h).ctl for h in hosts),
        ),
    }
    if observer:  # everything of the run, nothing back: no publisher, no token, no query but liveliness
        # The router grants a declaration whose key expression lies within a granted one: watching
        # the whole run lets alive/** and alive/*/* both in. The world's wake-ups are its own
        # business, not a message: a zero-byte put no decoder reads.
        out[OBSERVER] = Grants(subscribe=(k.everything,), withheld=(k.world_wake,), watch=(k.everything,))
    if ros2 is not None:
        out.update(_ros_grants(k, ros2))
    for h in hosts:
        out[host_user(h)] = Grants(
            tokens=(HostKeys(h).alive,), watch=(k.alive("launcher", 0),), serve=(HostKeys(h).ctl,)
        )
    for rid in robots:
        out[agent_user(rid)] = Grants(
            publish=(k.cmd(rid), k.telemetry(rid), *((k.codes,) if rid == leader_id else ())),
            subscribe=(k.inbox(rid), k.status),
            receive=() if rid == leader_id else (k.codes,),
            tokens=(k.alive("agent", rid),),
            # Its own: is another agent flying it? The logger's: a follower leaves after it.
            watch=(k.alive("world", 0), k.alive("agent", rid), k.alive("logger", 0)),
        )
    return out


def _ros_grants(k: Keys, ros2: RosAccess) -> dict[str, Grants]:
    """The bridge's grants and, if asked, the ROS node's (:class:`RosAccess`)."""
    ros, mine = RosKeys(ros2.domain_id, ros2.namespace), tuple(ros2.robots)
    out = {
        BRIDGE: Grants(
            publish=(*(k.cmd(r) for r in mine), ros.topics),
            refused=(ros.any_cmd_vel,),  # what only a ROS node says
            subscribe=(
                k.truth,
                k.status,
                k.codes,
                k.sightings,
                *(k.inbox(r) for r in mine),
                *(ros.cmd_vel(r) for r in mine),
            ),
            tokens=(k.alive("bridge", 0), *(k.alive("agent", r) for r in mine), ros.graph),
            watch=(k.alive("world", 0), *(k.alive("agent", r) for r in mine), ros.graph),
        )
    }
    if ros2.login:
        graph = (ros.graph,)
        cmd_vels = tuple(ros.cmd_vel(r) for r in mine)
        out[ROS2] = Grants(publish=cmd_vels, subscribe=(ros.topics,), tokens=graph, watch=graph)
    return out


def _rule(
    rule_id: str, flow: str, messages: list[str], keys: Iterable[str], permission: str = "allow"
) -> dict[str, Any]:
    return {"id": rule_id, "permission": permission, "flows": [flow], "messages": messages, "key_exprs": list(keys)}


def access_control(
    run_id: str,
    robots: Sequence[int],
    leader_id: int,
    hosts: Sequence[str] = (),
    *,
    observer: bool = False,
    mtls: bool = False,
    local: Sequence[str] = (),
    ros2: RosAccess | None = None,
) -> dict[str, Any]:
    """The router's ``access_control`` section for one run: deny by default,
    each identity granted exactly its role's keys. With ``mtls``, an identity
    is its user name and its TLS certificate's common name, both: a stolen
    password without the certificate's key, or a certificate of another
    name, matches no one and is granted nothing. The users in ``local`` are
    granted their keys over loopback only (Zenoh matches a link's interface)."""
    k = Keys(run_id)
    learn = [k.everything, *([RosKeys(ros2.domain_id).topics] if ros2 is not None else [])]
    rules: list[dict[str, Any]] = [
        # Publishers only send once they know of a subscriber: everyone may learn the run's subscriptions.
        _rule("learn-subscribers", "egress", ["declare_subscriber"], learn),
    ]
    subjects: list[dict[str, Any]] = []
    policies: list[dict[str, Any]] = []
    for user, g in grants(run_id, robots, leader_id, hosts, observer=observer, ros2=ros2).items():
        own: list[dict[str, Any]] = []
        if g.publish:
            own.append(_rule(f"{user}-put", "ingress", ["put"], g.publish))
        if g.subscribe:
            own.append(_rule(f"{user}-sub", "ingress", ["declare_subscriber"], g.subscribe))
            own.append(_rule(f"{user}-data", "egress", ["put"], (*g.subscribe, *g.receive)))
        if g.withheld:
            own.append(_rule(f"{user}-withheld", "egress", ["put"], g.withheld, permission="deny"))
        if g.refused:
            own.append(_rule(f"{user}-refused", "ingress", ["put"], g.refused, permission="deny"))
        if g.tokens:
            own.append(_rule(f"{user}-token", "ingress", ["liveliness_token"], g.tokens))
        if g.watch:
            watching = ["declare_liveliness_subscriber", "liveliness_query"]
            own.append(_rule(f"{user}-watch", "ingress", watching, g.watch))
            own.append(_rule(f"{user}-seen", "egress", ["liveliness_token", "reply"], g.watch))
        if g.serve:  # declare its queryable, receive the queries, answer them
            own.append(_rule(f"{user}-serve", "ingress", ["declare_queryable", "reply"], g.serve))
            own.append(_rule(f"{user}-queries", "egress", ["query"], g.serve))
        if g.ask:  # learn the queryable, query it, receive the answers
            own.append(_rule(f"{user}-ask", "ingress", ["query"], g.ask))
            own.append(_rule(f"{user}-answers", "egress", ["declare_queryable", "reply"], g.ask))
        rules += own
        subject: dict[str, Any] = {"id": user, "usernames": [user]}
        if mtls:
            subject["cert_common_names"] = [user]
        if user in local:
            subject["interfaces"] = loopback_interfaces()
        subjects.append(subject)
        policies.append({"id": user, "rules": ["learn-subscribers", *(r["id"] for r in own)], "subjects": [user]})
    return {"enabled": True, "default_permission": "deny", "rules": rules, "subjects": subjects, "policies": policies}
