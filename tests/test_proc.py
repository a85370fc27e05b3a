"""swarm.proc's JsonWriter: the newest snapshot reaches the file, off the caller's thread."""

from __future__ import annotations

import json
import threading
from pathlib import Path

from formation_swarm import proc


def test_the_writer_writes_the_newest_snapshot_and_a_copy_of_it(tmp_path: Path) -> None:
    path = tmp_path / "stats" / "agent-2.json"
    w = proc.JsonWriter(str(path))
    holds = [[1, 2]]
    w.offer({"answered": 1, "holds": holds})
    holds.append([5, 9])  # changed by the caller after the offer: the file keeps what was offered
    w.offer({"answered": 2, "holds": holds[:1], "nan": float("nan")})
    w.close()
    assert json.loads(path.read_text()) == {"answered": 2, "holds": [[1, 2]], "nan": None}
    assert not path.with_suffix(".json.tmp").exists()
    assert w.errors == 0


def test_a_slow_write_does_not_hold_the_caller_and_later_offers_replace_waiting_ones(
    tmp_path: Path, monkeypatch: object
) -> None:
    path = tmp_path / "s.json"
    release = threading.Event()
    written: list[int] = []
    real = proc.write_json

    def slow(p: str | None, data: dict) -> None:
        release.wait(10.0)
        written.append(data["n"])
        real(p, data)

    monkeypatch.setattr(proc, "write_json", slow)  # type: ignore[attr-defined]
    w = proc.JsonWriter(str(path))
    for n in range(50):  # none of these waits for the disk
        w.offer({"n": n})
    release.set()
    w.close()
    assert written[-1] == 49
    assert len(written) <= 2  # the first, if the thread took it before the rest came, and the newest
    assert json.loads(path.read_text()) == {"n": 49}


def test_an_unwritable_path_is_counted_not_raised(tmp_path: Path) -> None:
    blocker = tmp_path / "file"
    blocker.write_text("")
    w = proc.JsonWriter(str(blocker / "sub" / "s.json"))  # a file where a folder should be
    w.offer({"n": 1})
    w.close()
    assert w.errors == 1


def test_no_path_writes_nothing_and_starts_no_thread() -> None:
    w = proc.JsonWriter(None)
    w.offer({"n": 1})
    w.close()
    assert w.errors == 0
