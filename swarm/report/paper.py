"""Which of the paper's figures a run reproduces: a shipped scenario of the
paper as shipped (any seed) reproduces its figures; a changed one says what
was changed."""

from __future__ import annotations

import tomllib
from collections.abc import Mapping
from pathlib import Path
from typing import Any

# The paper's figures each shipped scenario reproduces, by figure (scenarios/*.toml).
PAPER = {
    "fig6_turn_vn_1_5": {"trajectories": "Fig. 6a", "formation_error": "Fig. 6b"},
    "fig6_turn_vn_2": {"trajectories": "Fig. 6c", "formation_error": "Fig. 6d"},
    "fig7_turn_vn_dynamic": {"trajectories": "Fig. 7a", "formation_error": "Fig. 7b", "vn": "Fig. 8"},
    "fig9_ekf_noise": {"targets": "Fig. 9-10"},
    "fig11_obstacles": {"trajectories": "Fig. 11"},
}


def paper_figures(scenario_toml: Path) -> dict[str, str]:
    """The paper's figures this run reproduces, by figure stem: those of the
    shipped scenario it is, with any seed; none if it was changed (a --set,
    a fault) or is not shipped."""
    from formation_swarm.spec.files import shipped

    try:
        raw = tomllib.loads(scenario_toml.read_text())
    except (OSError, ValueError):
        return {}
    for stem, path in shipped().items():
        if stem in PAPER and _without_seed(tomllib.loads(path.read_text())) == _without_seed(raw):
            return dict(PAPER[stem])
    return {}


def paper_changed(scenario_toml: Path) -> tuple[str, list[str]] | None:
    """For a run of a paper's scenario that was changed, which one and the
    keys that were, sorted: e.g. ("fig11_obstacles", ["[[faults]]",
    "run.robots"]) (None: not one)."""
    from formation_swarm.spec.files import shipped

    try:
        raw = _without_seed(tomllib.loads(scenario_toml.read_text()))
    except (OSError, ValueError):
        return None
    for stem, path in shipped().items():
        orig = _without_seed(tomllib.loads(path.read_text()))
        if stem in PAPER and (orig.get("run") or {}).get("name") == (raw.get("run") or {}).get("name"):
            was, now = _flat(orig), _flat(raw)
            changed = sorted(was.keys() ^ now.keys() | {k for k, v in was.items() if k in now and now[k] != v})
            return (stem, changed) if changed else None
    return None


def paper_changes(scenario_toml: Path) -> str | None:
    """``paper_changed`` in words: e.g. "fig11_obstacles with [[faults]],
    run.robots changed" (None: not one)."""
    if (found := paper_changed(scenario_toml)) is None:
        return None
    stem, changed = found
    shown = ", ".join(changed[:6]) + (f" and {len(changed) - 6} more" if len(changed) > 6 else "")
    return f"{stem} with {shown} changed"


def _flat(raw: Mapping[str, Any], prefix: str = "") -> dict[str, Any]:
    """Dotted keys down to the tables' values; a list of tables ([[faults]]) is one key."""
    out: dict[str, Any] = {}
    for k, v in raw.items():
        if isinstance(v, Mapping):
            out |= _flat(v, f"{prefix}{k}.")
        else:
            out[f"[[{prefix}{k}]]" if isinstance(v, list) and v and isinstance(v[0], Mapping) else f"{prefix}{k}"] = v
    return out


def _without_seed(raw: Mapping[str, Any]) -> dict[str, Any]:
    run = {k: v for k, v in (raw.get("run") or {}).items() if k != "seed"}
    return {**raw, "run": run}
