"""The swarm command line with bad input: one line on stderr naming the flag
and the value, exit code 2, no traceback and nothing started or created; a
role that crashes is named with its exit code and the end of its log."""

from __future__ import annotations

import argparse
import io
import json
import socket
import subprocess
import sys
import time
from concurrent.futures import ThreadPoolExecutor
from dataclasses import dataclass
from importlib.metadata import version
from pathlib import Path

import pytest

from formation_swarm import __version__, cli
from formation_swarm.launch.console import print_result
from formation_swarm.launch.launcher import Launch, free_port
from formation_swarm.report import build as report
from formation_swarm.report import compare, export
from formation_swarm.runtime import cliargs
from formation_swarm.studies import results, sweep
from tests.helpers import SCENARIOS

SWARM = Path(sys.executable).parent / "swarm"
COMMAND = [str(SWARM)] if SWARM.exists() else [sys.executable, "-m", "formation_swarm.cli"]
MAX_SEED = str(2**63 - 1)
LIVE = "rerun+http://127.0.0.1:9876/proxy"

RUN = ["run", "fig11_obstacles"]
SWEEP = ["sweep", "fig11_obstacles", "--seeds", "2"]
SEED_RANGE = "must be an integer in [0, 2**63 - 1]"
TICKS = "must be at most 2**53 ticks of run.dt_s = 0.05 s (about 4.504e+14 s, the most a message's tick count carries)"
# Files a case reads, made in its folder when its argv names them.
INPUT_FILES = {
    "deep_arrays.toml": "[run]\nname = " + "[" * 100_000 + "]" * 100_000 + "\n",
    "deep_tables.toml": "x = " + "{a = " * 5_000 + "1" + "}" * 5_000 + "\n",
}
# id: (argv, a fragment of the one line on stderr); {tmp} is the test's folder, which holds a_file.
REJECTED = {
    "run: negative seed": ([*RUN, "--seed", "-3"], f"argument --seed: {SEED_RANGE}, got '-3'"),
    "run: fractional seed": ([*RUN, "--seed", "1.5"], f"argument --seed: {SEED_RANGE}, got '1.5'"),
    "run: seed past 2**63 - 1": ([*RUN, "--seed", str(2**63)], f"argument --seed: {SEED_RANGE}, got '{2**63}'"),
    "run: seed in --set": ([*RUN, "--set", "run.seed=-3"], "run.seed must be in [0, 2**63 - 1], got -3"),
    "run: kill the world": ([*RUN, "--kill", "world@5"], "cannot kill the world"),
    "run: --out empty": ([*RUN, "--out", ""], "--out '': an empty name"),
    "run: --out holds a run": ([*RUN, "--out", "{tmp}/old_run"], "already holds a run (summary.json)"),
    "world: --peers-timeout past the clock": (
        ["world", "--scenario", "fig11_obstacles", "--run", "x", "--peers-timeout", "1e12"],
        "argument --peers-timeout: must be a number of seconds in (0, 1e+06], got '1e12'",
    ),
    "run: kill an unknown process": ([*RUN, "--kill", "agent-9@5"], "no robot 9 in this run; robots are 1, 2, 3"),
    "run: kill after the end": ([*RUN, "--kill", "agent-2@1e9"], "starts at 1e+09 s, at or after the run's end (56 s;"),
    "run: a fault of no kind": ([*RUN, "--fault", "explode agent-2@5s"], "unknown fault kind 'explode'; kinds: kill"),
    "run: a misspelt fault kind": ([*RUN, "--fault", "kil agent-2@5s"], "fault kind 'kil'; did you mean 'kill'?"),
    "run: a fault without its parameter": ([*RUN, "--fault", "drop obs:2@5s"], "fault 'drop' needs p=VALUE"),
    "run: a fault on the world": ([*RUN, "--fault", "freeze world@5s for=1s"], "cannot freeze the world"),
    "run: a fault on an unknown robot": ([*RUN, "--fault", "blackout 7@5s"], "no robot 7 in this run"),
    "run: two faults on one process at once": (
        [*RUN, "--fault", "freeze agent-2@5s for=3s", "--fault", "kill agent-2@6s"],
        "overlaps 'freeze agent-2@5s for=3s' on the same process",
    ),
    "run: logger fault without a logger": (
        [*RUN, "--no-logger", "--kill", "logger@5"],
        "cannot kill 'logger' (the run has no logger: --no-logger",
    ),
    "run: kill without a time": ([*RUN, "--kill", "agent-2"], "a kill is PROCESS@SECONDS"),
    "run: zero timeout": ([*RUN, "--timeout", "0"], "argument --timeout: must be a number of seconds > 0, got '0'"),
    "run: NaN timeout": ([*RUN, "--timeout", "nan"], "argument --timeout: must be a number of seconds > 0, got 'nan'"),
    "run: --out is a file": ([*RUN, "--out", "{tmp}/a_file"], "--out {tmp}/a_file: is an existing file, not a folder"),
    "run: --out under a file": (
        [*RUN, "--out", "{tmp}/a_file/run"],
        "--out {tmp}/a_file/run: cannot create a writable folder there (Not a directory)",
    ),
    "run: --out in /proc": ([*RUN, "--out", "/proc/x"], "--out /proc/x: cannot create a writable folder there"),
    "run: port 0": ([*RUN, "--serve-web", "--grpc-port", "0"], "argument --grpc-port: must be in [1, 65535], got '0'"),
    "run: port 70000": (
        [*RUN, "--serve-web", "--web-port", "70000"],
        "argument --web-port: must be in [1, 65535], got '70000'",
    ),
    "run: port without --serve-web": (
        [*RUN, "--grpc-port", "9000"],
        "argument --grpc-port: only used with --serve-web",
    ),
    "run: --rt-priority in lockstep": (
        [*RUN, "--rt-priority", "5"],
        "argument --rt-priority: only used with --mode realtime, got it in lockstep (see swarm run --help)",
    ),
    "run: --rt-priority 100": (
        [*RUN, "--mode", "realtime", "--rt-priority", "100"],
        "argument --rt-priority: must be in [0, 99], got '100'",
    ),
    "run: one port for two": (
        [*RUN, "--serve-web", "--grpc-port", "9000", "--web-port", "9000"],
        "arguments --grpc-port and --web-port: must differ, got 9000 for both",
    ),
    "run: --live without a logger": (
        [*RUN, "--no-logger", "--live", LIVE],
        "argument --live: the logger does the streaming; drop --no-logger",
    ),
    "run: --live not a viewer address": (
        [*RUN, "--live", "127.0.0.1:9876"],
        "argument --live: must be a viewer address like rerun+http://HOST:PORT/proxy, got '127.0.0.1:9876'",
    ),
    "run: unknown mode": ([*RUN, "--mode", "fast"], "argument --mode: invalid choice: 'fast'"),
    "run: unknown scenario key": ([*RUN, "--set", "run.sede=1"], "unknown key run.sede; did you mean 'seed'?"),
    "run: --set without a value": ([*RUN, "--set", "nonsense"], "--set takes KEY=VALUE"),
    "run: a waypoint of NaN": (
        [*RUN, "--set", "leader.waypoints=[[0.0,0.0],[nan,80.0]]"],
        "leader.waypoints[1][0] must be a finite number, got nan",
    ),
    "run: a duration of more ticks than a message counts": (
        [*RUN, "--set", "run.duration_s=1e300"],
        f"run.duration_s {TICKS}, got 1e+300",
    ),
    "run: a duration of 400 digits": (
        [*RUN, "--set", "run.duration_s=1" + "0" * 400],
        "run.duration_s must be an integer in [-2**63, 2**63 - 1] (64 bits), got one of 1329 bits",
    ),
    "run: a hold window of more ticks than a run counts": (
        [*RUN, "--set", "controller.hold_after_s=1e300"],
        f"controller.hold_after_s {TICKS}, got 1e+300",
    ),
    "run: a negative static V_N": (
        [*RUN, "--set", "controller.vn=-3"],
        "(with controller.vn = -3): controller.vn must be 'dynamic' or a number > 0, got -3",
    ),
    "run: a run name in letters beyond ASCII": (
        [*RUN, "--set", "run.name=café"],
        "run.name must write its letters and digits in ASCII (the run's id and folder are made of them;",
    ),
    "run: a file of arrays 100,000 deep": (
        ["run", "{tmp}/deep_arrays.toml"],
        "{tmp}/deep_arrays.toml: arrays or inline tables nested more than 32 deep",
    ),
    "run: a file of inline tables 5,000 deep": (
        ["run", "{tmp}/deep_tables.toml"],
        "{tmp}/deep_tables.toml: arrays or inline tables nested more than 32 deep",
    ),
    "run: a kill at 1e308 s": (
        [*RUN, "--fault", "kill agent-3@1e308s"],
        "fault 'kill agent-3@1e+308s': starts at 1e+308 s, at or after the run's end (56 s;",
    ),
    "run: a fault lasting more ticks than a run counts": (
        [*RUN, "--fault", "drop obs:2@1s for=1e308s p=0.5"],
        f"for {TICKS}, got 1e+308 s",
    ),
    "run: a duration under one tick": (
        [*RUN, "--set", "run.duration_s=0.01"],
        "run.duration_s: at least one control step (run.dt_s = 0.05 s), got 0.01",
    ),
    "run: a key set twice": (
        [*RUN, "--set", "leader.speed_mps=1.6", "--set", "leader.speed_mps=2"],
        "--set leader.speed_mps is given twice (1.6 and 2): give it once",
    ),
    "run: --seed and another run.seed": (
        [*RUN, "--seed", "3", "--set", "run.seed=5"],
        "seed 3 and run.seed 5 in the overrides: give the seed once",
    ),
    "run: unknown scenario": (
        ["run", "fig11_obstacle"],
        "no scenario file or shipped scenario named 'fig11_obstacle'; did you mean 'fig11_obstacles'?",
    ),
    "run: no scenario": (["run"], "the following arguments are required: scenario"),
    "run: unknown flag": ([*RUN, "--bogus"], "unrecognized arguments: --bogus (see swarm run --help)"),
    "unknown command": (["fly"], "argument COMMAND: invalid choice: 'fly'"),
    "sweep: a fault on no robot of the run": ([*SWEEP, "--fault", "blackout 9@3s"], "no robot 9 in this run"),
    "sweep: a fault without its time": ([*SWEEP, "--fault", "blackout 2"], "a fault is KIND TARGET@START"),
    "sweep: zero jobs": ([*SWEEP, "--jobs", "0"], "argument --jobs: must be in [1, 256], got '0'"),
    "sweep: zero seeds": (
        ["sweep", "fig11_obstacles", "--seeds", "0"],
        "argument --seeds: must be in [1, 10000], got '0'",
    ),
    "sweep: negative first seed": ([*SWEEP, "--seed-start", "-1"], f"argument --seed-start: {SEED_RANGE}, got '-1'"),
    "sweep: seeds past 2**63 - 1": ([*SWEEP, "--seed-start", MAX_SEED], "seeds S to S+N-1 must stay within 2**63 - 1"),
    "sweep: --out is a file": (
        [*SWEEP, "--out", "{tmp}/a_file"],
        "--out {tmp}/a_file: is an existing file, not a folder",
    ),
    "sweep: a value twice": ([*SWEEP, "--set", "controller.vn=1.5,1.50"], "the value '1.50' is given twice"),
    "sweep: --set run.seed": ([*SWEEP, "--set", "run.seed=5,6"], "use --seeds N and --seed-start S"),
    "sweep: bad --set value": (
        [*SWEEP, "--set", "controller.vn=1.5,0"],
        "(with controller.vn = 0): controller.vn must be 'dynamic' or a number > 0, got 0",
    ),
    "export: a missing folder": (["export", "{tmp}/nowhere"], "{tmp}/nowhere: no such folder"),
    "export: unknown format": (["export", "{tmp}", "--format", "xls"], "argument --format: invalid choice: 'xls'"),
    "compare: a missing run": (["compare", "{tmp}/nowhere"], "{tmp}/nowhere: no such folder"),
    "results: one seed": (["results", "--seeds", "1"], "argument --seeds: must be in [2, 10000], got '1'"),
    "results: zero jobs": (["results", "--jobs", "0"], "argument --jobs: must be in [1, 256], got '0'"),
    "results: --write a missing file": (
        ["results", "--write", "{tmp}/missing.md"],
        "--write {tmp}/missing.md: cannot read it (No such file or directory)",
    ),
    "results: --write a file without markers": (
        ["results", "--write", "{tmp}/a_file"],
        "--write {tmp}/a_file: has no <!-- results table: begin --> ... <!-- results table: end --> markers",
    ),
    "results: --out is a file": (["results", "--out", "{tmp}/a_file"], "--out {tmp}/a_file: is an existing file"),
    "results: --set a key the table varies": (
        ["results", "--set", "links.obs_drop=0.5"],
        "--set links.obs_drop: the table varies that key itself",
    ),
    "results: --claims with an unknown key": (
        ["results", "--claims", "--set", "robot.wheel_noise=0.1"],
        "unknown key robot.wheel_noise; did you mean 'wheel_noise_mps'?",
    ),
    "results: --claims --write a file without their markers": (
        ["results", "--claims", "--set", "robot.wheel_noise_mps=0.1", "--write", "{tmp}/a_file"],
        "has no <!-- claims (robot.wheel_noise_mps=0.1): begin --> ... <!-- claims (robot.wheel_noise_mps=0.1): "
        "end --> markers",
    ),
    "report: negative snapshots": (
        ["report", "--snapshots", "-1", "{tmp}"],
        "argument --snapshots: must be in [0, 100], got '-1'",
    ),
    "report: no such folder": (["report", "{tmp}/missing"], "{tmp}/missing: no such folder"),
    "report: a file": (["report", __file__], f"{__file__}: a file, not a run folder"),
    "report: not a run folder": (["report", "{tmp}"], "{tmp} is not a run folder: no summary.json"),
    "sim: negative seed": (["sim", "--seed", "-1"], f"argument --seed: {SEED_RANGE}, got '-1'"),
    "sim: zero duration": (["sim", "--duration", "0"], "argument --duration: must be a number of seconds in (0, 3600]"),
    "sim: duration under a step": (
        ["sim", "--duration", "0.01"],
        "argument --duration: must be at least one control step (0.05 s), got 0.01",
    ),
    "sim: infinite duration": (["sim", "--duration", "inf"], "argument --duration: must be a number of seconds"),
    "sim: zero V_N": (["sim", "--vn", "0"], "argument --vn: must be 'dynamic' or a speed > 0 in m/s, got '0'"),
    "sim: V_N beyond the wheels": (
        ["sim", "--vn", "7"],
        "argument --vn: the fuzzy controller would command up to V_N + a = 7.5 m/s, above the robots' 3 m/s "
        "(robot.max_wheel_mps): at most 2.5",
    ),
}


def swarm(argv: list[str], cwd: Path, timeout_s: float = 60.0) -> subprocess.CompletedProcess[str]:
    return subprocess.run([*COMMAND, *argv], cwd=cwd, capture_output=True, text=True, timeout=timeout_s, check=False)


def no_traceback(proc: subprocess.CompletedProcess[str]) -> bool:
    """No traceback of swarm's own: a child's log quoted on the console is indented."""
    return not any(line.startswith("Traceback") for line in (proc.stdout + proc.stderr).splitlines())


def files(folder: Path) -> list[Path]:
    return sorted(folder.rglob("*"))


@dataclass
class Outcome:
    folder: Path
    before: list[Path]
    after: list[Path]
    proc: subprocess.CompletedProcess[str]
    elapsed_s: float


@pytest.fixture(scope="module")
def rejected(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Outcome]:
    """Every case of REJECTED, each in its own folder; independent processes,
    so four at a time (most of their time is Python importing numpy and filterpy)."""

    def one(case: str) -> Outcome:
        argv, _ = REJECTED[case]
        folder = tmp_path_factory.mktemp("bad")
        (folder / "a_file").write_text("not a folder\n")
        for name, text in INPUT_FILES.items():
            if any(f"{{tmp}}/{name}" in a for a in argv):
                (folder / name).write_text(text)
        (folder / "old_run").mkdir()
        (folder / "old_run" / "summary.json").write_text("{}\n")
        before = files(folder)
        started = time.monotonic()
        proc = swarm([a.format(tmp=folder) for a in argv], cwd=folder)
        return Outcome(folder, before, files(folder), proc, time.monotonic() - started)

    with ThreadPoolExecutor(max_workers=4) as pool:
        return dict(zip(REJECTED, pool.map(one, REJECTED), strict=True))


@pytest.mark.parametrize("case", list(REJECTED))
def test_bad_input_is_one_line_exit_2_and_nothing_made(rejected: dict[str, Outcome], case: str) -> None:
    argv, fragment = REJECTED[case]
    res = rejected[case]
    proc = res.proc
    assert proc.returncode == 2, proc.stderr
    assert proc.stdout == ""
    assert len(proc.stderr.splitlines()) == 1, proc.stderr
    assert fragment.format(tmp=res.folder) in proc.stderr
    command = argv[0] if argv[0] in (*cli.DELEGATED, "run", "sim", "scenarios") else None
    assert proc.stderr.startswith(f"swarm {command}: " if command else "swarm: ")
    assert "Traceback" not in proc.stdout + proc.stderr
    assert res.after == res.before  # no run folder, no runs/, no sweeps/
    assert res.elapsed_s < 60.0  # refused up front, not after a run: a few s quiet, 20 s on a loaded machine


def test_a_role_that_crashes_is_named_with_its_code_and_its_log(tmp_path: Path) -> None:
    """The logger cannot serve the web viewer on a port taken after the launcher
    checked it: it exits with an error before tick 0; the run stops at once
    (the world would wait for it) and says which process, its exit code and
    its log's end."""
    lines: list[str] = []
    launch = Launch(
        "fig6_turn_vn_2",
        serve_web=True,
        web_ports=(free_port(), free_port()),
        out=tmp_path / "run",
        progress=lines.append,
    )
    with socket.socket() as taken:
        taken.bind(("0.0.0.0", launch.web_ports[1]))  # taken now, between the check and the logger
        taken.listen()
        started = time.monotonic()
        with launch:
            res = launch.wait(timeout_s=120)
        elapsed = time.monotonic() - started
    text = io.StringIO()
    print_result(res, text)
    out = "\n".join(lines) + "\n" + text.getvalue()
    assert res.exit_code == 1, out
    assert elapsed < 50.0  # not the world's 60 s wait for a logger that is gone (about 10 s, loaded 20)
    log = tmp_path / "run" / "logs" / "logger.log"
    assert f"logger exited with code 1 before the run started; the end of {log}:" in out
    quoted = [line for line in out.splitlines() if line.startswith("  | ")]
    assert any("Address already in use" in line for line in quoted), out
    assert "the run cannot start without logger" in out
    assert "no metrics: the run ended before its first tick" in out
    assert "Traceback" not in out
    summary = json.loads((tmp_path / "run" / "summary.json").read_text())
    assert summary["exit_code"] == 1
    exited = [e for e in summary["events"] if e["event"] == "exited" and e["process"] == "logger"]
    assert [e["code"] for e in exited] == [1]
    assert any("Address already in use" in line for line in exited[0]["log_tail"])

    # ... and swarm report on that folder writes report.md alone and says why, in one line.
    rep = swarm(["report", str(tmp_path / "run")], cwd=tmp_path)
    assert rep.returncode == 0, rep.stderr
    assert len(rep.stdout.splitlines()) == 1
    assert "report.md only, no figures: nothing was recorded: the run ended before its first tick (exit code 1)" in (
        rep.stdout
    )
    assert "Traceback" not in rep.stdout + rep.stderr


def test_a_formation_named_in_any_script_flies(tmp_path: Path) -> None:
    """A name TOML must quote: the launcher writes the scenario as run so that
    the world and the agents read it back (they could not: exit 1 after 35 s)."""
    text = (SCENARIOS / "fig11_obstacles.toml").read_text()
    text = text.replace("[formations.triangle]", '[formations."triángulo ▲"]').replace('"triangle"', '"triángulo ▲"')
    (tmp_path / "tri.toml").write_text(text)
    out = tmp_path / "run"
    argv = ["run", "tri.toml", "--set", "run.duration_s=1", "--no-logger", "--out", str(out)]
    proc = swarm(argv, cwd=tmp_path, timeout_s=120.0)
    assert proc.returncode == 0, proc.stdout + proc.stderr
    assert '[formations."triángulo ▲"]\n' in (out / "scenario.toml").read_text()
    summary = json.loads((out / "summary.json").read_text())
    assert (summary["exit_code"], summary["ticks"]) == (0, 20)


def test_report_on_a_recording_it_cannot_read(tmp_path: Path) -> None:
    (tmp_path / "summary.json").write_text(json.dumps({"run_id": "r", "ticks": None, "exit_code": 1}))
    (tmp_path / "recording.rrd").write_bytes(b"")  # a logger killed before its first write
    proc = swarm(["report", str(tmp_path)], cwd=tmp_path)
    assert proc.returncode == 2
    assert len(proc.stderr.splitlines()) == 1
    assert f"cannot read {tmp_path / 'recording.rrd'}" in proc.stderr
    assert "Traceback" not in proc.stdout + proc.stderr
    (tmp_path / "summary.json").write_text("{not json")
    proc = swarm(["report", str(tmp_path)], cwd=tmp_path)
    assert proc.returncode == 2
    assert "summary.json is not valid JSON" in proc.stderr


def test_version() -> None:
    proc = swarm(["--version"], cwd=Path.cwd())
    assert proc.returncode == 0
    assert proc.stdout == f"formation-swarm {__version__}\n"
    assert __version__ == version("formation-swarm")  # the package's and the installed metadata's


def test_help_is_written_for_people() -> None:
    proc = swarm(["--help"], cwd=Path.cwd())
    assert proc.returncode == 0
    assert proc.stdout.split("\n\n")[1].startswith("swarm: an emulator of vision-based leader-follower formation")
    parsers = {
        "swarm": cli.build_parser(),
        "report": report.build_parser(),
        "sweep": sweep.build_parser(),
        "results": results.build_parser(),
        "export": export.build_parser(),
        "compare": compare.build_parser(),
    }
    for sub in parsers["swarm"]._subparsers._group_actions[0].choices.values():  # type: ignore[union-attr]
        if sub.add_help:  # the ones with their own parser here, not a module's
            parsers[sub.prog] = sub
    summaries = parsers["swarm"]._subparsers._group_actions[0]._choices_actions  # type: ignore[union-attr]
    assert all(len(a.help or "") > 20 for a in summaries), [a.dest for a in summaries if len(a.help or "") <= 20]
    for name, parser in parsers.items():
        text = parser.format_help()
        assert "``" not in text, name  # reST markup, which argparse prints as it is
        if name != "swarm":
            assert len(parser.description or "") > 80, name
        for action in parser._actions:
            if isinstance(action, (argparse._HelpAction, argparse._VersionAction, argparse._SubParsersAction)):
                continue
            assert len(action.help or "") > 20, (name, action.dest)


def test_no_arguments_prints_the_help() -> None:
    proc = swarm([], cwd=Path.cwd())
    assert proc.returncode == 2
    assert "swarm run fig11_obstacles" in proc.stdout
    assert proc.stderr == ""


@pytest.mark.parametrize(
    ("flags", "fragment"),
    [
        (["--config", "{tmp}/missing.json5"], "--config {tmp}/missing.json5: not a Zenoh configuration Zenoh accepts"),
        (["--listen", "tcp/127.0.0.1:99999"], "the port must be a number in [1, 65535]"),
    ],
)
def test_a_role_with_a_bad_zenoh_flag_says_so_in_one_line(tmp_path: Path, flags: list[str], fragment: str) -> None:
    argv = ["world", "--scenario", "fig11_obstacles", "--run", "x", *(f.format(tmp=tmp_path) for f in flags)]
    proc = swarm(argv, cwd=tmp_path)
    assert proc.returncode == 2, proc.stderr
    (line,) = proc.stderr.splitlines()
    assert line.startswith("world: ")
    assert fragment.format(tmp=tmp_path) in line
    assert no_traceback(proc)


@pytest.mark.parametrize("text", ["-1", "x", "nan", "inf", ""])
def test_a_non_negative_option_refuses_what_is_not_a_finite_number_at_least_0(text: str) -> None:
    with pytest.raises(argparse.ArgumentTypeError, match=f"must be a finite number >= 0, got {text!r}"):
        cliargs.non_negative(text)
    assert cliargs.non_negative("0") == 0.0
    assert cliargs.non_negative("1.5") == 1.5


def test_a_reader_that_leaves_early_does_not_cut_the_run_short(tmp_path: Path) -> None:
    """`swarm run ... | head -1`: the pipe closes after the first line; the run
    still goes to its end, writes its folder and exits 0."""
    out = tmp_path / "run"
    argv = [*COMMAND, "run", "fig11_obstacles", "--set", "run.duration_s=3", "--out", str(out)]
    proc = subprocess.Popen(argv, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
    try:
        assert proc.stdout is not None
        assert proc.stdout.readline().startswith("[swarm] run ")
        proc.stdout.close()  # as head does after its line
        _, err = proc.communicate(timeout=180)  # a 3 s run takes about 5 s here
    finally:
        if proc.poll() is None:
            proc.kill()
            proc.wait()
    assert proc.returncode == 0, err
    assert "BrokenPipeError" not in err
    summary = json.loads((out / "summary.json").read_text())
    assert summary["ticks"] == 60  # 3 s at 20 Hz
    assert summary["end_reason"] == "duration_reached"


def test_a_listen_address_the_run_cannot_use_is_a_bad_command_line(tmp_path: Path) -> None:
    """Refused before anything starts (exit 2, no run folder), not once the
    world has started and failed to listen (exit 1, "cannot reach the world")."""
    from formation_swarm.protocol import trust

    logins = trust.write_host_logins(tmp_path / "hosts", ["b", "c"])[trust.HOST_LOGINS]
    with socket.socket() as taken:
        taken.bind(("127.0.0.1", 0))
        taken.listen()
        port = taken.getsockname()[1]
        cases = {
            "127.0.0.1:7447": "endpoint must look like tcp/HOST:PORT, got '127.0.0.1:7447'",
            "tcp/127.0.0.1:99999": "the port must be a number in [1, 65535]",
            f"tcp/127.0.0.1:{port}": f"--listen tcp/127.0.0.1:{port}: cannot listen there (Address already in use)",
            "tcp/192.0.2.1:7447": "--listen tcp/192.0.2.1:7447: cannot listen there (Cannot assign requested address)",
        }
        for listen, said in cases.items():
            out = tmp_path / f"run-{len(listen)}"
            argv = [*RUN, "--hosts", "b,c", "--listen", listen, "--host-logins", str(logins), "--out", str(out)]
            proc = swarm(argv, tmp_path)
            assert proc.returncode == 2, (listen, proc.stderr)
            assert said in proc.stderr, (listen, proc.stderr)
            assert not out.exists()


def test_a_remote_agents_log_not_fetched_is_said_in_a_sentence() -> None:
    from formation_swarm.launch.console import describe_event

    ev = {"event": "not fetched", "process": "agent-2", "host": "c", "why": "host c is lost; they stay on it"}
    assert describe_event(ev) == "agent-2's log and stats were not fetched: host c is lost; they stay on it"


def test_launch_refuses_overrides_that_are_not_a_mapping_and_a_second_seed(tmp_path: Path) -> None:
    """The fixture's and the API's arguments, in the CLI's style by mistake: a
    sentence, not dict()'s 'dictionary update sequence element #0 has length 20'."""
    from formation_swarm.launch.launcher import Launch

    said = r"^overrides must map scenario keys to values, e.g. \{'leader.speed_mps': 1.6\}, got list \['leader"
    with pytest.raises(ValueError, match=said):
        Launch("fig11_obstacles", out=tmp_path / "r", overrides=["leader.speed_mps=1.6"])  # type: ignore[arg-type]
    with pytest.raises(ValueError, match=r"^seed 3 and run.seed 5 in the overrides: give the seed once$"):
        Launch("fig11_obstacles", out=tmp_path / "r", seed=3, overrides={"run.seed": 5})
    assert not (tmp_path / "r").exists()
