"""An agent written from docs/protocol.md alone flies beside ours.

tests/helpers/foreign_follower.py imports nothing of formation_swarm (checked
below): it is what someone writing an agent in another language would
write from the document. It flies the follower of the paper's two-robot
turn (fig7_turn_vn_dynamic) in lockstep with our world and our leader: the
run must complete with every tick answered and a bounded formation error.
Two of them fly Fig. 11's followers with drops on their links: they must
change formation with our leader, one tick after it at the earliest. Its
reading of the document is also checked against our code where the
document gives a formula: link-fault draws and formation slots; and its
client's configuration against the document's table. (With a login, as the
outside agent of a swarm run: tests/system/test_external.py.)
"""

from __future__ import annotations

import ast
import json
import re
import subprocess
import sys
import time
import tomllib
import uuid
from pathlib import Path

import pytest

from formation_swarm.launch.launcher import free_port
from formation_swarm.protocol import trust
from formation_swarm.protocol.links import uniform
from formation_swarm.spec import files as scenario_files
from formation_swarm.spec import scenario as scenario_mod
from tests.helpers import ROOT, SCENARIOS
from tests.helpers import foreign_follower as foreign

FOREIGN = Path(foreign.__file__)
TURN = SCENARIOS / "fig7_turn_vn_dynamic.toml"
FIG11 = SCENARIOS / "fig11_obstacles.toml"


def test_the_foreign_follower_imports_nothing_of_ours() -> None:
    tree = ast.parse(FOREIGN.read_text())
    imported = {a.name for n in ast.walk(tree) if isinstance(n, ast.Import) for a in n.names}
    imported |= {n.module for n in ast.walk(tree) if isinstance(n, ast.ImportFrom) and n.module}
    roots = {name.split(".")[0] for name in imported}
    assert roots <= set(sys.stdlib_module_names) | {"msgpack", "zenoh"}, roots


def test_its_client_configuration_is_the_documents(tmp_path: Path) -> None:
    """docs/protocol/session.md, "The client's configuration": the settings an
    outside process needs, its login read from the file format the document gives."""
    doc = (ROOT / "docs" / "protocol" / "session.md").read_text().split("## The client's configuration", 1)[1]
    rows = dict(re.findall(r"^\| `([^`]+)` \| `([^`]+)` \|", doc, re.MULTILINE))
    files = trust.write_run_secrets(tmp_path / "secrets", "r1", (1, 2, 3), leader_id=1)
    conf = foreign.client_config(json.loads(rows["connect/endpoints"])[0], str(files["agent-2"]))
    for path in ("mode", "connect/endpoints", "connect/retry", "scouting/multicast/enabled"):
        assert json.loads(conf.get_json(path)) == json.loads(rows[path]), path
    assert json.loads(conf.get_json("connect/timeout_ms")) >= 60_000  # the router may come a minute later
    assert json.loads(conf.get_json("transport/auth/usrpwd"))["user"] == "agent-2"


def test_its_link_fault_draws_are_ours() -> None:
    for seed in (0, 1, -5, 2**40):
        for link in ("obs:0>2", "formation:1>3", "cmd:7>0"):
            for seq in (0, 1, 2, 1000, 2**53):
                assert foreign.link_uniform(seed, link, seq) == uniform(seed, link, seq)


@pytest.mark.parametrize("name", sorted(scenario_files.shipped()))
def test_its_formation_slots_are_ours(name: str) -> None:
    path = scenario_files.shipped()[name]
    sc = scenario_mod.load(path)
    theirs = foreign.formation_slots(tomllib.loads(path.read_text()))
    assert len(theirs) == len(sc.formation_names)
    for code, slots in enumerate(theirs):
        ours = sc.formation_by_code(code).slots
        assert slots.keys() == ours.keys()
        for rid, (reference, offset) in slots.items():
            assert reference == ours[rid].reference
            assert offset == pytest.approx(tuple(ours[rid].offset), abs=1e-12)


def _fly(tmp_path: Path, scenario_file: Path, foreign_ids: tuple[int, ...], overrides: tuple[str, ...] = ()) -> dict:
    """World (router on a free loopback port), our leader (robot 1) and a foreign
    follower per id, in lockstep; every process reaped. The stats of each."""
    scenario = tmp_path / "scenario.toml"
    sc = scenario_mod.load(scenario_file, dict(scenario_files.parse_override(o) for o in overrides))
    scenario.write_text(scenario_files.dumps(sc.raw))
    endpoint = f"tcp/127.0.0.1:{free_port()}"
    common = ["--scenario", str(scenario), "--run", f"foreign-{uuid.uuid4().hex[:8]}"]
    procs: dict[str, subprocess.Popen[bytes]] = {}

    def start(name: str, argv: list[str]) -> None:
        with open(tmp_path / f"{name}.log", "wb") as log:
            procs[name] = subprocess.Popen(
                [*argv, "--stats", str(tmp_path / f"{name}.json")],
                stdout=log,
                stderr=subprocess.STDOUT,
                stdin=subprocess.DEVNULL,
            )

    def log(name: str) -> str:
        return (tmp_path / f"{name}.log").read_text()

    try:
        start(
            "world",
            [
                sys.executable,
                "-m",
                "formation_swarm.nodes.world.main",
                *common,
                "--mode",
                "lockstep",
                "--zenoh-mode",
                "router",
                "--listen",
                endpoint,
            ],
        )
        start(
            "leader",
            [sys.executable, "-m", "formation_swarm.nodes.agent.main", "--id", "1", *common, "--connect", endpoint],
        )
        for rid in foreign_ids:
            start(f"foreign-{rid}", [sys.executable, str(FOREIGN), "--id", str(rid), *common, "--connect", endpoint])
        # A run of ~1,000 ticks takes 1-2 s here once all are up, start-up ~2 s;
        # the world gives up on its own after 60 s without every agent.
        assert procs["world"].wait(timeout=90) == 0, log("world")
        for name, p in procs.items():  # every agent leaves on the world's "done"
            assert p.wait(timeout=10) == 0, (name, log(name))
    finally:
        for p in procs.values():
            if p.poll() is None:
                p.terminate()
        for p in procs.values():
            try:
                p.wait(timeout=5)
            except subprocess.TimeoutExpired:
                p.kill()
                p.wait()
    return {name: json.loads((tmp_path / f"{name}.json").read_text()) for name in procs}


def _report(label: str, world: dict, t0: float) -> None:
    errs = ", ".join(f"R{r} RMS {m['rms_m']:.3f} m max {m['max_m']:.3f} m" for r, m in world["followers"].items())
    print(f"{label}: {world['ticks']} ticks, misses {world['lockstep_misses']}, {errs}, {time.monotonic() - t0:.1f} s")


def test_a_foreign_follower_flies_the_turn_in_lockstep(tmp_path: Path) -> None:
    t0 = time.monotonic()
    stats = _fly(tmp_path, TURN, (2,))
    world, leader, theirs = stats["world"], stats["leader"], stats["foreign-2"]
    _report("fig7, foreign R2", world, t0)
    # The whole path ran and every tick was answered in time, by both.
    assert world["ticks"] == 880
    assert world["lockstep_misses"] == 0
    assert world["late_answers"] == 0
    assert world["deaths"] == []
    assert world["rejected"] == {}
    assert leader["rejected"] == {}
    assert theirs["rejected"] == {}
    assert theirs["exit"] == "done"
    assert theirs["done_tick"] == world["ticks"]
    assert theirs["answered"] == leader["answered"] == world["ticks"]
    assert theirs["no_reading"] == 0  # the leader is always in view here
    # The leader's code (one formation) kept coming and changed nothing: every
    # tick for 1 s (b = 20 ticks: s = 0..20), then every 0.5 s (p = 10): s = 30, ..., 870.
    assert theirs["codes_received"] == 21 + (879 - 20) // 10
    assert theirs["changes"] == []
    assert world["formation_events"] == []
    # Measured (seed 1, deterministic): RMS 0.073 m, max 0.248 m; our fuzzy
    # follower flies the same run with RMS 0.742 m, max 1.389 m.
    err = world["followers"]["2"]
    assert err["rms_m"] < 0.15
    assert err["max_m"] < 0.5


def test_two_foreign_followers_change_formation_with_our_leader(tmp_path: Path) -> None:
    """Fig. 11: triangle -> line before the obstacles -> triangle, with drops on
    every link an agent receives, so the foreign link layer and the code rule work."""
    t0 = time.monotonic()
    drops = ("links.obs_drop=0.1", "links.formation_drop=0.3")
    stats = _fly(tmp_path, FIG11, (2, 3), drops)
    world, leader = stats["world"], stats["leader"]
    _report("fig11, foreign R2 and R3, drops", world, t0)
    assert world["leader_done"]  # the leader reached the end of its path (before 56 s)
    assert world["lockstep_misses"] == 0
    assert leader["answered"] == world["ticks"]
    assert leader["rejected"] == {}
    assert world["deaths"] == []
    events = [(e["robot"], e["formation"], e["tick"]) for e in world["formation_events"]]
    led = [(name, tick) for r, name, tick in events if r == 1]
    assert [name for name, _ in led] == ["line", "triangle"]
    for rid in (2, 3):
        theirs = stats[f"foreign-{rid}"]
        assert theirs["answered"] == world["ticks"]
        assert theirs["rejected"] == {}
        # Its link layer dropped about the scenario's share, and a dropped observation was still answered.
        assert 0.05 < theirs["obs_dropped"] / world["ticks"] < 0.15  # ~1,060 observations: +-5 sd
        assert theirs["no_reading"] == theirs["obs_dropped"]
        assert 0.15 < theirs["formation_dropped"] / theirs["codes_received"] < 0.45  # ~160 codes: +-4 sd
        followed = [(name, tick) for r, name, tick in events if r == rid]
        assert [name for name, _ in followed] == ["line", "triangle"]
        # A code stamped k takes effect at k + 1 at the earliest; a dropped code
        # is repeated every tick for 1 s after a change.
        for (_, lead_tick), (_, tick) in zip(led, followed, strict=True):
            assert lead_tick + 1 <= tick <= lead_tick + 20
    # Measured over 7 runs: R2 RMS 0.167-0.173 m, R3 RMS 0.704-0.727 m (max 1.50-1.51
    # and 4.21-4.32 m: a change moves the target by a slot's width at once, and R3's
    # slot moves most). Not one figure: with observation drops a lockstep run is not
    # bit-reproducible (docs/protocol.md, "Link faults"). Our fuzzy followers, without
    # drops: 0.52 m and 1.04 m.
    assert world["followers"]["2"]["rms_m"] < 0.35
    assert world["followers"]["3"]["rms_m"] < 1.2
