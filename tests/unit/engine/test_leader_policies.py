"""A leader's policy of the user's and the hooks of policies and controllers
through the engine (formation_swarm.Engine), no process started: the
figure-eight example (examples/figure_eight) flies and gives one digest run
after run; ``reset()`` is called once before a role's first step and
``close()`` once when its agent stops (the run's end, the engine's reset or
close), never for an agent a fault killed; a close that raises is the run's
controller failure, not an exception. docs/leader-policy.md's policy
passes its test, and its code and tables name the public interface."""

from __future__ import annotations

import re
import sys
from pathlib import Path

import pytest

import formation_swarm
from formation_swarm import Engine
from formation_swarm.agents.laws import POLICY_GROUP
from formation_swarm.agents.leader_policy import LeaderMove, LeaderParams, LeaderSensing, LeaderSetup
from tests.helpers import ROOT, hooked

EIGHT = ROOT / "examples" / "figure_eight"
HOOKED = {"leader.policy": f"{hooked.MODULE}:Leader", "controller.law": f"{hooked.MODULE}:Follower"}
SHORT = {"run.duration_s": 2.0}  # 40 ticks


def test_the_figure_eight_flies_through_the_engine_and_two_runs_give_one_digest(
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    monkeypatch.syspath_prepend(str(EIGHT))
    short = {"run.duration_s": 18.0, "run.seed": 2, "leader.params.radius_m": 4}  # changes at 16.8 s
    first = Engine(EIGHT / "figure_eight.toml", overrides=short).run()
    again = Engine(EIGHT / "figure_eight.toml", overrides=short).run()
    s = first.summary
    assert (first.exit_code, first.end_reason, first.ticks) == (0, "duration_reached", 360)
    assert first.trajectory_digest == again.trajectory_digest
    assert s["robot_digests"] == again.summary["robot_digests"]
    assert s["laws"] == {
        "leader": "figure_eight:FigureEight",
        "followers": {"2": "fuzzy (V_N dynamic)", "3": "fuzzy (V_N dynamic)"},
    }
    assert [(e["robot"], e["formation"]) for e in s["formation_events"]] == [(1, "line"), (2, "line"), (3, "line")]
    assert s["controller_failures"] == []


def _calls() -> list[dict[str, int]]:
    return [dict(m.calls) for m in hooked.MADE]


def test_each_hook_is_called_once_a_run_a_reset_or_a_close() -> None:
    hooked.MADE.clear()
    engine = Engine("fig11_obstacles", overrides={**HOOKED, **SHORT})
    assert _calls() == [{"reset": 1}] * 3  # the leader, 2, 3: built and reset before the first tick
    res = engine.run()
    assert res.exit_code == 0
    assert _calls() == [{"reset": 1, "step": 40, "close": 1}] * 3  # closed at the run's end
    engine.reset()
    engine.close()
    engine.close()  # once
    assert _calls() == [{"reset": 1, "step": 40, "close": 1}] * 3 + [{"reset": 1, "close": 1}] * 3
    with Engine("fig11_obstacles", overrides={**HOOKED, **SHORT}) as again:
        again.step()
    assert _calls()[6:] == [{"reset": 1, "step": 1, "close": 1}] * 3


def test_an_agent_a_fault_killed_is_not_closed_its_successor_is() -> None:
    hooked.MADE.clear()
    res = Engine("fig11_obstacles", overrides={**HOOKED, **SHORT}, faults=["restart agent-3@1s after=0.5s"]).run()
    assert [(e["event"], e["process"]) for e in res.events] == [("killed", "agent-3"), ("started", "agent-3.2")]
    assert [(m.robot_id, dict(m.calls)) for m in hooked.MADE] == [
        (1, {"reset": 1, "step": 40, "close": 1}),
        (2, {"reset": 1, "step": 40, "close": 1}),
        (3, {"reset": 1, "step": 20}),  # killed at tick 20, as a process is: no call
        (3, {"reset": 1, "step": 10, "close": 1}),  # back at tick 30
    ]


def test_a_close_that_raises_fails_the_run_in_one_line_with_its_result_kept() -> None:
    overrides = {**HOOKED, **SHORT, "leader.params.raise_in": "close", "followers.3.params.raise_in": "close"}
    res = Engine("fig11_obstacles", overrides=overrides).run()
    error = "close() raised RuntimeError: close failing on purpose"
    assert res.summary["controller_failures"] == [
        {"robot": 1, "tick": 39, "error": error, "law": HOOKED["leader.policy"]},
        {"robot": 3, "tick": 39, "error": error, "law": HOOKED["controller.law"]},
    ]
    assert (res.exit_code, res.end_reason, res.ticks) == (1, "duration_reached", 40)
    assert res.followers["2"]["rms_m"] == Engine("fig11_obstacles", overrides=SHORT).run().followers["2"]["rms_m"]
    closing = [n for n in res.notes if "failed after tick 39" in n]
    assert [n.split(":")[0] for n in closing] == ["agent-1", "agent-3"]


# -- docs/leader-policy.md stays true ------------------------------------------------------

PAGE = (ROOT / "docs" / "leader-policy.md").read_text()
PYTHON = re.findall(r"^```python\n(.*?)^```$", PAGE, re.M | re.S)


def test_the_pages_policy_passes_the_pages_test(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    (tmp_path / "my_policy.py").write_text(PYTHON[0])
    monkeypatch.syspath_prepend(str(tmp_path))
    monkeypatch.chdir(ROOT)  # the page's test names the example's scenario from the repository's root
    namespace: dict[str, object] = {"__name__": "test_mine"}
    exec(compile(PYTHON[1], "leader-policy.md", "exec"), namespace)  # the page's own code
    try:
        (name,) = [n for n in namespace if n.startswith("test_")]
        namespace[name]()  # type: ignore[operator]
    finally:
        sys.modules.pop("my_policy", None)


def test_the_pages_code_and_tables_name_the_public_interface() -> None:
    code = "\n".join(PYTHON)
    imported = {
        n.strip() for line in re.findall(r"^from formation_swarm import (.+)$", code, re.M) for n in line.split(",")
    }
    assert imported == {"Engine", "LeaderMove", "LeaderSensing", "LeaderSetup"}
    assert imported <= set(formation_swarm.__all__)
    assert "formation_swarm." not in code
    for cls in (LeaderSetup, LeaderParams, LeaderSensing, LeaderMove):
        for name in cls.__dataclass_fields__:
            assert f"`{name}`" in PAGE, (cls.__name__, name)
    assert f'"{POLICY_GROUP}"' in PAGE
