"""The launcher's side of ``swarm host``: agents of a run placed on other machines.

:class:`HostClient` talks to one host (its liveliness token says whether it
is there; requests are protocol.hostmsg queries with a deadline each), and a
background thread polls every host of the run for the exit of its agents.
:class:`RemoteProc` gives a remote agent the part of ``subprocess.Popen`` the
launcher uses (poll, send_signal, wait), so the launcher watches, signals,
restarts and stops it as a local one; :class:`RemoteChild` is its Child.

An agent whose host is lost (its token went) reports ``LOST_CODE``.
"""

from __future__ import annotations

import contextlib
import signal
import subprocess
import threading
import time
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import zenoh

from formation_swarm.common.version import __version__
from formation_swarm.protocol.codec import DecodeError, Rejections
from formation_swarm.protocol.hostmsg import HostReply, HostRequest
from formation_swarm.protocol.keys import HostKeys
from formation_swarm.runtime.children import Child

REQUEST_TIMEOUT_S = 10.0
POLL_PERIOD_S = 0.25
LOST_CODE = 255  # the exit code of an agent whose host went: unknown
ACTIONS = {
    signal.SIGKILL: "kill",
    signal.SIGSTOP: "freeze",
    signal.SIGCONT: "thaw",
    signal.SIGTERM: "term",
    signal.SIGINT: "term",
}


# Why an answer from another session than the host's is refused (HostClient.ask).
ANOTHER_SESSION = "another session on the host's login"


class HostError(RuntimeError):
    """A host that is not there, refuses, or does not answer in time."""


class HostLoginTwice(HostError):
    """A host that answered from two sessions on its login: one is not the host."""


class HostClient:
    def __init__(self, sess: zenoh.Session, name: str) -> None:
        self.session = sess
        self.name = name
        self.keys = HostKeys(name)
        self.present = threading.Event()
        self.lost = False  # its token went after it had come
        self.reported = False
        self.info: HostReply | None = None
        self.codes: dict[str, int | None] = {}  # process -> exit code (None: running), from the last poll
        self.rejections = Rejections()
        self.session_id: str | None = None  # the Zenoh id of the session that answered first: the host's
        self.lock = threading.Lock()
        self.watcher = sess.liveliness().declare_subscriber(self.keys.alive, self._on_token, history=True)

    def _on_token(self, sample: zenoh.Sample) -> None:  # a Zenoh thread: state only
        if sample.kind == zenoh.SampleKind.PUT:
            self.present.set()
        elif self.present.is_set() and not self.lost:
            self.lost = True

    def ask(self, req: HostRequest, timeout_s: float = REQUEST_TIMEOUT_S) -> HostReply:
        """The host's answer; HostError when it refuses or does not answer within ``timeout_s``.

        Every session serving the host's key hears the request and every answer
        comes back (QueryTarget.ALL, no consolidation), so a second session on
        the host's login (a leaked login) is seen: at the first answer (the
        run's start) two answering sessions are HostLoginTwice, as neither can
        be told to be the host; after it, only the session that gave it is
        listened to, and the others' answers are counted as they come."""
        if self.lost:
            raise HostError(f"host {self.name} is lost")
        pinned = self.session_id
        answers: dict[str, HostReply] = {}
        over = threading.Event()

        def on_reply(r: zenoh.Reply) -> None:  # a Zenoh thread
            if r.ok is None:
                return
            judged = self._judge(r.ok.payload.to_bytes(), r.replier_id, pinned)
            with self.lock:
                if isinstance(judged, str):
                    self.rejections.reject(judged)
                    return
                answers.setdefault(*judged)
            if pinned is not None:
                over.set()  # the host's own answer: the others are counted as they come

        self.session.get(
            self.keys.ctl,
            zenoh.handlers.Callback(on_reply, over.set),  # over.set also once every session answered
            payload=req.to_bytes(),
            timeout=timeout_s,
            target=zenoh.QueryTarget.ALL,
            consolidation=zenoh.ConsolidationMode.NONE,
        )
        over.wait(timeout_s + 1.0)
        with self.lock:
            got = dict(answers)
        if len(got) > 1:
            raise HostLoginTwice(
                f"host {self.name} answered from {len(got)} sessions on its login: it is in use elsewhere "
                f"too (leaked?), so neither is trusted; make new host logins (swarm secure --hosts) and restart "
                "the hosts with them"
            )
        if not got:
            raise HostError(f"host {self.name} did not answer '{req.op}' within {timeout_s:g} s")
        sid, reply = next(iter(got.items()))
        self.session_id = sid
        if not reply.ok:
            raise HostError(f"host {self.name} refused to {req.op}: {reply.error}")
        return reply

    def _judge(self, payload: bytes, replier: Any, pinned: str | None) -> tuple[str, HostReply] | str:
        """An answer's session id and reply, or why it is refused."""
        try:
            reply = HostReply.from_bytes(payload)
        except DecodeError as exc:
            return exc.reason
        sid = "unknown" if replier is None else str(replier.zid)
        if reply.host != self.name:
            return "host mismatch"
        if pinned is not None and sid != pinned:
            return ANOTHER_SESSION
        return sid, reply

    def poll(self, run: str) -> None:
        if self.lost:
            return
        with contextlib.suppress(HostError):
            reply = self.ask(HostRequest("poll", __version__, run=run), timeout_s=2.0)
            with self.lock:
                self.codes.update({name: code for name, _pid, code in reply.processes})

    def close(self) -> None:
        with contextlib.suppress(zenoh.ZError):
            self.watcher.undeclare()


class Poller:
    """Polls every host of a run in a thread of its own until closed."""

    def __init__(self, clients: Sequence[HostClient], run: str) -> None:
        self.clients = list(clients)
        self.run = run
        self.done = threading.Event()
        self.thread = threading.Thread(target=self._loop, name="hosts-poller", daemon=True)
        self.thread.start()

    def _loop(self) -> None:
        while not self.done.wait(POLL_PERIOD_S):
            for c in self.clients:
                c.poll(self.run)

    def close(self) -> None:
        self.done.set()
        self.thread.join(timeout=5.0)


class RemoteProc:
    """An agent on a host, as the launcher sees a local process."""

    def __init__(self, client: HostClient, run: str, process: str, pid: int) -> None:
        self.client = client
        self.run = run
        self.process = process
        self.pid = pid
        self.args = [f"{client.name}:{process}"]
        self.returncode: int | None = None

    def poll(self) -> int | None:
        if self.returncode is None:
            if self.client.lost:
                self.returncode = LOST_CODE
            else:
                with self.client.lock:
                    self.returncode = self.client.codes.get(self.process)
        return self.returncode

    def wait(self, timeout: float | None = None) -> int:
        deadline = time.monotonic() + (timeout if timeout is not None else 3600.0)
        while self.poll() is None and time.monotonic() < deadline:
            time.sleep(POLL_PERIOD_S / 2)
        if self.returncode is None:
            raise subprocess.TimeoutExpired(self.args, timeout or 0.0)
        return self.returncode

    def send_signal(self, sig: int) -> None:
        if self.poll() is None:
            with contextlib.suppress(HostError):
                req = HostRequest("signal", __version__, run=self.run, process=self.process, action=ACTIONS[sig])
                self.client.ask(req)


@dataclass
class RemoteChild(Child):
    """An agent the launcher started on a host: its log is fetched at the end."""

    client: HostClient | None = None
    run: str = ""
    request: HostRequest | None = None

    @property
    def host(self) -> str:
        return "" if self.client is None else self.client.name

    def start(self) -> None:
        if self.client is None or self.request is None:
            raise ValueError("a remote child needs its host and its start request")
        reply = self.client.ask(self.request)
        self.proc = RemoteProc(self.client, self.run, self.name, reply.pid or 0)  # type: ignore[assignment]

    def fetch(self, stats: Path) -> str | None:
        """Write its log (its tail, from the host) and stats here; why not, or None."""
        if self.client is None or self.client.lost:
            return f"host {self.host} is lost; they stay on it"
        try:
            reply = self.client.ask(HostRequest("collect", __version__, run=self.run, process=self.name))
        except HostError as exc:
            return str(exc)
        self.log_path.write_text(reply.log)
        if reply.stats:
            (stats / f"{self.name}.json").write_text(reply.stats)
        return reply.error or None


def place(
    robots: Sequence[int],
    hosts: Sequence[str],
    allowed: Mapping[str, tuple[int, ...] | None],
    explicit: Mapping[int, str],
) -> dict[int, str]:
    """robot -> host: the explicit ones, the others round-robin over the hosts
    that may run them. ValueError naming a robot no host may run."""
    out: dict[int, str] = {}
    turn = 0
    for rid in robots:
        if rid in explicit:
            host = explicit[rid]
            if allowed.get(host) is not None and rid not in (allowed[host] or ()):
                raise ValueError(
                    f"robot {rid} is placed on host {host}, which may only run robots "
                    f"{', '.join(map(str, allowed[host] or ()))} (its --robots)"
                )
            out[rid] = host
            continue
        for i in range(len(hosts)):
            host = hosts[(turn + i) % len(hosts)]
            if allowed.get(host) is None or rid in (allowed[host] or ()):
                out[rid] = host
                turn = (turn + i + 1) % len(hosts)
                break
        else:
            raise ValueError(f"no host of {', '.join(hosts)} may run robot {rid} (see their --robots)")
    return out


def parse_placement(text: str) -> dict[int, str]:
    """``"1=a,2=b"`` -> {1: "a", 2: "b"}."""
    out: dict[int, str] = {}
    for part in (p.strip() for p in text.split(",") if p.strip()):
        rid, sep, host = part.partition("=")
        if not sep or not rid.strip().isdigit() or not host.strip():
            raise ValueError(f"a placement is ROBOT=HOST[,ROBOT=HOST...], e.g. 1=a,2=b, got {text!r}")
        out[int(rid)] = host.strip()
    return out
