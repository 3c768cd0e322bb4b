"""The write path: snapshots become intervals and events, on SQLite and PostgreSQL."""

from __future__ import annotations

import math

import pytest

import toaster
from tests.conftest import count
from toaster import Fact
from toaster import queries as q
from toaster.errors import InvalidInputError, TimeOrderError, UnknownAgentError, UnknownEntityError

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

ON = Fact("MUG", "IsOn", "TABLE", observability=0.8, property_type="position")


def test_snapshot_diff_opens_changes_refreshes_and_ends(store: toaster.Store) -> None:
    """Appear → refresh (confidence) → symbolic change → end, with events for real changes."""
    db = store.db
    dist = Fact("BOB", "Distance", "MUG", "far", 3.0, 0.9, sub_property="3D")
    assert store.sync_snapshot("am", "PR2_ROBOT", 10, [ON, dist]).appeared == 2
    assert (
        store.sync_snapshot("am", "PR2_ROBOT", 20, [ON, dist._replace(value_num=2.5)]).refreshed
        == 1
    )
    result = store.sync_snapshot("am", "PR2_ROBOT", 30, [ON, dist._replace(value_text="medium")])
    assert (result.changed, result.unchanged) == (1, 1)
    assert store.sync_snapshot("am", "PR2_ROBOT", 40, [ON]).ended == 1

    history = q.history(db, "PR2_ROBOT", property="Distance")
    assert [(r.value_text, r.value_num, r.valid_from_ns, r.valid_to_ns) for r in history] == [
        ("far", 2.5, 10, 30),
        ("medium", 3.0, 30, 40),
    ]
    kinds = [
        (e.kind, e.stamp_ns, e.previous_text)
        for e in q.events(db, "PR2_ROBOT", property="Distance")
    ]
    assert kinds == [("appeared", 10, None), ("changed", 30, "far"), ("ended", 40, None)]
    current = q.current_facts(db, "PR2_ROBOT")
    assert [(r.subject_id, r.property, r.target_id, r.valid_from_ns) for r in current] == [
        ("MUG", "IsOn", "TABLE", 10)
    ]
    assert current[0].observability == 0.8 and current[0].property_type == "position"


def test_unchanged_snapshot_writes_nothing(store: toaster.Store) -> None:
    """A repeated snapshot leaves facts and events untouched."""
    store.sync_snapshot("pdg", "PR2_ROBOT", 1, [ON])
    before = (
        count(store.db, "SELECT count(*) FROM events"),
        count(store.db, "SELECT count(*) FROM facts"),
    )
    for t in range(2, 20):
        assert store.sync_snapshot("pdg", "PR2_ROBOT", t, [ON]).unchanged == 1
    after = (
        count(store.db, "SELECT count(*) FROM events"),
        count(store.db, "SELECT count(*) FROM facts"),
    )
    assert before == after == (1, 1)


def test_sources_are_diffed_separately(store: toaster.Store) -> None:
    """One source ending its facts does not end another source's facts."""
    moving = Fact("BOB", "IsMoving", "", value_num=0.5)
    store.sync_snapshot("areas", "PR2_ROBOT", 1, [ON])
    store.sync_snapshot("monitor", "PR2_ROBOT", 1, [moving])
    store.sync_snapshot("monitor", "PR2_ROBOT", 2, [])
    assert [(r.property, r.source) for r in q.current_facts(store.db, "PR2_ROBOT")] == [
        ("IsOn", "areas")
    ]


def test_source_adopts_an_open_fact_of_another_source(store: toaster.Store) -> None:
    """A fact already open (asserted by a user) is taken over without a second interval."""
    store.assert_fact("PR2_ROBOT", ON, t_ns=5)
    store.sync_snapshot("areas", "PR2_ROBOT", 10, [ON])
    store.sync_snapshot("areas", "PR2_ROBOT", 20, [])
    rows = q.history(store.db, "PR2_ROBOT")
    assert [(r.valid_from_ns, r.valid_to_ns) for r in rows] == [(5, 20)]


def test_user_writes_make_sources_reassert(store: toaster.Store) -> None:
    """After EMPTY (or a retraction) the next snapshot re-adds what the source still holds,
    as the original's EMPTY ALL did."""
    store.sync_snapshot("areas", "PR2_ROBOT", 1, [ON])
    store.empty()
    assert q.current_facts(store.db) == []
    store.sync_snapshot("areas", "PR2_ROBOT", 2, [ON])
    assert [r.valid_from_ns for r in q.current_facts(store.db)] == [2]
    store.retract_facts("PR2_ROBOT", "IsOn", "MUG", "NULL", t_ns=3)
    store.sync_snapshot("areas", "PR2_ROBOT", 4, [ON])
    assert [(r.valid_from_ns, r.valid_to_ns) for r in q.history(store.db)] == [(2, 3), (4, None)]


def test_second_store_process_sees_changes(db_url: str, store: toaster.Store) -> None:
    """Two handles on one database: a retraction by one makes the other's source re-assert."""
    store.sync_snapshot("areas", "PR2_ROBOT", 1, [ON])
    with toaster.connect(db_url) as other:
        other.store().retract_facts("PR2_ROBOT", "IsOn", t_ns=2)
    store.sync_snapshot("areas", "PR2_ROBOT", 3, [ON])
    assert [(r.valid_from_ns, r.valid_to_ns) for r in q.history(store.db)] == [(1, 2), (3, None)]


def test_assert_and_retract_with_wildcards(store: toaster.Store) -> None:
    """set-info FACT add/remove semantics: value change, refresh, NULL wildcards, exact key."""
    assert store.assert_fact("PR2_ROBOT", ON, t_ns=1) == "appeared"
    assert store.assert_fact("PR2_ROBOT", ON._replace(confidence=0.5), t_ns=2) == "refreshed"
    assert store.assert_fact("PR2_ROBOT", ON._replace(value_text="false"), t_ns=3) == "changed"
    store.assert_fact("PR2_ROBOT", Fact("BOX", "IsOn", "TABLE"), t_ns=3, strict=False)
    store.assert_fact(
        "PR2_ROBOT",
        Fact("MUG", "IsMovingToward", "BOB", sub_property="direction"),
        t_ns=3,
        strict=False,
    )
    store.assert_fact(
        "PR2_ROBOT",
        Fact("MUG", "IsMovingToward", "BOB", sub_property="distance"),
        t_ns=3,
        strict=False,
    )
    # the original deleted both IsMovingToward facts here (no subProperty in its key)
    assert (
        store.retract_facts(
            "PR2_ROBOT", "IsMovingToward", "MUG", "BOB", sub_property="direction", t_ns=4
        )
        == 1
    )
    assert store.retract_facts("PR2_ROBOT", "IsOn", "NULL", "TABLE", t_ns=5) == 2
    left = [(r.property, r.sub_property) for r in q.current_facts(store.db, "PR2_ROBOT")]
    assert left == [("IsMovingToward", "distance")]
    ended = q.events(store.db, "PR2_ROBOT", kind="ended", property="IsOn")
    assert {(e.subject_id, e.stamp_ns) for e in ended} == {("MUG", 5), ("BOX", 5)}


def test_events_record_user_events(store: toaster.Store) -> None:
    """set-info EVENT stores a user event with its own time."""
    store.record_event("PR2_ROBOT", Fact("BOB", "PickUp", "MUG"), t_ns=42)
    (event,) = q.events(store.db, kind="event")
    assert (event.subject_id, event.property, event.target_id, event.stamp_ns) == (
        "BOB",
        "PickUp",
        "MUG",
        42,
    )


@pytest.mark.parametrize(
    ("fact", "message"),
    [
        (Fact("", "IsOn", "TABLE"), "invalid subject id ''"),
        (Fact("MUG", "", "TABLE"), "invalid property ''"),
        (Fact("MUG", "IsOn", "TABLE", confidence=1.5), "invalid confidence 1.5"),
        (Fact("MUG", "IsOn", "TABLE", confidence=math.nan), "invalid confidence nan"),
        (Fact("MUG", "IsOn", "TABLE", observability=-0.1), "invalid observability -0.1"),
        (Fact("MUG", "IsOn", "TABLE", value_num=math.inf), "invalid numeric value inf"),
    ],
)
def test_bad_facts_are_refused_and_nothing_is_written(
    store: toaster.Store, fact: Fact, message: str
) -> None:
    """A bad fact in a snapshot fails the whole tick with a one-line error naming it."""
    good = Fact("BOX", "IsOn", "TABLE")
    with pytest.raises(InvalidInputError, match=message.replace("(", r"\(")):
        store.sync_snapshot("pdg", "PR2_ROBOT", 1, [good, fact])
    assert q.history(store.db) == []
    assert store.sync_snapshot("pdg", "PR2_ROBOT", 1, [good]).appeared == 1


def test_unknown_agent_and_entity(store: toaster.Store) -> None:
    """Unknown agents and (for user assertions) unknown entities are named with the fix."""
    with pytest.raises(UnknownAgentError, match="unknown agent 'SALLY'.*set-info ENTITY"):
        store.sync_snapshot("pdg", "SALLY", 1, [ON])
    with pytest.raises(UnknownEntityError, match="unknown entity 'CUP'"):
        store.assert_fact("PR2_ROBOT", Fact("CUP", "IsOn", "TABLE"), t_ns=1)
    assert q.history(store.db) == []


def test_time_order_is_enforced(store: toaster.Store) -> None:
    """Snapshots of one source must come in time order; retracting before the start fails."""
    store.sync_snapshot("pdg", "PR2_ROBOT", 100, [ON])
    with pytest.raises(TimeOrderError, match="older than its previous one"):
        store.sync_snapshot("pdg", "PR2_ROBOT", 50, [])
    with pytest.raises(TimeOrderError, match="it started later"):
        store.retract_facts("PR2_ROBOT", "IsOn", t_ns=10)
    assert [r.valid_to_ns for r in q.history(store.db)] == [None]


def test_hostile_ids_are_stored_literally(store: toaster.Store) -> None:
    """Quotes, semicolons and SQL in ids are data, never code; per-agent views still work."""
    weird = 'Bob\'s "robot"; DROP TABLE facts; -- :x %s'
    store.add_entity(weird, "robot")
    store.add_entity("o'neil; DELETE", "object")
    fact = Fact("o'neil; DELETE", "Is'On", "%(x)s ?", value_text="'); --")
    store.sync_snapshot(weird, weird, 1, [fact])
    (row,) = q.current_facts(store.db, weird)
    assert (row.subject_id, row.property, row.target_id, row.value_text, row.source) == (
        "o'neil; DELETE",
        "Is'On",
        "%(x)s ?",
        "'); --",
        weird,
    )
    agent = next(a for a in q.agents(store.db) if a.id == weird)
    quoted = '"' + agent.fact_view.replace('"', '""') + '"'
    result = q.execute(store.db, f"SELECT subject_id, target_id FROM {quoted}")
    assert result.rows == [("o'neil; DELETE", "%(x)s ?")]


def test_an_agent_id_cannot_pose_as_a_nested_holder(store: toaster.Store) -> None:
    """'BOB>ANNE' is Bob's model of Anne: no human or robot may take that id (its beliefs
    would be read as his, its actions taken for none); an object may."""
    toaster.beliefs.configure(store.db, depth=2)
    before = toaster.beliefs.holders(store.db)
    for kind in ("human", "robot"):
        with pytest.raises(InvalidInputError, match="'>' joins nested belief holders"):
            store.add_entity("BOB>ANNE", kind)
    with pytest.raises(InvalidInputError, match="'>' joins"):
        store.add_entities([("CROWD>1", "human", "", "", None)])
    assert toaster.beliefs.holders(store.db) == before
    store.add_entity("BOX>LID", "object")
    assert [e.kind for e in q.entities(store.db, "BOX>LID")] == ["object"]


def test_long_agent_ids_get_distinct_views(store: toaster.Store) -> None:
    """View names fit PostgreSQL's 63 bytes and stay distinct for long ids."""
    ids = ["h" * 80 + "1", "h" * 80 + "2"]
    for agent_id in ids:
        store.add_entity(agent_id, "human")
        store.sync_snapshot("pdg", agent_id, 1, [Fact(agent_id, "IsMoving")])
    views = {a.id: a.fact_view for a in q.agents(store.db) if a.id in ids}
    assert len(set(views.values())) == 2
    assert all(len(v.encode()) <= 63 for v in views.values())
    for agent_id, view in views.items():
        assert q.execute(store.db, f'SELECT subject_id FROM "{view}"').rows == [(agent_id,)]


def test_remove_agent_drops_its_beliefs_and_views(store: toaster.Store) -> None:
    """Removing an agent removes its facts, events and views, not other agents' facts."""
    store.sync_snapshot("pdg", "BOB", 1, [ON])
    store.sync_snapshot("pdg", "PR2_ROBOT", 1, [ON])
    store.remove_entity("BOB")
    assert [r.agent_id for r in q.history(store.db)] == ["PR2_ROBOT"]
    assert "BOB" not in {a.id for a in q.agents(store.db)}
    with pytest.raises(toaster.errors.ToasterError):
        q.execute(store.db, 'SELECT * FROM "fact_table_BOB"')


def test_one_transaction_for_a_batch(store: toaster.Store) -> None:
    """Store calls inside store.transaction() are all or nothing."""
    with pytest.raises(UnknownEntityError), store.transaction():
        store.assert_fact("PR2_ROBOT", ON, t_ns=1)
        store.add_entity("LAMP")
        store.assert_fact("PR2_ROBOT", Fact("NOPE", "IsOn", "TABLE"), t_ns=1)
    assert q.history(store.db) == []
    assert q.entities(store.db, "LAMP") == []


def test_rules_run_in_the_same_transaction(store: toaster.Store) -> None:
    """A rule sees each change set; when it fails, the triggering write is rolled back."""
    seen = []

    class Refuses:
        def __call__(self, conn, changes) -> None:
            seen.append((changes.agent_id, [f.property for _, f in changes.appeared]))
            if any(f.property == "Bad" for _, f in changes.appeared):
                msg = "rule refused"
                raise InvalidInputError(msg)

        def detach(self, conn, agent_id, *, keep) -> None:
            """Shares no rows."""

    store.add_rule(Refuses())
    store.sync_snapshot("pdg", "PR2_ROBOT", 1, [ON])
    with pytest.raises(InvalidInputError, match="rule refused"):
        store.sync_snapshot("pdg", "PR2_ROBOT", 2, [ON, Fact("MUG", "Bad")])
    assert seen == [("PR2_ROBOT", ["IsOn"]), ("PR2_ROBOT", ["Bad"])]
    assert [r.property for r in q.history(store.db)] == ["IsOn"]
    assert store.sync_snapshot("pdg", "PR2_ROBOT", 3, [ON]).unchanged == 1
