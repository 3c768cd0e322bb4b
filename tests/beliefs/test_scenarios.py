"""Belief rules on both backends: the shipped scenarios, false beliefs, second order, config."""

from __future__ import annotations

from importlib import resources

import pytest
import sqlalchemy as sa

import toaster
import toaster.queries as q
from toaster.beliefs import api, scenario
from toaster.db import migrate
from toaster.db.engine import make_engine
from toaster.db.invariants import violations
from toaster.errors import FileFormatError, InvalidInputError

EXAMPLES = sorted(
    p.name
    for p in (resources.files("toaster") / "examples").iterdir()
    if p.name.startswith("beliefs_")
)


@pytest.mark.slow
@pytest.mark.parametrize("name", EXAMPLES)
def test_example_scenarios_meet_their_expectations(db: toaster.Database, name: str) -> None:
    sc = scenario.replay(db, resources.files("toaster") / "examples" / name)
    assert sc.expect, "every shipped scenario states what it demonstrates"
    assert scenario.check(db, sc) == []
    with db.transaction() as conn:  # every holder's timeline keeps the temporal invariants
        assert violations(conn) == []


@pytest.mark.slow
def test_sally_anne_false_belief_report_and_history(db: toaster.Database) -> None:
    scenario.replay(db, resources.files("toaster") / "examples" / "beliefs_sally_anne.yaml")
    t4 = 4_000_000_000
    diffs = api.false_beliefs(db, "SALLY", at=t4)
    assert {(d.target_id, d.value_a, d.value_b) for d in diffs if d.subject_id == "MARBLE"} == {
        ("BASKET", "true", None),
        ("BOX", None, "true"),
    }
    # Sally's false belief is an interval of her own: it ends when she sees the box again.
    basket = [
        r for r in api.belief_history(db, "MARBLE", "IsIn", "BASKET") if r.agent_id == "SALLY"
    ]
    assert [(r.valid_from_ns, r.valid_to_ns) for r in basket] == [(2_000_000_000, 5_000_000_000)]
    ended = q.events(db, "SALLY", kind="ended", subject="MARBLE")
    assert [(e.stamp_ns, e.target_id) for e in ended] == [(5_000_000_000, "BASKET")]
    # Anne never stopped believing the truth: no difference with the robot at the end.
    assert [d for d in api.false_beliefs(db, "ANNE") if d.subject_id == "MARBLE"] == []


@pytest.mark.slow
def test_targetless_facts_and_confidence_product(db: toaster.Database) -> None:
    st = db.store()
    st.add_entity("R", "robot", is_self=True, t_ns=0)
    st.add_entity("H", "human", t_ns=0)
    base = [
        toaster.Fact("H", "IsInRoom", "LAB", confidence=0.5),
        toaster.Fact("BALL", "IsInRoom", "LAB"),
    ]
    st.sync_snapshot("p", "R", 1, base)
    st.sync_snapshot("p", "R", 2, [*base, toaster.Fact("BALL", "IsMoving", confidence=0.8)])
    row = api.belief_value(db, "H", "BALL", "IsMoving")
    assert row is not None and row.target_id == ""
    assert row.confidence == pytest.approx(0.8 * 0.5)
    st.sync_snapshot("p", "R", 3, base)  # the ball stops: H sees it too
    assert api.belief_value(db, "H", "BALL", "IsMoving") is None
    assert api.belief_value(db, "H", "BALL", "IsMoving", at=2).valid_to_ns == 3


@pytest.mark.slow
def test_depth_one_creates_no_nested_holders(db: toaster.Database) -> None:
    api.configure(db, depth=1)
    scenario.replay(db, resources.files("toaster") / "examples" / "beliefs_cookie_box.yaml")
    assert not [h for h in api.holders(db) if ">" in h]
    with pytest.raises(InvalidInputError, match="depth"):
        api.beliefs(db, "BOB", about="ROBOT")


@pytest.mark.slow
def test_rules_can_be_disabled(db: toaster.Database) -> None:
    api.configure(db, enabled=False)
    scenario.replay(db, resources.files("toaster") / "examples" / "beliefs_sally_anne.yaml")
    assert api.beliefs(db, "SALLY") == []
    assert api.beliefs(db, "ROBOT", property="IsIn")


@pytest.mark.slow
@pytest.mark.parametrize(
    ("key", "value"),
    [
        ("depth", 0),
        ("depth", "2"),
        ("visibility", {"X": "y"}),
        ("nope", 1),
        ("copresence", "IsInRoom"),
    ],
)
def test_bad_settings_are_rejected_in_one_line(
    db: toaster.Database, key: str, value: object
) -> None:
    with pytest.raises(InvalidInputError) as info:
        api.configure(db, **{key: value})
    assert key in str(info.value) and "\n" not in str(info.value)


def test_bad_scenario_files_name_the_problem(tmp_path) -> None:
    bad = tmp_path / "bad.yaml"
    bad.write_text("steps:\n  - {rooms: {A: B}}\n")
    with pytest.raises(FileFormatError, match="step 1.*give t"):
        scenario.load(bad)
    bad.write_text("steps:\n  - {t: 1, facts: [[A]]}\n")
    with pytest.raises(FileFormatError, match=r"\[SUBJECT, PROPERTY, TARGET\]"):
        scenario.load(bad)
    with pytest.raises(FileFormatError, match="cannot read"):
        scenario.load(tmp_path / "missing.yaml")


@pytest.mark.slow
def test_two_store_processes_both_apply_the_rules(db_url: str) -> None:
    first, second = toaster.connect(db_url), toaster.connect(db_url)
    try:
        st = first.store()
        st.add_entity("R", "robot", is_self=True, t_ns=0)
        st.add_entity("H", "human", t_ns=0)
        st.sync_snapshot(
            "a",
            "R",
            1,
            [toaster.Fact("H", "IsInRoom", "LAB"), toaster.Fact("CUP", "IsInRoom", "LAB")],
        )
        second.store().sync_snapshot("b", "R", 2, [toaster.Fact("CUP", "IsHot")])
        assert api.belief_value(first, "H", "CUP", "IsHot") is not None
    finally:
        first.close()
        second.close()


@pytest.mark.slow
def test_beliefs_revision_downgrades_and_upgrades(db_url: str) -> None:
    db = toaster.connect(db_url)
    scenario.replay(db, resources.files("toaster") / "examples" / "beliefs_sally_anne.yaml")
    db.close()
    engine = make_engine(db_url)
    migrate.downgrade(engine, "0001")
    names = sa.inspect(engine).get_table_names()
    assert "belief_chain" not in names and "belief_rules" not in names
    with engine.connect() as conn:
        nested = conn.execute(sa.text("SELECT count(*) FROM agents WHERE id LIKE '%>%'"))
        assert nested.scalar_one() == 0
    migrate.upgrade(engine)
    engine.dispose()
    with toaster.connect(db_url) as again:
        assert api.config(again)["depth"] == 2


@pytest.mark.slow
def test_false_beliefs_needs_the_robot_named_when_there_are_two(db: toaster.Database) -> None:
    st = db.store()
    for robot in ("R1", "R2"):
        st.add_entity(robot, "robot", is_self=True, t_ns=0)
    st.add_entity("H", "human", t_ns=0)
    with pytest.raises(InvalidInputError, match=r"\('R1', 'R2'\): name the robot .*other=ID"):
        api.false_beliefs(db, "H")
    assert api.false_beliefs(db, "H", "R2") == []
