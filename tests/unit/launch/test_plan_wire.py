"""The wire recording in a run's command lines (launch.plan): on by default,
each local process given a spool named for it, a restarted agent a fresh
one; off with record_wire=False. No process is started here."""

from __future__ import annotations

from pathlib import Path

from formation_swarm.launch.plan import Plan, RunOptions


def _spools(lines: dict[str, list[str]]) -> dict[str, str | None]:
    return {
        name: argv[argv.index("--wire-spool") + 1] if "--wire-spool" in argv else None for name, argv in lines.items()
    }


def test_each_process_spools_to_a_file_of_its_own_by_default(tmp_path: Path) -> None:
    plan = Plan.make("fig11_obstacles", RunOptions(out=tmp_path / "run"))
    lines = plan.command_lines("tcp/127.0.0.1:9", {}, remote_agents=False, live=None)
    wire = tmp_path / "run" / "wire"
    assert _spools(lines) == {
        name: str(wire / f"{name}.spool") for name in ("world", "logger", "agent-1", "agent-2", "agent-3")
    }
    fresh = plan.restart_argv(lines["agent-3"], "agent-3.2")
    assert _spools({"agent-3.2": fresh}) == {"agent-3.2": str(wire / "agent-3.2.spool")}
    assert fresh[fresh.index("--stats") + 1] == str(tmp_path / "run" / "stats" / "agent-3.2.json")


def test_without_the_wire_recording_no_process_spools(tmp_path: Path) -> None:
    for opts in (
        RunOptions(out=tmp_path, record_wire=False),
        RunOptions(out=tmp_path, record_wire=False, logger=False),
    ):
        lines = Plan.make("fig11_obstacles", opts).command_lines("tcp/127.0.0.1:9", {}, remote_agents=False, live=None)
        assert set(_spools(lines).values()) == {None}
    # Without the logger the world and the agents still spool.
    lines = Plan.make("fig11_obstacles", RunOptions(out=tmp_path, logger=False)).command_lines(
        "tcp/127.0.0.1:9", {}, remote_agents=False, live=None
    )
    assert sorted(n for n, s in _spools(lines).items() if s) == ["agent-1", "agent-2", "agent-3", "world"]
