"""The key space: every key's form, and what the parsers accept and refuse."""

from __future__ import annotations

import pytest

from formation_swarm.protocol.keys import MAX_ROBOT_ID, Keys, RobotKey, check_robot_id, check_run_id

K = Keys("run-1")


def test_every_key_starts_with_the_run() -> None:
    assert K.prefix == "swarm/run-1"
    assert K.obs(2) == "swarm/run-1/robot/2/obs"
    assert K.cmd(2) == "swarm/run-1/robot/2/cmd"
    assert K.codes == "swarm/run-1/robot/*/formation"
    assert K.telemetry(3) == "swarm/run-1/robot/3/telemetry"
    assert K.inbox(2) == "swarm/run-1/robot/2/*"
    assert K.all_cmd == "swarm/run-1/robot/*/cmd"
    assert K.world_wake == "swarm/run-1/robot/wake/cmd"
    assert K.all_telemetry == "swarm/run-1/robot/*/telemetry"
    assert K.truth == "swarm/run-1/world/truth"
    assert K.status == "swarm/run-1/world/status"
    assert K.world_all == "swarm/run-1/world/**"
    assert K.everything == "swarm/run-1/**"
    assert K.alive("agent", 2) == "swarm/run-1/alive/agent/2"
    assert K.alive_all("logger") == "swarm/run-1/alive/logger/*"


def test_parse_robot_takes_this_runs_robot_keys_only() -> None:
    assert K.parse_robot(K.obs(2)) == RobotKey(2, "obs")
    assert K.parse_robot(K.telemetry(MAX_ROBOT_ID)) == RobotKey(MAX_ROBOT_ID, "telemetry")
    assert K.parse_robot(K.cmd(1)) == RobotKey(1, "cmd")
    for bad in (
        "swarm/run-2/robot/2/obs",  # another run
        "swarm/run-1/robot/2/obs/x",  # too deep
        "swarm/run-1/robot/2",  # too short
        "swarm/run-1/robot/2/odometry",  # unknown kind
        "swarm/run-1/robot/2/formation",  # codes come on K.codes, for every follower
        K.codes,
        "swarm/run-1/robot/x/obs",  # not an id
        "swarm/run-1/robot/-2/obs",
        "swarm/run-1/robot/0/obs",  # ids start at 1
        f"swarm/run-1/robot/{MAX_ROBOT_ID + 1}/obs",
        K.world_wake,
        K.truth,
    ):
        assert K.parse_robot(bad) is None, bad


def test_parse_alive_takes_this_runs_tokens_only() -> None:
    assert K.parse_alive(K.alive("world", 0)) == ("world", "0")
    assert K.parse_alive(K.alive("agent", 7)) == ("agent", "7")
    assert K.parse_alive(K.alive("logger", "main")) == ("logger", "main")
    for bad in (
        "swarm/run-2/alive/agent/7",
        "swarm/run-1/alive/agent",
        "swarm/run-1/alive/agent/7/x",
        "swarm/run-1/alive/robot/7",
        "swarm/run-1/alive/7/agent",
        K.obs(7),
    ):
        assert K.parse_alive(bad) is None, bad


@pytest.mark.parametrize("rid", [0, -1, MAX_ROBOT_ID + 1, True, 2.0, "2"])
def test_bad_robot_ids_are_refused(rid: object) -> None:
    with pytest.raises(ValueError, match="robot id"):
        check_robot_id(rid)  # type: ignore[arg-type]
    with pytest.raises(ValueError, match="robot id"):
        K.obs(rid)  # type: ignore[arg-type]


def test_robot_ids_from_1_to_the_maximum() -> None:
    assert check_robot_id(1) == 1
    assert check_robot_id(MAX_ROBOT_ID) == MAX_ROBOT_ID == 10_000


@pytest.mark.parametrize("run", ["", "-run", "a/b", "a*", "x" * 65, 7, None])
def test_bad_run_ids_are_refused(run: object) -> None:
    with pytest.raises(ValueError, match="run id"):
        Keys(run)  # type: ignore[arg-type]


def test_run_ids_up_to_64_characters() -> None:
    assert check_run_id("a" * 64) == "a" * 64
    assert check_run_id("Fig11_obstacles-3.2") == "Fig11_obstacles-3.2"


def test_bad_kinds_and_roles_are_refused() -> None:
    with pytest.raises(ValueError, match="kind"):
        K.robot(2, "odometry")
    with pytest.raises(ValueError, match="role"):
        K.alive("robot", 2)
    with pytest.raises(ValueError, match="role"):
        K.alive_all("robot")
