"""An agent killed during a real-time run is a death, whoever started it.

Robot 3's agent is SIGKILLed at sim t >= 3 s of a 10 s real-time run: our
agent, an outside one, and an outside one whose login a second session also
holds (it keeps robot 3's token). Before, the last ended with exit 0,
``deaths`` [], no event and no line (only ``stale_stops: 1``). Now each is
reported as the first: ``deaths`` lists robot 3, an event and a console line
say it, and the exit code is the managed agent's.
"""

from __future__ import annotations

import os
import signal
from pathlib import Path
from typing import Any

import pytest
import zenoh

from formation_swarm.launch.launcher import Launch
from formation_swarm.protocol import trust
from formation_swarm.protocol.keys import Keys
from formation_swarm.protocol.session import make_config
from tests.system.test_outside_logins import FIG11, foreign_agent, hold_token

pytestmark = pytest.mark.slow

REALTIME = {"run.duration_s": 10.0}
KILL_AT_S = 3.0
MANAGED_EXIT = 0  # a follower's death: the run flew on without it (robots_lost fails only the leader's or all)


def _kill_and_finish(launch: Launch, pid: int) -> tuple[int, dict[str, Any]]:
    assert launch.wait_until(lambda: launch.sim_time() >= KILL_AT_S, timeout_s=90)
    os.kill(pid, signal.SIGKILL)
    res = launch.wait(timeout_s=120)
    return res.exit_code, res.summary


@pytest.mark.parametrize("who", ["managed", "outside", "outside, a second session on its login"])
def test_an_agent_killed_in_real_time_is_a_death_whoever_started_it(tmp_path: Path, who: str) -> None:
    lines: list[str] = []
    options = {"mode": "realtime", "overrides": REALTIME, "logger": False, "progress": lines.append}
    launch = Launch(FIG11, out=tmp_path / "run", external=[] if who == "managed" else [3], **options)
    try:
        if who == "managed":
            launch.start()
            code, s = _kill_and_finish(launch, launch.pids()["agent-3"])
        else:
            agent = launch.prepare()[3]
            assert agent.login is not None
            stolen = trust.read_settings(agent.login)  # a copy taken before the agent connected
            launch.start()
            with foreign_agent(agent.flags(), tmp_path) as proc:
                assert launch.wait_until(lambda: launch.sim_time() >= 0.0, timeout_s=90), lines
                if who == "outside":
                    code, s = _kill_and_finish(launch, proc.pid)
                else:
                    with zenoh.open(make_config("client", [launch.endpoint], settings=stolen)) as thief:
                        token = hold_token(thief, Keys(launch.run_id).alive("agent", 3))
                        code, s = _kill_and_finish(launch, proc.pid)
                        token.undeclare()
    finally:
        launch.stop()
    assert code == MANAGED_EXIT, s["events"]
    assert (s["end_reason"], s["ticks"], s["failure"]) == ("duration_reached", 200, None)
    (death,) = s["deaths"]
    assert (death["robot"], death["cause"]) == (3, "lost")
    assert KILL_AT_S <= death["time_s"] <= KILL_AT_S + 1.5  # the launcher's status lags up to 0.25 s; the kill ~0
    assert s["stale_stops"] == 0  # stopped as lost, not left to go stale
    if who == "managed":
        (ev,) = [e for e in s["events"] if e["event"] == "exited"]
        assert (ev["process"], ev["code"], ev["tick"]) == ("agent-3", -signal.SIGKILL, death["tick"])
        return
    (ev,) = [e for e in s["events"] if e["event"] == "outside agent left"]
    assert (ev["robot"], ev["tick"], ev["sim_time_s"], ev["placed_by"]) == (
        3,
        death["tick"],
        death["time_s"],
        "the world",
    )
    said = [line for line in lines if line.startswith("[swarm] robot 3's outside agent left")]
    assert len(said) == 1, lines
    used = [e["robot"] for e in s["events"] if e["event"] == "robot login used twice"]
    if who == "outside":
        assert "its token went; its login is written again for a fresh agent" in said[0]
        assert used == []
    else:  # the token stayed: the world saw the agent's session close and its observations unheard
        assert "while a second session on its login kept its token" in said[0]
        assert used == [3]
