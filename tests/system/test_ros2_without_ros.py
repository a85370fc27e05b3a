"""examples/ros2_follower/without_ros.py, as docs/ros2.md runs it: robot 3 of
a lockstep run driven through the ROS 2 bridge by a process with no ROS, from
the session configuration session_config.py writes; it leaves when the run
ends. Without a run: no /clock is said at its deadline, Ctrl-C ends it."""

from __future__ import annotations

import json
import re
import signal
import subprocess
import sys
import uuid
from pathlib import Path

import pytest
import zenoh

from formation_swarm.launch.launcher import Launch
from formation_swarm.launch.ros2 import write_login
from formation_swarm.protocol.session import make_config
from formation_swarm.runtime.children import free_port

pytestmark = pytest.mark.slow

EXAMPLE = Path(__file__).parents[2] / "examples" / "ros2_follower"
DRIVER = [sys.executable, str(EXAMPLE / "without_ros.py")]


def test_robot_3_flown_by_the_example_without_ros_answers_every_tick(tmp_path: Path) -> None:
    run_id = f"noros-{uuid.uuid4().hex[:8]}"
    launch = Launch(
        "fig11_obstacles",
        overrides={"ros2.bridge": True, "run.duration_s": 3.0},
        external=[3],
        out=tmp_path / run_id,
        run_id=run_id,
        progress=lambda _line: None,
        peers_timeout_s=30.0,
    )
    with launch:
        login = write_login(launch.login("ros2") or {}, tmp_path / "ros2.json")  # as --ros2-login does
        conf = tmp_path / "swarm_session.json5"
        made = subprocess.run(
            [sys.executable, str(EXAMPLE / "session_config.py"), str(login), launch.endpoint, str(conf)],
            capture_output=True,
            text=True,
            timeout=30,
            check=True,
        )
        assert made.stdout.endswith("logged in as ros2\n")
        driver = subprocess.Popen([*DRIVER, str(conf)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            result = launch.wait(timeout_s=120.0)
            out, err = driver.communicate(timeout=30)
        finally:
            if driver.poll() is None:
                driver.kill()
                driver.wait(timeout=10)
    s = result.summary
    assert result.exit_code == 0, err
    ticks = s["ticks"]
    assert ticks == 60  # 3 s of 0.05 s
    twists = s["ros2"]["twists"]["3"]
    assert (twists["taken"], twists["rejected"], twists.get("unawaited", 0)) == (ticks, 0, 0)
    assert s["lockstep_misses"] == 0
    assert driver.returncode == 0, err
    last = out.splitlines()[-1]
    assert last.startswith("without_ros: the run ended (its ROS 2 bridge left); ")
    assert _sent(last) == ticks  # one Twist a /clock
    assert s["followers"]["3"]["rms_m"] < 1.5


def test_with_no_clock_it_says_so_at_its_deadline_and_ctrl_c_ends_it(tmp_path: Path) -> None:
    port = free_port()
    endpoint = f"tcp/127.0.0.1:{port}"
    conf = tmp_path / "session.json5"  # no login: this router asks for none
    conf.write_text(json.dumps({"mode": "client", "connect": {"endpoints": [endpoint]}}))
    with zenoh.open(make_config("router", listen=[endpoint])):  # a router, no run: no /clock
        waited = subprocess.run(
            [*DRIVER, str(conf), "--wait-s", "1"], capture_output=True, text=True, timeout=60, check=False
        )
        assert waited.returncode == 1, waited.stderr
        last = waited.stderr.splitlines()[-1]
        assert last.startswith("without_ros: no /clock within 1 s (--wait-s); check that the run leaves robot 3 ")
        assert _sent(last) == 0
        driver = subprocess.Popen([*DRIVER, str(conf)], stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True)
        try:
            assert driver.stdout is not None
            assert driver.stdout.readline().startswith(
                "without_ros: node swarm_follower on domain 0: waiting up to 90 s"
            )
            driver.send_signal(signal.SIGINT)
            _out, err = driver.communicate(timeout=30)
        finally:
            if driver.poll() is None:
                driver.kill()
                driver.wait(timeout=10)
    assert driver.returncode == 130
    assert err.splitlines()[-1].startswith("without_ros: interrupted; ")
    assert _sent(err.splitlines()[-1]) == 0
    nothing = subprocess.run([*DRIVER, str(tmp_path / "none.json5")], capture_output=True, text=True, timeout=60)
    assert nothing.returncode == 2
    assert nothing.stderr.startswith(f"without_ros: {tmp_path / 'none.json5'}: no such file")
    assert len(nothing.stderr.splitlines()) == 1


def _sent(line: str) -> int:
    """The Twists a driver's last line says it sent."""
    found = re.search(r"; (\d+) Twists sent for robot 3$", line)
    assert found is not None, line
    return int(found[1])
