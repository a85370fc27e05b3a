"""The laws a run flew, in the phrase the console's header, report.md, the
figures' titles and `swarm compare`'s legend give (launch.words.describe_laws)."""

from __future__ import annotations

from formation_swarm.launch.words import describe_laws, robot_ids
from formation_swarm.report.figures import Context

PAPER = "fuzzy (V_N dynamic)"
MINE = "mypkg.mod:Ctl"


def test_one_law_for_all_or_each_law_with_its_followers() -> None:
    one = {"leader": "path", "followers": {"2": PAPER, "3": PAPER}}
    several = {"leader": "path", "followers": {"2": PAPER, "3": MINE, "4": MINE, "5": "lpsi", "6": MINE, "7": PAPER}}
    assert [describe_laws(one), describe_laws(several)] == [
        "leader path, law fuzzy (V_N dynamic)",
        "leader path, laws R2,R7 fuzzy (V_N dynamic); R3,R4,R6 mypkg.mod:Ctl; R5 lpsi",
    ]
    assert describe_laws({"leader": "path", "followers": {}}) == "leader path"  # a run without followers


def test_robot_ids_in_short() -> None:
    assert [robot_ids([2]), robot_ids([3, 2]), robot_ids([7, 2, 3, 4, 9, 10])] == ["R2", "R2,R3", "R2-R4,R7,R9,R10"]


def test_every_figures_title_names_the_laws_and_the_vn_figure_which_sent_none() -> None:
    from formation_swarm.report.figures.timelines import _no_vn

    laws = {"leader": "path", "followers": {"2": MINE, "3": "lpsi"}}
    ctx = Context(scenario="s", seed=1, robots=[1, 2, 3], followers=[2, 3], laws=laws)
    assert ctx.title("vn", "V_N").splitlines()[1] == describe_laws(laws)
    assert ctx.laws_of_followers() == [MINE, "lpsi"]
    assert MINE in _no_vn(ctx)
    assert "lpsi" in _no_vn(ctx)
    unknown = Context(scenario="s", seed=1, robots=[1, 2], followers=[2])
    assert len(unknown.title("vn", "V_N").splitlines()) == 1  # a run whose laws are not known: none said
