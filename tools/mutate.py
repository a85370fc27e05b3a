"""Mutation testing of the pure modules with cosmic-ray: ``make mutate``.

    python tools/mutate.py [MODULE ...] [--fresh] [--list-survivors]

For each module of ``MODULES`` (the maths in agents/ and world/, the wire in
protocol/, the metrics, the sweep's aggregate and the results table),
cosmic-ray lists the mutants (one small change each: an operator, a number,
a comparison, a boolean...), this script applies each one in place, runs the
module's fast tests against the editable install, and records whether a test
failed (killed) or all passed (survived). The file is restored after each
mutant, also on Ctrl-C. Sessions live in ``.mutation/`` and resume: a second
run only runs the mutants not yet run, unless the module changed (or --fresh).

Why this runner and not ``cosmic-ray exec``: cosmic-ray starts the test
command afresh for every mutant, and here most of that (~1.2 s) is importing
pytest, numpy, scipy and filterpy. This script imports them once and forks a
child per mutant, which imports our (mutated) modules from disk and runs
pytest: the same verdicts, ~4x faster. The sessions are cosmic-ray's own
databases, so ``cr-report .mutation/agents.ekf.sqlite`` reads them too.

Left out on purpose: binary operators replaced by shifts or bitwise ones
(``a + b`` -> ``a << b``): on floats each is a TypeError, killed by any test
that runs the line, which would only pad the score. Surviving mutants judged
equivalent (no test can tell them from the original) are listed in
``tools/equivalent_mutants.txt`` with a reason, and left out of the score.

Score: killed / (killed + survived), equivalents excluded. A mutant that
runs past its time limit (an endless loop) counts as killed, as in cosmic-ray.
"""

from __future__ import annotations

import argparse
import ast
import contextlib
import hashlib
import os
import re
import select
import signal
import sys
import tempfile
import time
from dataclasses import dataclass
from pathlib import Path

ROOT = Path(__file__).resolve().parent.parent
STATE = ROOT / ".mutation"
EQUIVALENTS = ROOT / "tools" / "equivalent_mutants.txt"
# Shifts and bitwise operators as replacements: a TypeError on floats (see above).
EXCLUDED_OPERATORS = re.compile(r"core/ReplaceBinaryOperator_\w+_(RShift|LShift|BitOr|BitAnd|BitXor)$")
PYTEST_ARGS = ("-x", "-q", "-m", "not slow", "-p", "no:cacheprovider", "-W", "ignore::DeprecationWarning")


@dataclass(frozen=True)
class Module:
    path: str  # in the repository
    tests: tuple[str, ...]  # pytest arguments: the fast tests that exercise it
    scope: tuple[str, ...] = ()  # top-level names to mutate (functions, constants); () = the whole file

    @property
    def name(self) -> str:
        return self.path.removesuffix(".py").replace("/", ".")


def T(name: str) -> str:  # noqa: N802 - reads as the tests folder
    """A test file's path (``name`` may end in ``::test``) wherever under tests/ it lives."""
    file, sep, node = name.partition("::")
    found = sorted((ROOT / "tests").rglob(file))
    if len(found) != 1:
        raise SystemExit(f"tools/mutate.py: {len(found)} test files named {file} under tests/")
    return f"{found[0].relative_to(ROOT)}{sep}{node}"


PUBLISHED = T("test_published.py")  # the published figures recomputed (seconds): last, it is the slowest


def _unit_tests(path: str, fixtures: tuple[str, ...] = ("swarm_run", "swarm_launch", "tmp_path")) -> tuple[str, ...]:
    """The tests of a file that take none of ``fixtures`` (start no process)."""
    tree = ast.parse((ROOT / path).read_text())
    return tuple(
        f"{path}::{node.name}"
        for node in tree.body
        if isinstance(node, ast.FunctionDef)
        and node.name.startswith("test_")
        and not {a.arg for a in node.args.args} & set(fixtures)
    )


# The tests of tests/system/test_process_faults.py that start no process.
PROCESS_FAULT_UNITS = _unit_tests(T("test_process_faults.py"))
MODULES = (
    Module(
        "agents/geometry.py",
        (T("test_geometry.py"), T("test_ekf.py"), T("test_follower.py"), T("test_avoidance.py"), PUBLISHED),
    ),
    Module("agents/ekf.py", (T("test_ekf.py"), T("test_follower.py"), T("test_closed_loop.py"), PUBLISHED)),
    Module(
        "agents/fuzzy.py",
        (
            T("test_fuzzy.py"),
            T("test_follower.py"),
            T("test_closed_loop.py"),
            T("test_formation_tree.py"),
            PUBLISHED,
        ),
    ),
    Module("agents/avoidance.py", (T("test_geometry.py"), T("test_avoidance.py"), T("test_follower.py"), PUBLISHED)),
    *(
        Module(
            path,
            (
                T("test_follower.py"),
                T("test_closed_loop.py"),
                T("test_avoidance.py"),
                T("test_ekf.py"),
                T("test_lpsi.py"),
                T("test_formation_tree.py"),
                PUBLISHED,
            ),
        )
        for path in ("agents/tracking.py", "agents/fuzzy_controller.py", "agents/lpsi_controller.py")
    ),
    *(
        Module(path, (T("unit/agents/test_roles.py"), T("test_agent_inputs.py"), PUBLISHED))
        for path in ("agents/follower_role.py", "agents/leader_role.py", "agents/leader_policy.py")
    ),
    Module(
        "agents/formation.py", (T("test_formation_tree.py"), T("test_geometry.py"), T("test_scenario.py"), PUBLISHED)
    ),
    Module("agents/sight.py", (T("test_formation_tree.py"), T("test_scenario.py"))),
    Module("agents/leader.py", (T("test_leader.py"), PUBLISHED)),
    Module("agents/lpsi.py", (T("test_lpsi.py"), T("test_follower.py"), PUBLISHED)),
    Module("agents/pilot.py", (T("test_pilot.py"), T("test_closed_loop.py"), PUBLISHED)),
    Module(
        "world/kinematics.py",
        (
            T("test_kinematics.py"),
            T("test_camera.py"),
            T("test_geometry.py"),
            T("unit/world/test_engine.py"),
            PUBLISHED,
        ),
    ),
    Module("world/camera.py", (T("test_camera.py"), T("test_camera_frame.py"), T("test_geometry.py"), PUBLISHED)),
    Module(
        "world/engine.py",
        (
            T("unit/world/test_engine.py"),
            T("test_world_engine.py"),
            T("test_camera_frame.py"),
            T("test_sensor_actuator_faults.py"),
            T("test_avoidance.py"),
            PUBLISHED,
        ),
    ),
    Module("world/hardware_faults.py", (T("test_sensor_actuator_faults.py"),)),
    Module(
        "protocol/keys.py",
        (
            T("test_keys.py"),
            T("test_protocol.py"),
            T("test_messages.py"),
            T("test_agent_inputs.py"),
            T("test_world_inputs.py"),
        ),
    ),
    Module("protocol/links.py", (T("test_links.py"),)),
    Module(
        "protocol/codec.py",
        (T("test_messages.py"), T("test_protocol.py"), T("test_agent_inputs.py"), T("test_world_inputs.py")),
    ),
    Module(
        "protocol/messages.py",
        (T("test_messages.py"), T("test_protocol.py"), T("test_agent_inputs.py"), T("test_world_inputs.py")),
    ),
    Module("protocol/batch.py", (T("test_protocol.py"), T("test_messages.py"))),
    Module("protocol/acl.py", (T("test_trust_rules.py"), T("test_observer_rules.py"))),
    Module("protocol/trust.py", (T("test_trust_rules.py"),)),
    Module("protocol/tls.py", (T("test_tls.py"),)),
    Module("agents/inbox.py", (T("test_inbox.py"), T("test_agent_inputs.py"), T("test_world_inputs.py"))),
    Module("swarm/common/faults/__init__.py", (T("test_fault_grammar.py"),)),
    Module("swarm/common/faults/kinds.py", (T("test_fault_grammar.py"),)),
    Module("swarm/common/faults/schedule.py", (T("test_fault_grammar.py"),)),
    Module("world/process_faults.py", PROCESS_FAULT_UNITS),
    Module("world/recovery.py", PROCESS_FAULT_UNITS),
    Module(
        "swarm/studies/tables.py",
        (T("test_results.py"), T("test_sweep.py::test_aggregate_mean_std_and_t_interval")),
        scope=("_T975", "aggregate", "_is_number"),
    ),
    Module(
        "swarm/studies/results.py",
        (T("test_results.py"),),
        scope=("CONTROLLERS", "DROPS", "NOISE", "jobs", "table", "write_into", "unfit_runs"),
    ),
)


# -- the mutants -----------------------------------------------------------------


def _scope_lines(path: Path, names: tuple[str, ...]) -> set[int]:
    """Line numbers of the top-level definitions and assignments named."""
    lines: set[int] = set()
    for node in ast.parse(path.read_text()).body:
        if isinstance(node, (ast.FunctionDef, ast.ClassDef)):
            found = node.name in names
        elif isinstance(node, (ast.Assign, ast.AnnAssign)):
            targets = node.targets if isinstance(node, ast.Assign) else [node.target]
            found = any(isinstance(t, ast.Name) and t.id in names for t in targets)
        else:
            found = False
        if found:
            first = min([node.lineno] + [d.lineno for d in getattr(node, "decorator_list", [])])
            lines.update(range(first, (node.end_lineno or node.lineno) + 1))
    return lines


def _annotation_spans(path: Path) -> list[tuple[tuple[int, int], tuple[int, int]]]:
    """(start, end) positions of every type annotation: with ``from __future__
    import annotations`` none is ever evaluated, so a mutant there is equivalent."""
    spans = []
    for node in ast.walk(ast.parse(path.read_text())):
        notes = []
        if isinstance(node, ast.arg):
            notes.append(node.annotation)
        elif isinstance(node, (ast.FunctionDef, ast.AsyncFunctionDef)):
            notes.append(node.returns)
        elif isinstance(node, ast.AnnAssign):
            notes.append(node.annotation)
        for a in notes:
            if a is not None:
                spans.append(((a.lineno, a.col_offset), (a.end_lineno or a.lineno, a.end_col_offset or 0)))
    return spans


def _mutated_line(spec: object) -> tuple[str, str]:
    """(original line, mutated line) of a mutant, stripped: how it is named."""
    from cosmic_ray.mutating import mutate_code
    from cosmic_ray.plugins import get_operator

    source = Path(spec.module_path).read_text()
    op = get_operator(spec.operator_name)(**(spec.operator_args or {}))
    mutated = mutate_code(source, op, spec.occurrence) or ""
    row = spec.start_pos[0] - 1
    old, new = source.splitlines(), mutated.splitlines()
    return old[row].strip(), (new[row].strip() if row < len(new) else "")


def _key(path: str, old: str, new: str) -> str:
    return f"{path}  `{old}`  ->  `{new}`"


def load_equivalents(path: Path = EQUIVALENTS) -> dict[str, str]:
    """key -> reason, from lines ``FILE  `ORIGINAL`  ->  `MUTATED`  : REASON``."""
    out = {}
    pattern = re.compile(r"^(\S+)\s+`(.*)`\s+->\s+`(.*)`\s+:\s+(.+)$")
    for n, line in enumerate(path.read_text().splitlines(), 1):
        if not line.strip() or line.startswith("#"):
            continue
        m = pattern.match(line)
        if m is None:
            raise ValueError(f"{path}:{n}: expected FILE  `ORIGINAL`  ->  `MUTATED`  : REASON, got {line!r}")
        out[_key(m[1], m[2], m[3])] = m[4]
    return out


def _session(mod: Module, fresh: bool) -> Path:
    """The module's cosmic-ray session, created (or re-created when the file changed)."""
    from cosmic_ray.commands.init import init
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import WorkerOutcome, WorkResult

    STATE.mkdir(exist_ok=True)
    db_path = STATE / f"{mod.name}.sqlite"
    stamp = STATE / f"{mod.name}.stamp"
    # Not the tests: adding a test never lets a killed mutant survive (after removing
    # one, run with --fresh); --survivors runs the survivors against the new ones.
    rules = repr((mod.scope, EXCLUDED_OPERATORS.pattern, "annotations skipped"))
    digest = hashlib.sha256((ROOT / mod.path).read_bytes() + rules.encode()).hexdigest()
    if not fresh and db_path.exists() and stamp.exists() and stamp.read_text() == digest:
        return db_path
    db_path.unlink(missing_ok=True)
    with use_db(str(db_path), WorkDB.Mode.create) as db:
        init([Path(mod.path)], db, {})
        lines = _scope_lines(ROOT / mod.path, mod.scope) if mod.scope else None
        notes = _annotation_spans(ROOT / mod.path)
        for item in db.pending_work_items:
            (spec,) = item.mutations
            why = None
            if EXCLUDED_OPERATORS.match(spec.operator_name):
                why = "operator left out"
            elif any(a <= tuple(spec.start_pos) < b for a, b in notes):
                why = "in a type annotation"
            elif lines is not None and spec.start_pos[0] not in lines:
                why = "out of scope"
            if why:
                db.set_result(item.job_id, WorkResult(output=why, worker_outcome=WorkerOutcome.SKIPPED))
    stamp.write_text(digest)
    return db_path


# -- running the tests in a forked child ----------------------------------------------


def _warm_up() -> None:
    """Import what every test run needs and none of our modules (those are mutated)."""
    import filterpy.kalman  # noqa: F401 - pulls scipy and matplotlib
    import msgpack  # noqa: F401
    import numpy  # noqa: F401
    import pytest  # noqa: F401
    import scipy.integrate  # noqa: F401
    import scipy.stats  # noqa: F401

    with contextlib.suppress(ImportError):  # test_fuzzy's oracle
        import simpful  # noqa: F401
    if any(m.startswith("formation_swarm") for m in sys.modules):
        raise RuntimeError("our modules must be imported by each child, from the mutated files")


def run_tests(tests: tuple[str, ...], timeout_s: float) -> tuple[str, float, str]:
    """("passed" | "failed" | "timeout", seconds, output tail) of pytest in a forked child."""
    with tempfile.TemporaryFile() as log:
        t0 = time.monotonic()
        pid = os.fork()
        if pid == 0:  # the child: fresh imports of our modules, from the (mutated) files
            code = 3
            try:
                os.setpgid(0, 0)
                os.dup2(log.fileno(), 1)
                os.dup2(log.fileno(), 2)
                # Our modules compile from source: a .pyc neither read (one written for
                # the original in the same second would pass its check) nor written.
                sys.pycache_prefix = tempfile.mkdtemp(prefix="mutate-pyc-")
                sys.dont_write_bytecode = True
                os.chdir(ROOT)
                os.environ["PYTEST_DISABLE_PLUGIN_AUTOLOAD"] = "1"  # no entry-point scan; the fast tests need none
                import pytest

                code = int(pytest.main([*PYTEST_ARGS, *tests]))
            finally:
                os._exit(code)
        pidfd = os.pidfd_open(pid)
        try:
            ready, _, _ = select.select([pidfd], [], [], timeout_s)
        except BaseException:  # Ctrl-C: the child goes too
            os.killpg(pid, signal.SIGKILL)
            os.waitpid(pid, 0)
            raise
        finally:
            os.close(pidfd)
        if not ready:
            os.killpg(pid, signal.SIGKILL)
        _, status = os.waitpid(pid, 0)
        elapsed = time.monotonic() - t0
        log.seek(0)
        tail = log.read()[-2000:].decode(errors="replace")
    if not ready:
        return "timeout", elapsed, tail
    code = os.waitstatus_to_exitcode(status)
    if code == 5:
        raise RuntimeError(f"pytest collected no test from {tests}")
    return ("passed" if code == 0 else "failed"), elapsed, tail


# -- the run -------------------------------------------------------------------------


def _forget_survivors(db_path: Path) -> None:
    """Run the surviving mutants again (after adding tests): a test added never
    lets a killed mutant survive, so only the survivors need another run."""
    import sqlite3

    with contextlib.closing(sqlite3.connect(db_path)) as con, con:
        con.execute("DELETE FROM work_results WHERE test_outcome = 'SURVIVED'")  # cosmic-ray stores enum names


def _stable_order(item: object) -> str:
    (spec,) = item.mutations
    return hashlib.sha256(f"{spec.operator_name} {spec.occurrence}".encode()).hexdigest()


def mutate_module(
    mod: Module, fresh: bool, survivors: bool = False, sample: int | None = None, out: object = sys.stdout
) -> None:
    from cosmic_ray.mutating import use_mutation
    from cosmic_ray.plugins import get_operator
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import TestOutcome, WorkerOutcome, WorkResult

    db_path = _session(mod, fresh)
    if survivors:
        _forget_survivors(db_path)
    with use_db(str(db_path), WorkDB.Mode.open) as db:
        pending = sorted(db.pending_work_items, key=_stable_order)
        if sample is not None:  # the same sample every time: the first N mutants in a fixed order
            skipped = {job for job, r in db.results if r.worker_outcome == WorkerOutcome.SKIPPED}
            chosen = sorted((i for i in db.work_items if i.job_id not in skipped), key=_stable_order)[:sample]
            ids = {i.job_id for i in chosen}
            pending = [i for i in pending if i.job_id in ids]
        if not pending:
            return
        verdict, base_s, tail = run_tests(mod.tests, timeout_s=300.0)
        if verdict != "passed":
            raise RuntimeError(f"{mod.path}: its tests fail without any mutant:\n{tail}")
        timeout_s = max(10.0, 5.0 * base_s)
        print(
            f"[mutate] {mod.path}: {len(pending)} mutants, tests take {base_s:.2f} s, limit {timeout_s:.0f} s each",
            file=out,
            flush=True,
        )
        t0 = time.monotonic()
        for i, item in enumerate(pending, 1):
            (spec,) = item.mutations
            op = get_operator(spec.operator_name)(**(spec.operator_args or {}))
            with contextlib.ExitStack() as stack:
                try:
                    _, mutated = stack.enter_context(use_mutation(Path(spec.module_path), op, spec.occurrence))
                except Exception as exc:  # noqa: BLE001 - cosmic-ray fails on some nodes; the file is untouched
                    db.set_result(item.job_id, WorkResult(output=repr(exc), worker_outcome=WorkerOutcome.EXCEPTION))
                    continue
                if mutated is None:
                    db.set_result(item.job_id, WorkResult(worker_outcome=WorkerOutcome.NO_TEST))
                    continue
                verdict, _, tail = run_tests(mod.tests, timeout_s)
            outcome = TestOutcome.SURVIVED if verdict == "passed" else TestOutcome.KILLED
            db.set_result(
                item.job_id,
                WorkResult(output=verdict + "\n" + tail, test_outcome=outcome, worker_outcome=WorkerOutcome.NORMAL),
            )
            if i % 50 == 0:
                el = time.monotonic() - t0
                print(f"[mutate] {mod.path}: {i}/{len(pending)} ({el:.0f} s)", file=out, flush=True)


@dataclass
class Tally:
    killed: int = 0
    timeouts: int = 0
    survived: int = 0
    equivalent: int = 0
    skipped: int = 0
    pending: int = 0

    @property
    def total(self) -> int:
        return self.killed + self.survived


def tally(mod: Module, equivalents: dict[str, str], used: set[str]) -> tuple[Tally, list[str]]:
    from cosmic_ray.work_db import WorkDB, use_db
    from cosmic_ray.work_item import TestOutcome, WorkerOutcome

    t = Tally()
    survivors = []
    db_path = STATE / f"{mod.name}.sqlite"
    if not db_path.exists():
        return t, survivors
    with use_db(str(db_path), WorkDB.Mode.open) as db:
        results = dict(db.results)
        for item in db.work_items:
            res = results.get(item.job_id)
            if res is None:
                t.pending += 1
            elif res.worker_outcome != WorkerOutcome.NORMAL:  # left out by rule, or cosmic-ray could not apply it
                t.skipped += 1
            elif res.test_outcome == TestOutcome.SURVIVED:
                (spec,) = item.mutations
                key = _key(mod.path, *_mutated_line(spec))
                if key in equivalents:
                    t.equivalent += 1
                    used.add(key)
                else:
                    t.survived += 1
                    survivors.append(f"{key}  : line {spec.start_pos[0]}, {spec.operator_name}")
            else:
                t.killed += 1
                t.timeouts += (res.output or "").startswith("timeout")
    return t, survivors


def report(mods: tuple[Module, ...], list_survivors: bool, out: object = sys.stdout) -> float:
    equivalents = load_equivalents()
    used: set[str] = set()
    grand = Tally()
    all_survivors = []
    print(f"{'module':24} {'killed':>7} {'(timeout)':>9} {'survived':>8} {'equiv.':>6} {'score':>7}", file=out)
    for mod in mods:
        t, survivors = tally(mod, equivalents, used)
        all_survivors += survivors
        for f in ("killed", "timeouts", "survived", "equivalent", "skipped", "pending"):
            setattr(grand, f, getattr(grand, f) + getattr(t, f))
        score = f"{100 * t.killed / t.total:6.1f}%" if t.total else "     -"
        extra = f"  ({t.pending} not run)" if t.pending else ""
        print(f"{mod.path:24} {t.killed:7} {t.timeouts:9} {t.survived:8} {t.equivalent:6} {score:>7}{extra}", file=out)
    score = grand.killed / grand.total if grand.total else float("nan")
    print(
        f"{'all':24} {grand.killed:7} {grand.timeouts:9} {grand.survived:8} {grand.equivalent:6} {100 * score:6.1f}%",
        file=out,
    )
    print(
        f"mutation score {grand.killed}/{grand.total} = {100 * score:.1f}% killed "
        f"({grand.equivalent} equivalent mutants excluded, {grand.skipped} left out by rule"
        + (f", {grand.pending} not run" if grand.pending else "")
        + ")",
        file=out,
    )
    if list_survivors and all_survivors:
        print("\nsurvivors (add to tools/equivalent_mutants.txt with a reason only if no test can tell):", file=out)
        print("\n".join(all_survivors), file=out)
    stale = [k for k in equivalents if k not in used and any(k.startswith(m.path + " ") for m in mods)]
    if stale and not grand.pending:
        print("\nequivalents listed but no longer surviving (remove them):\n" + "\n".join(stale), file=out)
    return score


def main(argv: list[str] | None = None) -> int:
    ap = argparse.ArgumentParser(description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter)
    ap.add_argument("modules", nargs="*", help="repository paths of modules to mutate (default: all)")
    ap.add_argument("--fresh", action="store_true", help="forget earlier results and run every mutant again")
    ap.add_argument("--survivors", action="store_true", help="run the surviving mutants again (after adding tests)")
    ap.add_argument("--sample", type=int, metavar="N", help="run at most N mutants per module (a fixed sample)")
    ap.add_argument("--report-only", action="store_true", help="print the score of the sessions as they are")
    ap.add_argument("--list-survivors", action="store_true", help="print the surviving mutants")
    args = ap.parse_args(argv)
    known = {m.path: m for m in MODULES}
    unknown = [p for p in args.modules if p not in known]
    if unknown:
        ap.error(f"not a module of the mutation run: {unknown}; known: {sorted(known)}")
    mods = tuple(known[p] for p in args.modules) if args.modules else MODULES

    def interrupt(_sig: int, _frame: object) -> None:
        raise KeyboardInterrupt

    for sig in (signal.SIGINT, signal.SIGTERM):  # also when started in the background (SIGINT ignored)
        signal.signal(sig, interrupt)
    if not args.report_only:
        _warm_up()
        t0 = time.monotonic()
        originals = {m.path: (ROOT / m.path).read_bytes() for m in mods}
        try:
            for mod in mods:
                mutate_module(mod, args.fresh, args.survivors, args.sample)
        except KeyboardInterrupt:
            print("[mutate] interrupted: finished mutants are kept; run again to go on", file=sys.stderr)
            return 130
        finally:
            for path, content in originals.items():  # cosmic-ray restores each file; make sure of it
                if (ROOT / path).read_bytes() != content:
                    (ROOT / path).write_bytes(content)
                    print(f"[mutate] restored {path}", file=sys.stderr)
        print(f"[mutate] {time.monotonic() - t0:.0f} s", flush=True)
    score = report(mods, args.list_survivors)
    return 0 if score >= 0.9 else 1


if __name__ == "__main__":
    sys.exit(main())
