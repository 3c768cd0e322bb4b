"""The read path: current, memory, history, as-of, events, ontology, properties, SQL."""

from __future__ import annotations

import pytest

import toaster
from toaster import Fact
from toaster import queries as q
from toaster.errors import ReadOnlyError, ToasterError

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

ON_TABLE = Fact("MUG", "IsOn", "TABLE")
ON_SHELF = Fact("MUG", "IsOn", "SHELF")


@pytest.fixture
def timeline(store: toaster.Store) -> toaster.Store:
    """MUG on TABLE [10, 50), on SHELF [50, ...); BOB IsMoving [20, 30); BOX on TABLE [40, 60)."""
    store.sync_snapshot("pdg", "PR2_ROBOT", 10, [ON_TABLE])
    store.sync_snapshot("pdg", "PR2_ROBOT", 20, [ON_TABLE, Fact("BOB", "IsMoving", value_num=1.0)])
    store.sync_snapshot("pdg", "PR2_ROBOT", 30, [ON_TABLE])
    store.sync_snapshot("pdg", "PR2_ROBOT", 40, [ON_TABLE, Fact("BOX", "IsOn", "TABLE")])
    store.sync_snapshot("pdg", "PR2_ROBOT", 50, [ON_SHELF, Fact("BOX", "IsOn", "TABLE")])
    store.sync_snapshot("pdg", "PR2_ROBOT", 60, [ON_SHELF])
    return store


def test_as_of_matches_intervals_at_every_instant(timeline: toaster.Store) -> None:
    """beliefs_at(t) holds exactly the intervals with from <= t < to (half-open)."""
    db = timeline.db
    history = q.history(db, "PR2_ROBOT")
    for t in range(0, 70, 5):
        expected = sorted(
            (r.subject_id, r.property, r.target_id)
            for r in history
            if r.valid_from_ns <= t and (r.valid_to_ns is None or t < r.valid_to_ns)
        )
        got = sorted(
            (r.subject_id, r.property, r.target_id) for r in q.beliefs_at(db, "PR2_ROBOT", t)
        )
        assert got == expected, t


def test_as_of_filters_by_the_interval_source(timeline: toaster.Store) -> None:
    """source= filters beliefs_at by the intervals' source, as it does the other reads (it
    once failed: source is an interval's column, not its key's)."""
    db = timeline.db
    timeline.sync_snapshot("gaze", "PR2_ROBOT", 70, [Fact("BOB", "IsLookingToward", "MUG")])
    assert {r.source for r in q.beliefs_at(db, "PR2_ROBOT", 75)} == {"pdg", "gaze"}
    assert [r.subject_id for r in q.beliefs_at(db, "PR2_ROBOT", 75, source="gaze")] == ["BOB"]
    assert [r.target_id for r in q.beliefs_at(db, "PR2_ROBOT", 75, source="pdg")] == ["SHELF"]


def test_fact_value_now_and_then(timeline: toaster.Store) -> None:
    """One fact's value now and at a past time; None when it does not hold."""
    db = timeline.db
    assert q.fact_value(db, "PR2_ROBOT", "MUG", "IsOn", "TABLE") is None
    assert q.fact_value(db, "PR2_ROBOT", "MUG", "IsOn", "SHELF").valid_from_ns == 50
    then = q.fact_value(db, "PR2_ROBOT", "MUG", "IsOn", "TABLE", at=49)
    assert (then.valid_from_ns, then.valid_to_ns) == (10, 50)
    assert q.fact_value(db, "PR2_ROBOT", "MUG", "IsOn", "TABLE", at=50) is None
    assert q.fact_value(db, "PR2_ROBOT", "BOB", "IsMoving", at=25).value_num == 1.0


def test_memory_and_windows(timeline: toaster.Store) -> None:
    """Memory holds closed intervals; windows keep the intervals that overlap them."""
    db = timeline.db
    assert [(r.subject_id, r.target_id) for r in q.memory(db, "PR2_ROBOT")] == [
        ("MUG", "TABLE"),
        ("BOB", ""),
        ("BOX", "TABLE"),
    ]
    window = q.history(db, "PR2_ROBOT", since=31, until=45)
    assert [(r.subject_id, r.valid_from_ns) for r in window] == [("MUG", 10), ("BOX", 40)]
    assert [r.subject_id for r in q.history(db, subject=["BOB", "BOX"])] == ["BOB", "BOX"]


def test_events_window_and_order(timeline: toaster.Store) -> None:
    """Events in a window, oldest first or newest first, filtered by kind."""
    db = timeline.db
    window = q.events(db, "PR2_ROBOT", since=30, until=50)
    assert [(e.stamp_ns, e.kind, e.subject_id) for e in window] == [
        (30, "ended", "BOB"),
        (40, "appeared", "BOX"),
        (50, "ended", "MUG"),
        (50, "appeared", "MUG"),
    ]
    latest = q.events(db, kind="ended", newest_first=True, limit=1)
    assert [(e.stamp_ns, e.subject_id) for e in latest] == [(60, "BOX")]


def test_per_agent_views_from_plain_sql(timeline: toaster.Store) -> None:
    """fact_table_X / memory_table_X / events_table_X read like the original's tables."""
    db = timeline.db
    current = q.execute(db, 'SELECT subject_id, target_id FROM "fact_table_PR2_ROBOT"')
    assert current.rows == [("MUG", "SHELF")]
    memory = q.execute(db, 'SELECT count(*) FROM "memory_table_PR2_ROBOT"')
    events = q.execute(db, 'SELECT count(*) FROM "events_table_PR2_ROBOT"')
    assert (memory.rows[0][0], events.rows[0][0]) == (3, 7)
    assert q.execute(db, 'SELECT count(*) FROM "fact_table_BOB"').rows == [(0,)]


def test_execute_is_read_only_unless_write(timeline: toaster.Store) -> None:
    """The database refuses writes without write=True; with it they land, through the write
    surface for facts (the internal tables refuse them even then)."""
    db = timeline.db
    with pytest.raises(ReadOnlyError, match="--write"):
        q.execute(db, "DELETE FROM events")
    assert q.execute(db, "SELECT count(*) FROM events").rows == [(7,)]
    with pytest.raises(ToasterError, match="events is kept by toaster's store"):
        q.execute(db, "DELETE FROM events WHERE stamp_ns < :t", {"t": 30}, write=True)
    q.execute(
        db,
        "INSERT INTO fact_inbox (action, agent_id, subject_id, property, t_ns) "
        "VALUES ('retract', 'PR2_ROBOT', 'MUG', 'IsOn', :t)",
        {"t": 70},
        write=True,
    )
    assert q.execute(db, "SELECT count(*) FROM events").rows == [(8,)]
    with pytest.raises(ToasterError, match="SQL error"):
        q.execute(db, "SELEC nonsense")


def test_are_in_table_with_wildcards(timeline: toaster.Store) -> None:
    """ARE_IN_TABLE answers per fact, with 'NULL' wildcards not inverted (original bug)."""
    answers = q.are_in_table(
        timeline.db,
        "PR2_ROBOT",
        [
            ON_SHELF,
            ON_TABLE,
            Fact("MUG", "IsOn", "NULL"),
            Fact("NULL", "IsOn", "SHELF"),
            Fact("NULL", "IsOn", "TABLE"),
        ],
    )
    assert answers == [True, False, True, True, False]


def test_ontology_descendants(store: toaster.Store) -> None:
    """LEAVE walks the tree recursively and returns instantiated individuals with their flag."""
    for cls, ind, inst in [
        ("thing", "container", False),
        ("container", "mug", False),
        ("mug", "RED_MUG", True),
        ("mug", "BLUE_MUG", True),
        ("container", "box", False),
        ("box", "BOX1", True),
        ("box", "container", False),
    ]:  # a cycle must not loop forever
        store.add_ontology(cls, ind, inst)
    leaves = q.descendants(store.db, "container")
    assert [(r.entity_class, r.individual, r.instantiated) for r in leaves] == [
        ("box", "BOX1", True),
        ("mug", "BLUE_MUG", True),
        ("mug", "RED_MUG", True),
    ]
    everything = q.descendants(store.db, "thing", instantiated_only=False)
    assert ("container", "mug", False) in everything
    assert [r.individual for r in q.ontology(store.db, "mug")] == ["BLUE_MUG", "RED_MUG"]


def test_properties_and_entities(store: toaster.Store) -> None:
    """Open key/value properties of registered entities; unknown entities are refused."""
    store.set_property("MUG", "color", "red")
    store.set_property("MUG", "height", 0.12)
    store.set_property("MUG", "color", "blue")
    assert [(p.key, p.value) for p in q.properties(store.db, "MUG")] == [
        ("color", "blue"),
        ("height", "0.12"),
    ]
    with pytest.raises(toaster.errors.UnknownEntityError, match="'CUP'"):
        store.set_property("CUP", "color", "red")
    assert store.remove_property("MUG", "color") == 1
    assert {e.kind for e in q.entities(store.db, kind="human")} == {"human"}
    assert {a.id: a.is_self for a in q.agents(store.db)} == {
        "PR2_ROBOT": True,
        "BOB": False,
        "ANNE": False,
    }


def test_to_dataframe(timeline: toaster.Store) -> None:
    """Rows become a DataFrame with one column per field, times as integers."""
    frame = q.to_dataframe(q.history(timeline.db))
    assert list(frame.columns) == list(toaster.FactRow._fields)
    assert len(frame) == 4 and str(frame["valid_from_ns"].dtype) == "int64"
