"""summary.json and scenario.toml as hostile input (report.inputs): each
refusal one ValueError naming the file and the fault."""

from __future__ import annotations

import json
import os
import re
import sys
from pathlib import Path

import pytest

from formation_swarm.report import inputs
from formation_swarm.report.inputs import read_scenario, read_summary
from formation_swarm.report.schema import SUMMARY, check
from formation_swarm.spec.files import shipped

GOOD = {"run_id": "r", "seed": 1, "followers": {"2": {"rms_m": 0.1}}}


def refused(path: Path, text: str | bytes) -> str:
    """What read_summary says of ``path`` holding ``text``."""
    if isinstance(text, str):
        path.write_text(text)
    else:
        path.write_bytes(text)
    with pytest.raises(ValueError, match=re.escape(str(path))) as err:
        read_summary(path)
    return str(err.value)


def with_field(**fields: object) -> str:
    return json.dumps({**GOOD, **fields})


SUMMARIES = {
    "a follower's metrics as an array": (
        with_field(followers={"2": [1, 2]}),
        "followers.2 must be an object, got an array",
    ),
    "a seed as text": (with_field(seed="7"), "seed must be an integer, got the string '7'"),
    "a number as true": (with_field(ticks=True), "ticks must be an integer, got true"),
    "an event of null": (with_field(events=[None]), "events[0] must not be null"),
    "a fault's time as text": (
        with_field(faults=[{"at_s": "5"}]),
        "faults[0].at_s must be a number, got the string '5'",
    ),
    "laws as an array": (with_field(laws=[]), "laws must be an object, got an array"),
    "NaN": (with_field().replace('"seed": 1', '"x": NaN'), "holds NaN, which no run writes (a number must be finite)"),
    "Infinity": (with_field().replace('"seed": 1', '"x": -Infinity'), "holds -Infinity, which no run writes"),
    "1e999": (with_field().replace("0.1", "1e999"), "holds 1e999, a number too large for a float"),
    "an integer of 30 digits": (with_field().replace('"seed": 1', '"seed": ' + "9" * 30), "integer of 30 digits"),
    "an integer past 64 bits": (with_field(seed=2**64), f"the integer {2**64}, larger than any run writes (64 bits)"),
    "33 levels": (with_field(x=json.loads("[" * 32 + "]" * 32)), "arrays or objects nested more than 32 deep"),
    "100000 levels": (with_field()[:-1] + ', "x": ' + "[" * 100_000 + "]" * 100_000 + "}", "nested more than 32"),
    "not an object": ("[1, 2]", "is not a run summary (a JSON object with the run's run_id)"),
    "no run_id": ('{"seed": 1}', "is not a run summary"),
    "not JSON": ("{nope", "is not valid JSON: Expecting property name enclosed in double quotes"),
    "random bytes": (bytes(range(256)) * 4, "is not valid JSON: "),
}


@pytest.mark.parametrize("case", list(SUMMARIES))
def test_a_summary_it_refuses_is_named_with_its_fault(tmp_path: Path, case: str) -> None:
    text, said = SUMMARIES[case]
    path = tmp_path / "summary.json"
    message = refused(path, text)
    assert message.startswith(str(path))
    assert said in message
    assert "\n" not in message


def test_a_good_summary_reads_back_as_written(tmp_path: Path) -> None:
    path = tmp_path / "summary.json"
    path.write_text(json.dumps({**GOOD, "x": json.loads("[" * 31 + "]" * 31), "unread": {"any": "thing"}}))
    assert read_summary(path)["followers"] == {"2": {"rms_m": 0.1}}


def test_a_summary_over_the_size_limit_or_not_a_file(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.setattr(inputs, "MAX_SUMMARY_BYTES", 2**20)
    path = tmp_path / "summary.json"
    assert re.findall(r"^(.+): larger than (\d+) MiB", refused(path, with_field(pad=" " * 2**20))) == [(str(path), "1")]
    path.unlink()
    os.mkfifo(path)  # a read would block for ever
    with pytest.raises(ValueError, match=r": not a regular file$"):
        read_summary(path)


def test_the_schema_names_the_first_key_at_fault() -> None:
    with pytest.raises(ValueError, match=r"^parts\.logger\.target_errors\.3\.ekf_rms_m must be a number, got"):
        check({"parts": {"logger": {"target_errors": {"3": {"ekf_rms_m": "x"}}}}}, SUMMARY)
    with pytest.raises(ValueError, match=r"^faults\[1\]\.recoveries\[0\]\.watched must be an array, got the number 2"):
        check({"faults": [{}, {"recoveries": [{"watched": 2}]}]}, SUMMARY)
    check({"followers": {"2": None}, "ticks": None, "unread": [None]}, SUMMARY)  # null: absent; unread keys: free


FIG7 = shipped()["fig7_turn_vn_dynamic"].read_text()
SCENARIOS = {
    "random bytes": (bytes(range(256)), "is not a scenario: not UTF-8 text (invalid start byte at byte 128)"),
    "not TOML": ("[run\n", "is not valid TOML: "),
    "a wrong type": (FIG7.replace("robots = 2", 'robots = "two"'), "run.robots must be an integer, got 'two'"),
    "NaN": (FIG7.replace("[run]", "[run]\ndt_s = nan", 1).replace("dt_s = 0.05", ""), "run.dt_s must be a finite"),
    "inf": (FIG7 + "\n[robot]\ndiameter_m = inf\n", "robot.diameter_m must be a finite number, got inf"),
    "deep arrays": ("x = " + "[" * 100_000 + "]" * 100_000 + "\n", "arrays or inline tables nested more than 32 deep"),
    "33 levels": ("x = " + "[" * 33 + "]" * 33 + "\n", "nested more than 32 deep"),
}


@pytest.mark.parametrize("case", list(SCENARIOS))
def test_a_scenario_it_refuses_is_named_with_its_fault(tmp_path: Path, case: str) -> None:
    text, said = SCENARIOS[case]
    path = tmp_path / "scenario.toml"
    if isinstance(text, str):
        path.write_text(text)
    else:
        path.write_bytes(text)
    with pytest.raises(ValueError, match=f"^{re.escape(str(path))}") as err:
        read_scenario(path)
    assert said in str(err.value)


def test_a_scenario_of_a_users_law_reads_without_importing_it(tmp_path: Path) -> None:
    path = tmp_path / "scenario.toml"
    law = "no_such_module_p6:Follower"
    text = FIG7.replace(
        "[controller]", f'[robot]\nmax_wheel_mps = 1.0\n\n[controller]\nlaw = "{law}"\nparams = {{ k = 1 }}'
    )
    path.write_text(text)
    found = read_scenario(path)
    assert found is not None
    raw, sc = found
    assert raw["controller"]["law"] == law  # the tables as run, for the laws said
    assert (sc.dt_s, len(sc.formations)) == (0.05, 1)
    assert "no_such_module_p6" not in sys.modules
    assert read_scenario(tmp_path / "none.toml") is None  # no scenario: none to check
