"""Suite-wide guard: no process of ours may outlive the test session. With
pytest-xdist (``make test``: two workers), the tests of one file stay on one
worker (module fixtures, and test_claims' last test reads the runs of the
tests before it), and every test of tests/hosts/ on one worker: each makes
network namespaces and addresses of its own."""

from __future__ import annotations

import pytest

from tests.helpers import processes


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        path = item.nodeid.split("::", 1)[0]
        group = "hosts" if path.startswith("tests/hosts/") else path
        item.add_marker(pytest.mark.xdist_group(group))


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
