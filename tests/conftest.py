"""Suite-wide: no process of ours may outlive the test session, and the longest files go first."""

from __future__ import annotations

import signal
import threading

import pytest

from tests.helpers import processes


@pytest.fixture(scope="session", autouse=True)
def _no_process_left_behind(tmp_path_factory: pytest.TempPathFactory) -> object:
    # Every process the suite starts names a file under its base temp folder
    # (a run's scenario, a viewer's output): runs of other sessions or users,
    # and processes started before, do not count.
    base = str(tmp_path_factory.getbasetemp())
    before = {pid for pid, _ in processes(lambda cmd: base in cmd)}
    yield
    left = [(pid, cmd) for pid, cmd in processes(lambda cmd: base in cmd) if pid not in before]
    assert not left, f"processes left behind by the suite: {left}"


@pytest.fixture(autouse=True)
def _stop_signals_as_they_were() -> object:
    # A role's main() run in the test process ignores SIGINT and SIGTERM once it
    # returns (runtime.proc.exit_after_main); left so, every process the
    # worker starts later would inherit SIGINT ignored.
    before = {sig: signal.getsignal(sig) for sig in (signal.SIGINT, signal.SIGTERM)}
    yield
    if threading.current_thread() is threading.main_thread():
        for sig, handler in before.items():
            if handler is not None and signal.getsignal(sig) != handler:
                signal.signal(sig, handler)


# The longest files first (in that order: seconds of `make test`'s run, 20 s to 185 s
# of its two workers' time), so that its workers (pytest-xdist, --dist loadfile, files
# handed out one at a time in collection order) take them early and end together; every
# other file keeps its place after them. A stale list only costs balance.
LONGEST_FIRST = (
    "tests/system/test_web_view.py",
    "tests/hosts/test_hosts.py",
    "tests/system/test_distributed.py",
    "tests/system/test_ros2_bridge.py",
    "tests/system/test_claims.py",
    "tests/system/test_process_faults.py",
    "tests/system/test_endings.py",
    "tests/system/test_attacks.py",
    "tests/system/test_external.py",
    "tests/unit/studies/test_published.py",
    "tests/system/test_many_robots.py",
    "tests/system/test_report_gaps.py",
    "tests/system/test_leaked_logins.py",
    "tests/system/test_report.py",
    "tests/system/test_outside_deaths.py",
    "tests/hosts/test_stolen_logins_on_hosts.py",
    "tests/system/test_bad_input.py",
    "tests/system/test_interrupt.py",
    "tests/hosts/test_hosts_netns.py",
    "tests/system/test_ci_doc.py",
    "tests/system/test_slow_controllers.py",
)


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    rank = {path: i for i, path in enumerate(LONGEST_FIRST)}
    items.sort(key=lambda item: rank.get(item.nodeid.split("::", 1)[0], len(rank)))  # stable: the rest in order
