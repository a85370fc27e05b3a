"""``swarm sim``: the engine's command line, in this process. It prints the
result block of ``swarm run`` and the digest, takes laws, faults and keys,
and keeps the flags of the older one-follower loop it replaced."""

from __future__ import annotations

import pytest

from formation_swarm import Engine, cli
from formation_swarm.common.faults import Fault

FAULTS = ("drop obs:2@3s for=4s p=0.3", "restart agent-3@20s after=1s")


def sim(capsys: pytest.CaptureFixture[str], *argv: str) -> tuple[int, list[str], str]:
    code = cli.main(["sim", *argv])
    out = capsys.readouterr()
    return code, out.out.splitlines(), out.err


def test_it_prints_swarm_runs_result_block_and_the_engines_digest(capsys: pytest.CaptureFixture[str]) -> None:
    argv = ["fig11_obstacles", "--seed", "2", "--law", "lpsi"]
    code, lines, err = sim(capsys, *argv, *(a for f in FAULTS for a in ("--fault", f)))
    res = Engine("fig11_obstacles", seed=2, overrides={"controller.law": "lpsi"}, faults=FAULTS).run()
    assert (code, err) == (0, "")
    assert lines[0] == "[swarm] sim: fig11-obstacles, 3 robots, lockstep in this process, seed 2, leader path, law lpsi"
    assert lines[1] == "sim fig11-obstacles: exit 0, 1061 ticks, sim 53.05 s"
    assert lines[2] == "  ended: the leader reached its last waypoint at t=53.05 s"
    assert lines[3] == f"  follower R2: formation error RMS {res.followers['2']['rms_m']:.3f} m, max " + (
        f"{res.followers['2']['max_m']:.3f} m"
    )
    assert lines[4].startswith("  follower R3: formation error RMS ")
    assert "until its agent was killed at t=20.00 s, a fresh one started at t=21.00 s" in lines[4]
    assert "collisions 0, obstacle collisions 0" in lines[5]
    said = [line for line in lines if line.startswith("  fault: ")]
    assert [line.split(": ")[1] for line in said] == [str(Fault.parse(f)) for f in FAULTS]
    assert lines[-1] == f"  trajectory digest: {res.trajectory_digest}"


def test_its_older_flags_set_their_keys(capsys: pytest.CaptureFixture[str]) -> None:
    code, lines, _ = sim(capsys, "--vn", "1.5", "--duration", "5")
    same = Engine("fig7_turn_vn_dynamic", overrides={"controller.vn": 1.5, "run.duration_s": 5.0}).run()
    assert code == 0
    assert lines[0].startswith("[swarm] sim: turn-vn-dynamic, 2 robots")  # the paper's turning run, as before
    assert lines[-1] == f"  trajectory digest: {same.trajectory_digest}"


@pytest.mark.parametrize(
    ("argv", "said"),
    [
        (["fig11_obstacles", "--fault", "kill agent-3@20s"], "a kill is a SIGKILL of a process"),
        (["--law", "lpsi", "--set", "controller.law=fuzzy"], "--law and --set controller.law: give it once"),
        (["--law", "no_such_module:Law"], "controller.law"),
        (["--vn", "7"], "argument --vn: the fuzzy controller would command up to V_N + a = 7.5 m/s"),
        (["--duration", "0.01"], "argument --duration: must be at least one control step (0.05 s), got 0.01"),
    ],
)
def test_what_it_cannot_run_is_one_line_and_exit_2(
    capsys: pytest.CaptureFixture[str], argv: list[str], said: str
) -> None:
    code, lines, err = sim(capsys, *argv)
    assert (code, lines) == (2, [])
    assert err.startswith("swarm sim: ")
    assert said in err
    assert len(err.splitlines()) == 1
