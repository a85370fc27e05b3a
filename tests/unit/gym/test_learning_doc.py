"""docs/learning.md's examples run as written, and its table of the
observation names the adapters' entries in their order."""

from __future__ import annotations

import contextlib
import io
import re

from formation_swarm.gym.followers import ACTION, OBSERVATION
from tests.helpers import ROOT

TEXT = (ROOT / "docs" / "learning.md").read_text()
BLOCKS = re.findall(r"^```python\n(.*?)^```$", TEXT, re.M | re.S)


def test_the_pettingzoo_loop_runs_fig11_to_its_end() -> None:
    out = io.StringIO()
    namespace: dict[str, object] = {"__name__": "learning"}
    with contextlib.redirect_stdout(out):
        exec(compile(BLOCKS[0], "learning.md", "exec"), namespace)  # the page's own code
    assert len([line for line in BLOCKS[0].splitlines() if line]) <= 10
    env = namespace["env"]
    returns = namespace["returns"]
    assert env.agents == []  # type: ignore[attr-defined]
    assert set(returns) == {"follower_2", "follower_3"}  # type: ignore[arg-type]
    assert all(r < 0.0 for r in returns.values())  # type: ignore[attr-defined]
    res = env.run.engine.run()  # type: ignore[attr-defined]
    assert (res.end_reason, res.ticks) == ("leader_finished", 1061)  # the leader's path, as with the laws
    assert out.getvalue().startswith("{'follower_2': ")


def test_the_gymnasium_example_makes_and_steps_follower_2() -> None:
    namespace: dict[str, object] = {"__name__": "learning"}
    exec(compile(BLOCKS[1], "learning.md", "exec"), namespace)
    assert namespace["info"]["tick"] == 1  # type: ignore[index]
    assert namespace["env"].unwrapped.robot_id == 2  # type: ignore[attr-defined]
    assert namespace["reward"] == -namespace["info"]["formation_error_m"]  # type: ignore[index]


def test_the_tables_name_the_observation_and_the_action() -> None:
    rows = re.findall(r"^\| (\d) \| `(\w+)` \|", TEXT, re.M)
    assert rows == [(str(i), name) for i, name in enumerate(OBSERVATION)]
    assert ACTION == ("left_mps", "right_mps")
