"""Belief holders (revision 0008): agents and nested holders in ``holders``; nested holders are
neither entities nor agents, and go with the agents their chain names."""

from __future__ import annotations

import pytest
import sqlalchemy as sa

import toaster
import toaster.queries as q
from toaster.beliefs import api

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

F = toaster.Fact


def _story(db: toaster.Database) -> None:
    st = db.store()
    st.add_entity("R", "robot", is_self=True, t_ns=0)
    for agent in ("ANNE", "SALLY", "BOB"):
        st.add_entity(agent, "human", t_ns=0)
    room = [
        F("ANNE", "IsInRoom", "KITCHEN"),
        F("BASKET", "IsInRoom", "KITCHEN"),
        F("BOX", "IsInRoom", "KITCHEN"),
        F("BOB", "IsInRoom", "KITCHEN"),
    ]
    st.sync_snapshot(
        "s", "R", 1, [*room, F("SALLY", "IsInRoom", "KITCHEN"), F("MARBLE", "IsIn", "BASKET")]
    )
    st.sync_snapshot(
        "s", "R", 2, [*room, F("SALLY", "IsInRoom", "HALL"), F("MARBLE", "IsIn", "BASKET")]
    )
    st.sync_snapshot(
        "s", "R", 3, [*room, F("SALLY", "IsInRoom", "HALL"), F("MARBLE", "IsIn", "BOX")]
    )


def test_nested_holders_are_holders_not_entities(db: toaster.Database) -> None:
    _story(db)
    nested = [h for h in api.holders(db) if ">" in h]
    assert sorted(nested) == sorted(
        f"{a}>{b}" for a in ("ANNE", "BOB", "SALLY") for b in ("ANNE", "BOB", "SALLY") if a != b
    )
    assert not [e for e in q.entities(db) if ">" in e.id]
    assert [a.id for a in q.agents(db)] == ["R", "ANNE", "SALLY", "BOB"]
    with db.transaction() as conn:
        rows = conn.execute(
            sa.text(
                "SELECT h.id, h.agent_id, h.depth, c.position, c.member_id FROM holders h "
                "LEFT JOIN belief_chain c ON c.holder_id = h.id "
                "WHERE h.id IN ('ANNE', 'ANNE>SALLY') ORDER BY h.id, c.position"
            )
        ).all()
    assert [tuple(r) for r in rows] == [
        ("ANNE", "ANNE", 1, None, None),
        ("ANNE>SALLY", None, 2, 1, "ANNE"),
        ("ANNE>SALLY", None, 2, 2, "SALLY"),
    ]
    # Anne knows that Sally did not see the move: her model of Sally keeps the basket.
    assert api.belief_value(db, "ANNE", "MARBLE", "IsIn", "BASKET", about="SALLY") is not None
    assert api.belief_value(db, "ANNE", "MARBLE", "IsIn", "BOX") is not None


def test_removing_an_agent_removes_the_nested_holders_naming_it(db: toaster.Database) -> None:
    _story(db)
    db.store().remove_entity("BOB")
    assert [h for h in api.holders(db) if "BOB" in h] == []
    with db.transaction() as conn:
        left = conn.execute(
            sa.text(
                "SELECT (SELECT count(*) FROM fact_keys WHERE agent_id LIKE '%BOB%') "
                "+ (SELECT count(*) FROM events WHERE agent_id LIKE '%BOB%') "
                "+ (SELECT count(*) FROM belief_follow WHERE holder_id LIKE '%BOB%') "
                "+ (SELECT count(*) FROM belief_chain WHERE member_id = 'BOB')"
            )
        ).scalar()
    assert left == 0
    # The others go on: Sally comes back and sees the box.
    st = db.store()
    st.sync_snapshot(
        "s",
        "R",
        4,
        [
            F("ANNE", "IsInRoom", "KITCHEN"),
            F("SALLY", "IsInRoom", "KITCHEN"),
            F("BASKET", "IsInRoom", "KITCHEN"),
            F("BOX", "IsInRoom", "KITCHEN"),
            F("MARBLE", "IsIn", "BOX"),
        ],
    )
    assert api.belief_value(db, "SALLY", "MARBLE", "IsIn", "BOX") is not None
    assert api.belief_value(db, "ANNE", "MARBLE", "IsIn", "BOX", about="SALLY") is not None


def test_an_agent_registered_in_plain_sql_is_a_holder(db: toaster.Database) -> None:
    """The trigger on agents: a SQL client registering an agent can write its beliefs."""
    engine = sa.create_engine(db.url.replace("postgresql://", "postgresql+psycopg://"))
    with engine.begin() as conn:
        conn.execute(
            sa.text(
                "INSERT INTO entities (id, name, kind, owner_id, created_ns) "
                "VALUES ('EVE', 'EVE', 'human', '', 0)"
            )
        )
        conn.execute(
            sa.text(
                "INSERT INTO agents (id, num, is_self, registered_ns) VALUES ('EVE', 1, false, 0)"
            )
        )
        conn.execute(
            sa.text(
                "INSERT INTO fact_inbox (agent_id, subject_id, property, "
                "target_id, t_ns) VALUES ('EVE', 'MUG', 'IsOn', 'TABLE', 5)"
            )
        )
    engine.dispose()
    assert "EVE" in api.holders(db)
    assert [(r.subject_id, r.target_id) for r in q.current_facts(db, "EVE")] == [("MUG", "TABLE")]
