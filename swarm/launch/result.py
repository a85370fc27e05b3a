"""How a run ended: its exit code, why it ended, and what the summary says
of its processes."""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

from formation_swarm.launch import remote
from formation_swarm.protocol.messages import Status
from formation_swarm.runtime import summary as summary_mod
from formation_swarm.runtime import wirefile
from formation_swarm.runtime.children import Child

INTERRUPTED, TIMED_OUT = 130, 124  # exit codes, as a shell reports Ctrl-C and timeout(1)


@dataclass
class RunResult:
    run_dir: Path
    summary: dict[str, Any] = field(repr=False)  # several kB: print res.summary to see it
    exit_code: int
    pids: dict[str, int] = field(default_factory=dict, repr=False)

    @property
    def recording(self) -> Path:
        return self.run_dir / "recording.rrd"


@dataclass
class Ending:
    """What ended the launcher's wait, besides the world's own end."""

    interrupted: bool = False  # Ctrl-C, SIGTERM or interrupt()
    timed_out: bool = False
    start_failed: bool = False  # a process ended with an error before tick 0
    limit_s: float | None = None  # the wall-clock limit that ended it, if one did

    @property
    def abrupt(self) -> bool:
        """Stopped without waiting for the processes to leave on their own."""
        return self.interrupted or self.timed_out or self.start_failed

    def exit_code(self, world_code: int | None) -> int:
        """130 interrupted, 124 timed out, 0 a world that ended well, else 1."""
        if self.interrupted:
            return INTERRUPTED
        if self.timed_out:
            return TIMED_OUT
        return 0 if world_code == 0 and not self.start_failed else 1


def end_reason(
    world: Mapping[str, Any],
    world_code: int | None,
    last: Status | None,
    events: Sequence[Mapping[str, Any]],
    ending: Ending,
) -> tuple[str, float | None]:
    """Why the run ended (summary.END_REASONS) and the sim time it reached;
    ``world``: the world's stats, ``world_code``: its exit code."""
    reached = world.get("sim_time_s")
    if reached is None and last is not None:
        reached = last.time_s
    if ending.interrupted:
        return summary_mod.INTERRUPTED, reached
    if any(e.get("event") == "start failed" for e in events):
        return summary_mod.START_FAILED, reached
    if ending.timed_out:
        return summary_mod.TIMED_OUT, reached
    if world_code == 0 and world.get("end_reason"):
        return world["end_reason"], world.get("ended_at_s")
    if world.get("end_reason") == summary_mod.PEERS_TIMEOUT:  # the agents that left when it gave up: not the cause
        return summary_mod.PEERS_TIMEOUT, None
    return summary_mod.ROLE_FAILED, reached


def place_exits(events: Sequence[dict[str, Any]], world: Mapping[str, Any]) -> None:
    """Each process that exited on its own placed at the tick the world saw
    its token go (``logger_lost``, a death by loss in ``deaths``): the
    launcher's own guess, the last status it had, lags by up to a status
    period of wall time (in lockstep, seconds of sim time)."""
    seen: dict[str, list[Mapping[str, Any]]] = {}
    if isinstance(lost := world.get("logger_lost"), Mapping):
        seen["logger"] = [lost]
    for d in world.get("deaths") or []:
        if isinstance(d, Mapping) and d.get("cause") == "lost":
            seen.setdefault(f"agent-{d.get('robot')}", []).append(d)
    for e in events:
        if e.get("event") != "exited" or "code" not in e or e.get("tick") is not None:
            continue  # not an exit, or one a kill placed already
        place = seen.get(str(e.get("process")).split(".")[0])
        if place:  # a restarted agent's exits, in order, with its losses in order
            at = place.pop(0)
            e.update(tick=at.get("tick"), sim_time_s=at.get("time_s"), placed_by="the world")


def fetch_failed_logs(children: Mapping[str, Child], stats: Path) -> None:
    """The log of each agent on a host that ended with an error on its own,
    fetched before its exit is told (its last lines on the console and in
    its event): the logs of remote agents come here only at the run's end."""
    for c in children.values():
        on_its_own = not c.reported and c.stop_sent_at is None
        if isinstance(c, remote.RemoteChild) and on_its_own and c.poll() not in (None, 0):
            c.fetch(stats)  # a host lost or silent: the exit is told without the log, as before


def merge_wire(run_dir: Path, say: Callable[[str], None]) -> None:
    """The receivers' spools merged into the run's wire.mcap (runtime.wirefile);
    a merge that fails leaves them, said in one line: swarm replay merges them later."""
    try:
        wirefile.merge_spools(run_dir, say)
    except Exception as exc:  # noqa: BLE001 - a full disk, a scenario.toml gone, a field mcap cannot hold, ...: the run's summary comes first
        say(f"[swarm] cannot merge the wire spools of {run_dir} into {wirefile.FILE_NAME}: {type(exc).__name__}: {exc}")


def processes_part(children: Mapping[str, Child], lost_hosts: Sequence[str]) -> dict[str, dict[str, Any]]:
    """Each process's pid, exit code and how long it took to leave once told to."""
    procs: dict[str, dict[str, Any]] = {}
    for name, c in children.items():
        exit_after_stop = None
        if c.stop_sent_at is not None and c.exited_at is not None:
            exit_after_stop = max(0.0, c.exited_at - c.stop_sent_at)
        procs[name] = {
            "pid": c.pid,
            "exit_code": None if c.proc is None else c.proc.returncode,
            "exit_after_stop_s": exit_after_stop,
        }
        if isinstance(c, remote.RemoteChild) and c.host in lost_hosts:
            procs[name].update(exit_code=None, lost_with_host=c.host)
    return procs
