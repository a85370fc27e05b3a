"""How the ``swarm_run`` fixture ends a run that does not end by itself: a
timeout fails the test that called it (not a result the test might read
as a run), Ctrl-C stops the session after every process is stopped."""

from __future__ import annotations

import json
import re
import textwrap
from pathlib import Path

import pytest

from tests.helpers import ROOT

pytest_plugins = ["pytester"]


def test_a_run_past_its_timeout_fails_the_test_and_names_its_folder(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(
        textwrap.dedent(
            """
            def test_slow(swarm_run):
                res = swarm_run("fig11_obstacles", logger=False, timeout_s=0.5)
                raise AssertionError(f"swarm_run returned {res.exit_code}")
            """
        )
    )
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    result.assert_outcomes(failed=1)
    out = result.stdout.str()
    assert "swarm_run: fig11_obstacles did not end within timeout_s=0.5 s" in out
    assert "every process is stopped; its folder: " in out
    assert "swarm_run returned" not in out
    assert "Traceback" not in out  # one line, not the plugin's own stack
    # The run's summary says which limit ended it, in the fixture's terms (no CLI flag).
    folder = out.split("its folder: ", 1)[1].split()[0].rstrip(".;,")
    ended = json.loads((Path(folder) / "summary.json").read_text())["ended"]
    assert ended.startswith("the wall-clock limit of 0.5 s was reached"), ended


def test_ctrl_c_during_a_run_stops_the_session(pytester: pytest.Pytester) -> None:
    # Launch.wait turns Ctrl-C into exit code 130 after stopping every process;
    # here it says so at once (a real Ctrl-C cannot be sent to an inner session).
    pytester.makeconftest(
        textwrap.dedent(
            """
            import pytest
            from formation_swarm.launch import launcher

            @pytest.fixture(autouse=True)
            def interrupted(monkeypatch, tmp_path):
                monkeypatch.setattr(launcher.Launch, "start", lambda self: None)
                monkeypatch.setattr(launcher.Launch, "stop", lambda self, graceful_first=True: None)
                monkeypatch.setattr(launcher.Launch, "wait", lambda self, timeout_s=None:
                                    launcher.RunResult(tmp_path, {}, 130))
            """
        )
    )
    pytester.makepyfile(
        textwrap.dedent(
            """
            def test_first(swarm_run):
                swarm_run("fig11_obstacles")

            def test_never_reached():
                pass
            """
        )
    )
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    assert result.ret == pytest.ExitCode.INTERRUPTED
    assert "KeyboardInterrupt" in result.stdout.str()
    result.assert_outcomes()  # test_never_reached did not run: the session stopped at the first test


def test_a_failed_test_names_the_folders_of_its_runs_and_a_result_prints_short(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(
        textwrap.dedent(
            """
            def test_strict(swarm_run):
                res = swarm_run("fig11_obstacles", logger=False, overrides={"run.duration_s": 1})
                print(res)
                assert res.summary["followers"]["3"]["rms_m"] < 0.0

            def test_mid_run(swarm_launch):
                launch = swarm_launch("fig11_obstacles", mode="realtime")
                assert launch.wait_until(lambda: launch.sim_time() >= 0.2, timeout_s=60)
                assert launch.sim_time() < 0.0
            """
        )
    )
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    result.assert_outcomes(failed=2)
    out = result.stdout.str()
    section = out.split("swarm runs")[1].splitlines()[1]
    assert section.endswith("/test_strict0/run-0 (run " + section.split("(run ")[1])
    assert "; summary.json, logs/)" in section
    # A test that failed while its run went on: what its folder holds then, and why no summary.
    mid = out.split("swarm runs")[2].splitlines()[1]
    assert "/test_mid_run0/run-0 (run " in mid
    assert mid.endswith("; recording.rrd, logs/; no summary.json: the test ended while the run went on)"), mid
    printed = next(line for line in out.splitlines() if line.startswith("RunResult("))
    assert printed.endswith("/test_strict0/run-0'), exit_code=0)")  # not the summary's kB


def test_the_fixture_refuses_wrong_arguments_in_a_sentence(pytester: pytest.Pytester) -> None:
    pytester.makepyfile(
        textwrap.dedent(
            """
            import pytest

            def test_bad(swarm_run):
                with pytest.raises(ValueError, match=r"^swarm_run: timeout_s must be a number of seconds > 0, got -1$"):
                    swarm_run("fig11_obstacles", timeout_s=-1)
                with pytest.raises(ValueError, match=r"^a scenario is a shipped scenario's name or a TOML file's path, "
                                                     r"got int 11$"):
                    swarm_run(11)
                with pytest.raises(ValueError, match=r"^overrides must map scenario keys to values"):
                    swarm_run("fig11_obstacles", overrides=["leader.speed_mps=1.6"])
                with pytest.raises(ValueError, match=r"file not found: my_scn.toml \\(relative to the working"):
                    swarm_run("my_scn.toml")
            """
        )
    )
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    result.assert_outcomes(passed=1)


@pytest.mark.slow
def test_the_docs_fixture_examples_pass_as_written(pytester: pytest.Pytester) -> None:
    """Every ```python block of tests in README's "In your own test suite" and
    in docs/testing.md, run together as a user's test file."""
    after = (ROOT / "README.md").read_text().split("### In your own test suite", 1)[1]
    readme = re.split(r"^##+ ", after, maxsplit=1, flags=re.M)[0]
    testing = (ROOT / "docs" / "testing.md").read_text()
    found = {
        doc: re.findall(r"^```python\n(def test_.*?)^```$", text, re.M | re.S)
        for doc, text in (("README", readme), ("docs/testing.md", testing))
    }
    assert all(found.values()), found
    source = "\n\n".join(block for blocks in found.values() for block in blocks)
    tests = len(re.findall(r"^def test_", source, re.M))
    pytester.makepyfile(source)
    result = pytester.runpytest_subprocess("-p", "no:cacheprovider")
    result.assert_outcomes(passed=tests)
