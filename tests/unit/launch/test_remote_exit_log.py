"""An agent on a host that fails on its own is told with the end of its log,
fetched from its host first: the logs of remote agents come to the run
folder only at the run's end (seen: "agent-2 exited with code 2 before the
run started ... (the log is empty)")."""

from __future__ import annotations

import re
import time
from pathlib import Path

from formation_swarm.common.version import __version__
from formation_swarm.launch.processes import Processes
from formation_swarm.launch.record import Journal
from formation_swarm.launch.remote import RemoteChild
from formation_swarm.launch.result import fetch_failed_logs
from formation_swarm.protocol.hostmsg import HostReply, HostRequest

LOG = "agent 2: /home/b/.cache/swarm-host/b/r1/scenario.toml: missing key run.robots\n"


class _Client:
    """A host that answers every collect with the agent's log and stats."""

    name = "b"
    lost = False

    def __init__(self) -> None:
        self.asked: list[HostRequest] = []

    def ask(self, req: HostRequest) -> HostReply:
        self.asked.append(req)
        return HostReply(ok=True, version=__version__, host="b", time_unix=time.time(), code=2, log=LOG, stats="{}")


class _Proc:
    def __init__(self, code: int | None) -> None:
        self.returncode = code
        self.pid = 4242

    def poll(self) -> int | None:
        return self.returncode


def _child(tmp_path: Path, client: _Client, code: int | None, name: str = "agent-2") -> RemoteChild:
    child = RemoteChild(name, [f"b:{name}"], tmp_path / "logs" / f"{name}.log", client=client, run="r1")  # type: ignore[arg-type]
    child.proc = _Proc(code)  # type: ignore[assignment]
    return child


def test_a_remote_agent_that_failed_before_the_run_is_told_with_its_log(tmp_path: Path) -> None:
    (tmp_path / "logs").mkdir()
    (tmp_path / "stats").mkdir()
    lines: list[str] = []
    procs = Processes(Journal(lines.append))
    client = _Client()
    procs.children = {"agent-2": _child(tmp_path, client, 2), "agent-3": _child(tmp_path, client, None, "agent-3")}
    fetch_failed_logs(procs.children, tmp_path / "stats")
    procs.report_exits(-1.0, started=False, lost_hosts=[])
    assert [(r.op, r.process) for r in client.asked] == [("collect", "agent-2")]  # the running one is left alone
    told, *tail = lines
    assert re.findall(r"(agent-\d+) exited with code (\d+)", told) == [("agent-2", "2")]
    assert "before the run started" in told
    assert told.endswith(f" {tmp_path / 'logs' / 'agent-2.log'}:")  # its log, whose end follows
    assert tail == [f"  | {LOG.strip()}"]
    (event,) = procs.journal.events
    assert (event["process"], event["code"], event["log_tail"]) == ("agent-2", 2, [LOG.strip()])
    fetch_failed_logs(procs.children, tmp_path / "stats")  # told once: fetched once
    assert len(client.asked) == 1


def test_a_remote_agent_stopped_by_the_launcher_is_not_fetched_early(tmp_path: Path) -> None:
    client = _Client()
    child = _child(tmp_path, client, -15)
    child.stop_sent_at = time.monotonic()
    fetch_failed_logs({"agent-2": child}, tmp_path / "stats")
    assert client.asked == []
