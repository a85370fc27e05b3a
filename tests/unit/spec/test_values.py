"""Every value of a scenario checked before anything starts: numbers finite
and of 64 bits, times within the ticks a message counts, names the scenario as
run writes and every process reads back, files nested no deeper than a limit.
Each refusal is a ScenarioError naming the key and the value."""

from __future__ import annotations

import math
import re
import tomllib
from pathlib import Path
from typing import Any

import pytest

from formation_swarm.common.checks import MAX_TICKS
from formation_swarm.spec import files as scenario_files
from formation_swarm.spec import scenario as sm
from formation_swarm.spec.keys import MAX_DEPTH
from tests.helpers import SCENARIOS

FIG11 = SCENARIOS / "fig11_obstacles.toml"
TICKS = "must be at most 2**53 ticks of run.dt_s = 0.05 s (about 4.504e+14 s, the most a message's tick count carries)"
CUSTOM = {
    "formations.triangle.shape": "custom",
    "formations.triangle.slots": {
        "2": {"reference": 1, "offset": [-1.5, -1.5]},
        "3": {"reference": 1, "offset": [1.5, -1.5]},
    },
}


def refused(overrides: dict[str, Any], path: Path = FIG11) -> sm.ScenarioError:
    """The error loading FIG11 with ``overrides`` raises: one line, naming the file."""
    with pytest.raises(sm.ScenarioError) as info:
        sm.load(path, overrides=overrides)
    assert "\n" not in str(info.value)
    assert str(info.value).startswith(str(path))
    return info.value


@pytest.mark.parametrize(
    ("overrides", "key"),
    [
        ({"leader.waypoints": [[0.0, 0.0], [math.nan, 80.0]]}, "leader.waypoints[1][0]"),
        ({"leader.waypoints": [[0.0, -math.inf], [0.0, 80.0]]}, "leader.waypoints[0][1]"),
        ({"run.dt_s": math.nan}, "run.dt_s"),
        ({"leader.speed_mps": math.inf}, "leader.speed_mps"),
        ({"controller.ekf.q_pos_m": math.nan}, "controller.ekf.q_pos_m"),
        ({"followers": {"2": {"d0_m": math.inf}}}, "followers.2.d0_m"),
        ({"obstacles": [{"x_m": math.inf, "y_m": 36.0, "radius_m": 1.0}]}, "obstacles[0].x_m"),
        (
            {**CUSTOM, "formations.triangle.slots": {"2": {"reference": 1, "offset": [math.nan, -1.5]}}},
            "formations.triangle.slots.2.offset[0]",
        ),
        # Even where the run would not read it: a wedge's slots.
        (
            {"formations.triangle.slots": {"2": {"reference": 1, "offset": [0.0, math.inf]}}},
            "formations.triangle.slots.2.offset[1]",
        ),
        ({"faults": [{"kind": "kill", "target": "agent-3", "at_s": math.nan}]}, "faults[0].at_s"),
    ],
)
def test_a_number_that_is_not_finite_is_refused_wherever_it_is(overrides: dict[str, Any], key: str) -> None:
    err = refused(overrides)
    assert err.key == key
    assert not math.isfinite(err.value)
    assert f"{key} must be a finite number, got {err.value!r}" in str(err)
    assert str(err).endswith(f'(as a string, quote it: "{err.value!r}")')  # a bare nan or inf is TOML's number


@pytest.mark.parametrize(
    ("overrides", "key", "bits"),
    [
        ({"run.duration_s": 10**400}, "run.duration_s", 1329),
        ({"leader.waypoints": [[0, 0], [0, -(2**63) - 1]]}, "leader.waypoints[1][1]", 64),
        ({"leader.id": 2**64}, "leader.id", 65),
    ],
)
def test_an_integer_beyond_64_bits_is_refused(overrides: dict[str, Any], key: str, bits: int) -> None:
    err = refused(overrides)
    assert (err.key, err.value.bit_length()) == (key, bits)
    assert f"{key} must be an integer in [-2**63, 2**63 - 1] (64 bits), got one of {bits} bits" in str(err)


def test_an_integer_of_thousands_of_digits_in_a_file_is_not_valid_toml(tmp_path: Path) -> None:
    path = tmp_path / "digits.toml"
    path.write_text(FIG11.read_text().replace("duration_s = 56.0", "duration_s = 1" + "0" * 5000))
    with pytest.raises(sm.ScenarioError, match=r"digits\.toml: not valid TOML: Exceeds the limit \(4300 digits\)"):
        sm.load(path)
    with pytest.raises(sm.ScenarioError, match=r"^the value '1000*'\.\.\. \(5001 characters\): Exceeds the limit"):
        scenario_files.parse_value("1" + "0" * 5000)


@pytest.mark.parametrize(
    ("overrides", "key"),
    [
        ({"run.duration_s": 1e300}, "run.duration_s"),
        ({"run.duration_s": 1.0, "run.dt_s": 1e-300}, "run.duration_s"),
        ({"run.lockstep_deadline_s": 1e300}, "run.lockstep_deadline_s"),
        ({"leader.clear_after_s": 1e300}, "leader.clear_after_s"),
        ({"controller.hold_after_s": 1e300}, "controller.hold_after_s"),
        ({"followers": {"3": {"lost_after_s": 1e300}}}, "followers.3.lost_after_s"),
    ],
)
def test_a_time_of_more_ticks_than_a_message_counts_is_refused(overrides: dict[str, Any], key: str) -> None:
    err = refused(overrides)
    assert err.key == key
    assert err.value in (1e300, 1.0)
    assert "must be at most 2**53 ticks of run.dt_s" in str(err)


def test_a_run_of_up_to_2_53_ticks_loads_and_a_longer_one_does_not() -> None:
    sc = sm.load(FIG11, overrides={"run.duration_s": 4e14})
    assert sc.ticks == 8 * 10**15 <= MAX_TICKS
    over = (MAX_TICKS + 2) * 0.05  # a tick more than 2**53, past the float's rounding
    err = refused({"run.duration_s": over})
    assert (err.key, err.value) == ("run.duration_s", over)
    assert f"run.duration_s {TICKS}, got {over!r}" in str(err)


@pytest.mark.parametrize(
    ("fault", "message"),
    [
        ("kill agent-3@1e308s", "fault 'kill agent-3@1e+308s': starts at 1e+308 s, at or after the run's end (56 s;"),
        ("drop obs:2@1s for=1e308s p=0.5", "fault 'drop obs:2@1s for=1e+308s p=0.5': for must be at most 2**53 ticks"),
        ("restart agent-2@1s after=1e308s", "fault 'restart agent-2@1s after=1e+308': after must be at most 2**53"),
    ],
)
def test_a_fault_time_beyond_the_run_is_refused_in_a_line(fault: str, message: str) -> None:
    with pytest.raises(sm.ScenarioError) as info:
        sm.load(FIG11, faults=[fault])
    assert message in str(info.value)


@pytest.mark.parametrize("vn", [-3, 0, -0.5])
def test_a_static_vn_out_of_range_names_the_key_as_written(vn: float) -> None:
    err = refused({"controller.vn": vn})
    assert (err.key, err.value) == ("controller.vn", vn)
    assert f"controller.vn must be 'dynamic' or a number > 0, got {vn!r}" in str(err)
    assert "static_vn" not in str(err)
    err = refused({"followers": {"2": {"vn": vn}}})
    assert (err.key, err.value) == ("followers.2.vn", vn)


@pytest.mark.parametrize("rid", ["9", "1", "x"])  # no robot of the run; the leader (robot 1); no id at all
def test_a_followers_table_of_no_follower_is_refused(rid: str) -> None:
    err = refused({f"followers.{rid}.vn": 1.0})
    assert (err.key, err.value) == (f"followers.{rid}", {"vn": 1.0})
    assert "not a follower id" in str(err)


# Names every process reads back from the scenario as run: accepted, whatever their script.
NAMES = ["triángulo", "日本語の隊形", "🚀", "a b", "a.b", 'a"b', "a\\b", "x = 1", "[line]", "#1", "Ünïcödé-line_2"]


@pytest.mark.parametrize("name", NAMES)
def test_a_formation_of_any_name_makes_the_round_trip_through_the_scenario_as_run(tmp_path: Path, name: str) -> None:
    raw = tomllib.loads(FIG11.read_text())
    raw["formations"] = {name if k == "triangle" else k: v for k, v in raw["formations"].items()}
    raw["leader"]["formation"] = name
    sc = sm.from_dict(raw)
    assert sc.formation_names == (name, "line")
    written = tmp_path / "scenario.toml"  # as the launcher writes it for every process
    written.write_text(scenario_files.dumps(sc.raw))
    again = sm.load(written)
    assert again.raw == sc.raw
    assert again.formation_names == (name, "line")
    assert again.formations[name] == sc.formations[name]


def test_any_text_makes_the_round_trip_through_the_writer() -> None:
    raw = {
        "run": {"name": 'tab\there, new\nline, nul\x00, del\x7f, escape\x1b, quote", back\\slash, é, \u2028'},
        "formations": {"tri á": {"shape": "custom", "slots": {"2": {"reference": 1, "offset": [1.5, -1.5]}}}},
        "faults": [{"kind": "kill", "target": "agent-3", "at_s": 20.0}],
        "placement": {"1": "b"},
        "odd keys": {"é": 1, "a.b": {"c d": [1, {"e\nf": "g"}]}},
    }
    text = scenario_files.dumps(raw)
    assert tomllib.loads(text) == raw
    assert '[formations."tri á"]\n' in text
    # Only what TOML cannot write bare is quoted: the shipped scenarios are written as they were.
    text = scenario_files.dumps(tomllib.loads(FIG11.read_text()))
    assert "[formations.triangle]\n" in text
    assert 'name = "fig11-obstacles"' in text
    assert '[placement]\n"1" = "b"\n' in scenario_files.dumps({"placement": {"1": "b"}})


@pytest.mark.parametrize(
    ("where", "name", "message"),
    [
        ("formation", "tri\tangle", "a formation's name must be one line of printable text, got 'tri\\tangle'"),
        ("formation", "tri\nangle", "(it holds '\\n')"),
        ("run", "fig\n11", "run.name must be one line of printable text, got 'fig\\n11'"),
        ("run", "a\udcff", "run.name must be text that UTF-8 can write, got 'a\\udcff'"),
    ],
)
def test_a_name_the_run_cannot_print_or_carry_is_refused(where: str, name: str, message: str) -> None:
    raw = tomllib.loads(FIG11.read_text())
    if where == "formation":
        raw["formations"][name] = raw["formations"].pop("triangle")
        raw["leader"]["formation"] = name
    else:
        raw["run"]["name"] = name
    with pytest.raises(sm.ScenarioError) as info:
        sm.from_dict(raw)
    assert (info.value.key, info.value.value) == ("run.name" if where == "run" else f"formations.{name}", name)
    assert message in str(info.value)


def test_a_run_name_with_letters_beyond_ascii_is_refused_and_other_characters_load() -> None:
    """launch.plan makes the run's id (its Zenoh keys, its folder) of the name's
    ASCII letters and digits, any other character a '-': a letter it cannot keep is refused."""
    for name in ("café", "隊形", "x²"):
        err = refused({"run.name": name})
        assert (err.key, err.value) == ("run.name", name)
    said = "run.name must write its letters and digits in ASCII (the run's id and folder are made of them;"
    assert f"{said} other characters become '-'), got 'x²'" in str(err)
    for name in ("a/b", "x y", "run → 2", ""):
        assert sm.load(FIG11, overrides={"run.name": name}).name == name


@pytest.mark.parametrize(
    "text",
    ["[run]\nname = " + "[" * 100_000 + "]" * 100_000, "x = " + "{a = " * 5_000 + "1" + "}" * 5_000],
    ids=["arrays 100,000 deep", "inline tables 5,000 deep"],
)
def test_a_file_nested_past_the_limit_is_one_error_naming_it(tmp_path: Path, text: str) -> None:
    path = tmp_path / "deep.toml"
    path.write_text(text + "\n")
    with pytest.raises(
        sm.ScenarioError, match=f"^{re.escape(str(path))}: arrays or inline tables nested more than {MAX_DEPTH} deep$"
    ):
        sm.load(path)


def test_nesting_past_the_limit_that_the_reader_takes_is_refused_with_its_key(tmp_path: Path) -> None:
    path = tmp_path / "deep.toml"
    path.write_text(FIG11.read_text() + "\n[links]\nx = " + "[" * 40 + "]" * 40 + "\n")
    with pytest.raises(sm.ScenarioError) as info:
        sm.load(path)
    key = "links.x" + "[0]" * (MAX_DEPTH - 2)  # the file, [links] and x are 3 levels
    assert info.value.key == key
    assert f"{path}: {key}: tables and arrays nested more than {MAX_DEPTH} deep (a scenario needs 6)" in str(info.value)
    deep: list[Any] = []
    for _ in range(10_000):  # from Python, without a file: refused, not a RecursionError
        deep = [deep]
    with pytest.raises(sm.ScenarioError, match=f"nested more than {MAX_DEPTH} deep"):
        sm.load(FIG11, overrides={"leader.waypoints": deep})


def test_a_command_line_value_or_key_nested_past_the_limit_is_refused() -> None:
    with pytest.raises(
        sm.ScenarioError, match=rf"^--set leader.waypoints: the value '\[\[\[.*nested more than {MAX_DEPTH}"
    ) as info:
        scenario_files.parse_override("leader.waypoints=" + "[" * 100_000 + "]" * 100_000)
    assert info.value.key == "leader.waypoints"
    with pytest.raises(sm.ScenarioError, match=f"a key of at most {MAX_DEPTH} parts, got 3000"):
        scenario_files.parse_override(".".join(["a"] * 3000) + "=1")
