"""docs/protocol.md and its pages stay true: their tables are checked against the code.

A change to the wire (a key, a field, its order, type or range, a limit, a
rejection reason, a start-up or end-of-run constant, a scenario default an
agent reads) without the same change to the pages fails here. The type
column of each message table is not only compared as text: each type is
turned into values it accepts and values it rejects, with the reason the
pages give, and the decoder must agree.

docs/protocol.md is the index of the pages under docs/protocol/: it links
every page and each of its sections, and every link of these pages, and every
link of the other docs into them, resolves to a file and a heading.
"""

from __future__ import annotations

import importlib
import inspect
import json
import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import Any

import msgpack
import pytest

from formation_swarm.protocol import acl, codec, keys, messages, session, trust
from formation_swarm.protocol.codec import DecodeError, Message
from formation_swarm.protocol.keys import Keys
from formation_swarm.runtime import process
from formation_swarm.spec import keys as scenario_keys
from tests.helpers import ROOT

INDEX = ROOT / "docs" / "protocol.md"
PAGES = {path: path.read_text() for path in [INDEX, *sorted((ROOT / "docs" / "protocol").glob("*.md"))]}
TEXT = "\n".join(PAGES.values())
RUN, ID = "R.1", 7
MESSAGE_TYPES = {cls.__name__: cls for cls in Message.__subclasses__()}


def section(title: str) -> str:
    """The text under the heading ``title`` (any level) of the one page that has
    it, up to the next heading of the same or a higher level."""
    found = []
    for path, text in PAGES.items():
        for m in re.finditer(rf"^(#+) {re.escape(title)}\s*$", text, re.MULTILINE):
            level = len(m.group(1))
            end = re.compile(rf"^#{{1,{level}}} ", re.MULTILINE).search(text, m.end())
            found.append((path, text[m.end() : end.start() if end else len(text)]))
    if len(found) != 1:
        where = [str(p.relative_to(ROOT)) for p, _ in found]
        raise AssertionError(f"the protocol pages have {len(found)} headings {title!r}, not one: {where}")
    return found[0][1]


def table(text: str) -> list[list[str]]:
    """The rows of the first Markdown table in ``text``, header and rule left out;
    cells stripped of spaces and of one pair of backticks."""
    lines = [ln.strip() for ln in text.splitlines()]
    start = next(i for i, ln in enumerate(lines) if ln.startswith("|"))
    rows = []
    for ln in lines[start + 2 :]:
        if not ln.startswith("|"):
            break
        cells = [c.strip().replace("\\|", "|") for c in re.split(r"(?<!\\)\|", ln)[1:-1]]
        rows.append([c[1:-1] if c.startswith("`") and c.endswith("`") and c.count("`") == 2 else c for c in cells])
    return rows


def number(text: str) -> int | float:
    text = text.strip()
    if m := re.fullmatch(r"(\d+)\^(\d+)", text):
        return int(m.group(1)) ** int(m.group(2))
    return int(text) if re.fullmatch(r"-?\d+", text) else float(text)


def placed(key: str) -> str:
    return key.replace("<run>", RUN).replace("<id>", str(ID)).replace("<role>", "agent")


# -- keys ------------------------------------------------------------------------------


def test_every_key_in_the_table_is_built_by_the_keys_module_and_back() -> None:
    k = Keys(RUN)
    built = {
        "obs": k.obs(ID),
        "cmd": k.cmd(ID),
        "codes": k.codes,
        "telemetry": k.telemetry(ID),
        "truth": k.truth,
        "status": k.status,
        "faults": k.faults,
        "sightings": k.sightings,
        "alive": (k.alive("world", 0), k.alive("agent", ID), k.alive("logger", 0), k.alive("launcher", 0)),
        "world_wake": k.world_wake,
    }
    patterns = {
        "inbox": k.inbox(ID),
        "all_cmd": k.all_cmd,
        "all_telemetry": k.all_telemetry,
        "world_all": k.world_all,
        "alive_any": k.alive_any,
        "alive_all": k.alive_all("agent"),
        "everything": k.everything,
    }
    # A new member of Keys must be added here, and so to the document.
    helpers = {"robot", "parse_robot", "parse_alive", "run_id", "prefix"}
    members = {n for n in dir(Keys) if not n.startswith("_")} | {"run_id", "prefix"}
    assert members == set(built) | set(patterns) | helpers
    flat = {v for x in built.values() for v in (x if isinstance(x, tuple) else (x,))}
    assert {placed(row[0]) for row in table(section("Key expressions"))} == flat
    assert {placed(row[0]) for row in table(section("Key expressions").split("Our processes subscribe")[1])} == set(
        patterns.values()
    )


def test_run_and_robot_id_rules() -> None:
    assert "1 to 64" in section("Key expressions")
    assert "letters, digits, `_`, `.` and `-`" in section("Key expressions")
    keys.check_run_id("a" * 64)
    for bad in ("a" * 65, "_a", "a/b", ""):
        with pytest.raises(ValueError, match="run id"):
            keys.check_run_id(bad)
    assert "1..10000" in section("Key expressions")
    assert keys.MAX_ROBOT_ID == 10000


# -- envelope, limits ------------------------------------------------------------------


def test_envelope_and_limits() -> None:
    rows = table(section("Envelope"))
    assert [r[1] for r in rows] == ["tag", "version", *Message._names()]
    assert [int(r[0]) for r in rows] == list(range(5))
    limits = {r[0]: number(r[1]) for r in table(section("Limits"))}
    ours = {
        name: getattr(codec, name)
        for name in (
            "VERSION",
            "MAX_PAYLOAD_BYTES",
            "MAX_ITEMS",
            "WORLD_ID",
            "MAX_TICK",
            "BATCH_TAG",
            "MAX_BATCH_ITEMS",
        )
    }
    ours["MAX_ROBOT_ID"] = keys.MAX_ROBOT_ID
    assert limits == ours
    assert f"{8 * codec.MAX_ITEMS}" in section("Limits")
    assert f"[{codec.BATCH_TAG}, {codec.VERSION}, []]" in section("Batches")


# -- message tables ------------------------------------------------------------------


@dataclass
class Spec:
    """Values a documented type accepts, and values it rejects with the reason."""

    good: list[Any]
    bad: list[tuple[Any, str]] = field(default_factory=list)


def split_top(text: str) -> list[str]:
    """``a, [b, c], d`` -> ["a", "[b, c]", "d"]."""
    out, depth, cur = [], 0, ""
    for ch in text:
        if ch == "," and depth == 0:
            out.append(cur.strip())
            cur = ""
            continue
        depth += {"[": 1, "]": -1}.get(ch, 0)
        cur += ch
    return [*out, cur.strip()] if cur.strip() else out


def spec(t: str) -> Spec:
    t = t.strip()
    if t.endswith(" or nil"):
        inner = spec(t[: -len(" or nil")])
        return Spec([*inner.good, None], [(v, r) for v, r in inner.bad if v is not None])
    if t == "float":
        return Spec(
            [1.5, -2, 0.0],
            [
                (math.nan, "not finite"),
                (math.inf, "not finite"),
                ("1", "wrong type"),
                (True, "wrong type"),
                (None, "wrong type"),
            ],
        )
    if m := re.fullmatch(r"int (\S+)\.\.(\S+)", t):
        lo, hi = number(m.group(1)), number(m.group(2))
        return Spec(
            [lo, hi],
            [
                (lo - 1, "out of range"),
                (hi + 1, "out of range"),
                (float(lo), "wrong type"),
                (True, "wrong type"),
                (None, "wrong type"),
            ],
        )
    if t == "process":
        return Spec(
            ["logger", "agent-1", "agent-10000"],
            [
                ("agent-0", "out of range"),
                ("agent-10001", "out of range"),
                ("agent-01", "out of range"),
                ("world", "out of range"),
                (3, "wrong type"),
                (None, "wrong type"),
            ],
        )
    if t == "name":  # Telemetry's extras: messages.EXTRA_NAME
        return Spec(
            ["speed_mps", "a" * 32, "Kp2"],
            [
                ("", "out of range"),
                ("a" * 33, "out of range"),
                ("2a", "out of range"),
                ("a-b", "out of range"),
                (3, "wrong type"),
                (None, "wrong type"),
            ],
        )
    if t == "bool":
        return Spec([True, False], [(1, "wrong type"), (0, "wrong type"), (None, "wrong type")])
    if m := re.fullmatch(r"str (.*)", t):
        values = re.findall(r'"([^"]*)"', m.group(1))
        assert m.group(1) == " | ".join(f'"{v}"' for v in values), t
        return Spec(values, [("other", "out of range"), (1, "out of range"), (None, "out of range")])
    if m := re.fullmatch(r"array of \[(.*)\] \(max (\d+)\)", t):
        items = [spec(x) for x in split_top(m.group(1))]
        rec = [s.good[0] for s in items]
        too_many = [rec] * (int(m.group(2)) + 1)
        bad: list[tuple[Any, str]] = [(None, "wrong type"), (too_many, "too many items")]
        bad += [([rec[:-1]], "wrong shape"), ([[*rec, rec[-1]]], "wrong shape")]
        for i, s in enumerate(items):
            bad += [([[*rec[:i], v, *rec[i + 1 :]]], reason) for v, reason in s.bad]
        return Spec([[], [rec], [rec, [s.good[-1] for s in items]]], bad)
    if m := re.fullmatch(r"\[(.*)\]", t):
        items = [spec(x) for x in split_top(m.group(1))]
        arr = [s.good[0] for s in items]
        bad = [(arr[:-1], "wrong shape"), ([*arr, arr[-1]], "wrong shape"), (None, "wrong shape")]
        for i, s in enumerate(items):
            bad += [([*arr[:i], v, *arr[i + 1 :]], reason) for v, reason in s.bad if v is not None]
        return Spec([arr, [s.good[-1] for s in items]], bad)
    raise AssertionError(f"docs/protocol/messages.md: unknown type {t!r}")


def message_rows(name: str) -> tuple[int, list[list[str]]]:
    m = re.search(rf"^### {name} \(tag (\d+)\)$", TEXT, re.MULTILINE)
    assert m is not None, f"the protocol pages have no section '### {name} (tag N)'"
    return int(m.group(1)), table(section(f"{name} (tag {m.group(1)})"))


def test_every_message_type_has_a_section_and_no_other() -> None:
    documented = set(re.findall(r"^### (\w+) \(tag \d+\)$", TEXT, re.MULTILINE))
    assert (
        documented
        == set(MESSAGE_TYPES)
        == {"Observation", "Command", "FormationCode", "Telemetry", "Truth", "Status", "FaultCall"}
    )
    assert all(getattr(messages, n) is cls for n, cls in MESSAGE_TYPES.items())


@pytest.mark.parametrize("name", sorted(MESSAGE_TYPES))
def test_field_names_order_tag_and_version(name: str) -> None:
    cls = MESSAGE_TYPES[name]
    tag, rows = message_rows(name)
    assert tag == cls.TAG
    assert [int(r[0]) for r in rows] == list(range(len(rows)))
    assert [r[1] for r in rows] == ["tag", "version", *cls._names()]
    assert number(rows[0][2]) == cls.TAG
    assert number(rows[1][2]) == codec.VERSION


@pytest.mark.parametrize("name", sorted(MESSAGE_TYPES))
def test_the_decoder_accepts_and_rejects_what_the_types_say(name: str) -> None:
    cls = MESSAGE_TYPES[name]
    _, rows = message_rows(name)
    specs = [spec(r[2]) for r in rows[2:]]
    base = [cls.TAG, codec.VERSION, *[s.good[0] for s in specs]]

    def decode(i: int, value: Any) -> Message:
        raw = list(base)
        raw[2 + i] = value
        return cls.from_bytes(msgpack.packb(raw, use_bin_type=True))

    cls.from_bytes(msgpack.packb(base, use_bin_type=True))
    for i, (row, s) in enumerate(zip(rows[2:], specs, strict=True)):
        for value in s.good:
            decode(i, value)
        for value, reason in s.bad:
            with pytest.raises(DecodeError) as info:
                decode(i, value)
            assert info.value.reason == reason, (row[1], value)


def test_enumerated_strings_are_the_code_s() -> None:
    """A value added to an enumeration is not caught by trying values: compare them."""
    types = [row[2] for name in MESSAGE_TYPES for row in message_rows(name)[1]]
    documented = sorted(tuple(re.findall(r'"([^"]*)"', t)) for t in types if t.startswith("str "))
    checked = re.findall(r"one_of\(([^)]*)\)", inspect.getsource(messages))
    ours = sorted(tuple(re.findall(r'"([^"]*)"', args)) for args in checked)
    assert documented == ours != []


# -- rejection reasons -------------------------------------------------------------


WORLD_GATE = "formation_swarm.world.commands"


def test_the_rejection_reasons_are_the_code_s() -> None:
    documented = {r[0] for r in table(section("What a receiver rejects"))}
    src = inspect.getsource(codec)
    ours = set(re.findall(r'DecodeError\("([^"]+)"', src)) | set(re.findall(r'by_reason\["([^"]+)"\]', src))
    agent = ("nodes.agent.wire", "agents.inbox", "agents.role_base", "agents.follower_role")
    for mod in (*agent, "nodes.world.main", "nodes.logger.main"):
        src = inspect.getsource(importlib.import_module(f"formation_swarm.{mod}"))
        ours |= set(re.findall(r'\.reject\("([^"]+)"\)', src))
    # The world judges a command in world.commands (its process, nodes.world.main*, rejects nothing itself).
    ours |= set(re.findall(r'\.reject\("([^"]+)"\)', inspect.getsource(importlib.import_module(WORLD_GATE))))
    ours |= set(
        re.findall(r'return "([^"]+)"', inspect.getsource(importlib.import_module("formation_swarm.agents.inbox")))
    )
    assert documented == ours


# -- timing constants and scenario values ------------------------------------------


def test_timing_constants() -> None:
    for name, value, _ in table(section("Timing constants")):
        module, attr = name.rsplit(".", 1)
        assert getattr(importlib.import_module(f"formation_swarm.{module}"), attr) == number(value.split()[0]), name


def test_scenario_defaults() -> None:
    for key, default, _ in table(section("Scenario values an agent reads")):
        table_name, name = key.split(".")
        spec = scenario_keys.SECTIONS[table_name][0][name]
        ours = spec.default
        if default == "required":
            assert spec.required, key
        elif default.startswith('"'):
            assert ours == default.strip('"'), key
        else:
            assert ours == number(default), key


# -- the client's configuration and the logins' grants -------------------------------


def test_the_clients_configuration_is_ours() -> None:
    """Each setting of the table as our clients' configuration has it (the
    endpoint and the login as the document's examples)."""
    rows = {r[0]: json.loads(r[1]) for r in table(section("The client's configuration"))}
    assert set(rows) == {
        "mode",
        "connect/endpoints",
        "connect/timeout_ms",
        "connect/retry",
        "scouting/multicast/enabled",
        "transport/auth/usrpwd",
    }
    login = rows["transport/auth/usrpwd"]
    settings = trust.client_settings(trust.Credential(login["user"], "p" * 16))
    conf = session.make_config(
        "client",
        rows["connect/endpoints"],
        connect_timeout_s=process.DEFAULT_PEERS_TIMEOUT_S + process.CONNECT_MARGIN_S,
        settings=settings,
    )
    for path, value in rows.items():
        ours = json.loads(conf.get_json(path))
        if path == "transport/auth/usrpwd":
            assert set(ours) >= set(value), ours
            assert ours["user"] == value["user"]
        else:
            assert ours == value, path


def _grant_keys(cell: str, run: str, ids: tuple[int, ...]) -> set[str]:
    """The keys a cell of the grants table names, placed: ``<id>`` each of
    ``ids``, ``<name>`` the host "b", under the run's prefix but the hosts' keys."""
    out = set()
    for key in re.findall(r"`([^`]+)`", cell) or ([cell] if cell else []):  # a lone key lost its backticks
        for rid in ids if "<id>" in key else (0,):
            k = key.replace("<id>", str(rid)).replace("<name>", "b")
            out.add(k if k.startswith("swarmhost/") else f"swarm/{run}/{k}")
    return out


def test_the_logins_grants_are_the_code_s() -> None:
    robots, leader, follower = (1, ID), 1, ID
    ours = acl.grants(RUN, robots, leader, hosts=("b",), observer=True)
    fields = ("publish", "subscribe", "receive", "tokens", "watch", "serve", "ask")
    seen = set()
    for row in table(section("What each login may do")):
        login = row[0].split(" (")[0].strip("`")  # `agent-<id>` (the leader); the table drops a lone pair
        if login == "agent-<id>":
            rid = leader if "leader" in row[0] else follower
            ids: tuple[int, ...] = (rid,)
            user = acl.agent_user(rid)
        else:
            ids, user = robots, login.replace("<name>", "b")
        seen.add(user)
        for name, cell in zip(fields, row[1:], strict=True):
            assert _grant_keys(cell, RUN, ids) == set(getattr(ours[user], name)), (user, name)
    assert seen == set(ours)


# -- the index and the links ---------------------------------------------------------

LINK = re.compile(r"\[[^\]]*\]\(([^)\s]+)\)")


def headings(text: str) -> list[tuple[int, str]]:
    """The (level, title) of every heading, fenced code left out."""
    text = re.sub(r"^```.*?^```", "", text, flags=re.MULTILINE | re.DOTALL)
    return [(len(m.group(1)), m.group(2).strip()) for m in re.finditer(r"^(#{1,6}) (.+)$", text, re.MULTILINE)]


def slug(title: str) -> str:
    """The anchor GitHub gives a heading: lower case, punctuation dropped, spaces to hyphens."""
    return re.sub(r"[^\w\- ]", "", title.lower()).replace(" ", "-")


def anchors(text: str) -> set[str]:
    """The anchors of the headings of ``text``; a repeated one gets ``-1``, ``-2``."""
    out, count = set(), dict[str, int]()
    for _, title in headings(text):
        n = count.get(slug(title), 0)
        count[slug(title)] = n + 1
        out.add(slug(title) if n == 0 else f"{slug(title)}-{n}")
    return out


def links(path: Path) -> list[tuple[Path, str]]:
    """The links of a Markdown file to files of the repository: (file, anchor);
    a link within the page is to the page itself."""
    out = []
    for target in LINK.findall(path.read_text()):
        if re.match(r"[a-z]+:", target):  # https:, mailto:
            continue
        file, _, anchor = target.partition("#")
        out.append(((path.parent / file if file else path).resolve(), anchor))
    return out


def unresolved(path: Path, into: Path | None = None) -> list[str]:
    """The links of ``path`` (to ``into`` and the files under it, if given) whose
    file is missing or whose anchor is no heading of it."""
    bad = []
    for file, anchor in links(path):
        if into is not None and into not in (file, *file.parents):
            continue
        where = f"{path.relative_to(ROOT)} -> {file.relative_to(ROOT) if file.is_relative_to(ROOT) else file}"
        if not file.exists():
            bad.append(f"{where}: no such file")
        elif anchor and file.suffix == ".md" and anchor not in anchors(file.read_text()):
            bad.append(f"{where}#{anchor}: no such heading")
    return bad


def test_anchors_are_github_s() -> None:
    text = "# A page\n## The client's configuration\n### Observation (tag 1)\n## Notes\n## Notes\n"
    assert anchors(text) == {"a-page", "the-clients-configuration", "observation-tag-1", "notes", "notes-1"}
    assert anchors("```sh\n# not a heading\n```\n## Real-time scheduling\n") == {"real-time-scheduling"}


def test_the_index_links_every_page_and_each_of_its_sections() -> None:
    linked = set(links(INDEX))
    pages = [p for p in PAGES if p != INDEX]
    assert len(pages) >= 5
    for page in pages:
        assert (page.resolve(), "") in linked, f"docs/protocol.md does not link {page.name}"
        titles = headings(PAGES[page])
        assert [level for level, _ in titles].count(1) == 1 == titles[0][0], f"{page.name}: one title, first"
        for title in (title for level, title in titles if level == 2):
            assert (page.resolve(), slug(title)) in linked, f"docs/protocol.md does not link {page.name}#{slug(title)}"


def test_every_link_of_the_protocol_pages_resolves() -> None:
    assert all(links(p) for p in PAGES), "a page without a link: the check would prove nothing"
    assert [bad for page in PAGES for bad in unresolved(page)] == []


def test_every_link_into_the_protocol_pages_resolves() -> None:
    """Other docs link into the pages by file and heading: those files and headings exist."""
    docs = [ROOT / "README.md", ROOT / "deploy" / "README.md", *sorted((ROOT / "docs").glob("*.md"))]
    docs = [d for d in [*docs, *sorted((ROOT / "examples").rglob("*.md"))] if d not in PAGES]
    index, folder = INDEX.resolve(), (ROOT / "docs" / "protocol").resolve()
    into = [file for doc in docs for file, _ in links(doc) if file == index or folder in file.parents]
    assert into, "no doc links into the protocol pages: the check would prove nothing"
    assert [bad for doc in docs for target in (index, folder) for bad in unresolved(doc, target)] == []
