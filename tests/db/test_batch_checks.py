"""A fact batch is checked as arrays (each id and label once, the numbers with numpy): bad
values from any producer still fail in one line and write nothing."""

from __future__ import annotations

import numpy as np
import pytest

import toaster
from toaster.errors import InvalidInputError
from toaster.producers.batch import FactBatch
from toaster.world import World

S = 1_000_000_000


def _world(n: int = 6) -> World:
    world = World()
    for i in range(n):
        world.add_entity(f"e{i}", "object")
    return world


def _batch(
    world: World, dist: np.ndarray, *, labels: object = None, conf: object = 0.9
) -> FactBatch:
    batch = FactBatch(world)
    rows = np.arange(len(dist))
    batch.add("Distance", rows, "e0", value_text="", value_num=dist, conf=conf)
    zone_labels = np.array(["zone_a", "zone_b"], dtype=object) if labels is None else labels
    codes = (rows % 2).astype(np.int64)
    batch.add("IsInArea", rows, (codes, zone_labels))
    return batch


def _rows(db: toaster.Database) -> tuple[int, int, int]:
    with db.transaction() as conn:
        return tuple(  # type: ignore[return-value]
            conn.exec_driver_sql(f"SELECT COUNT(*) FROM {table}").scalar_one()
            for table in ("facts", "events", "fact_samples")
        )


def _current(db: toaster.Database) -> dict[tuple[str, str, str], tuple[str, object, float]]:
    with db.transaction() as conn:
        rows = conn.exec_driver_sql(
            "SELECT k.subject_id, k.property, k.target_id, f.value_text, f.value_num, "
            "f.confidence FROM facts f JOIN fact_keys k ON k.id = f.key_id "
            "WHERE f.valid_to_ns IS NULL AND k.agent_id = 'PR2_ROBOT'"
        ).all()
    return {(r[0], r[1], r[2]): (r[3], r[4], r[5]) for r in rows}


@pytest.mark.parametrize(
    ("bad", "message"),
    [
        ({"dist": np.array([1.0, np.nan, 3.0, 4.0])}, "invalid numeric value nan for e1 Distance"),
        ({"dist": np.array([1.0, 2.0, np.inf, 4.0])}, "invalid numeric value inf for e2 Distance"),
        ({"conf": np.array([0.5, 0.5, 1.5, 0.5])}, "invalid confidence 1.5"),
        ({"labels": np.array(["zone_a", "zone\x00b"], dtype=object)}, "NUL character"),
        ({"labels": np.array(["zone_a", "z" * 300], dtype=object)}, "ids are at most 256 bytes"),
    ],
)
def test_a_bad_value_in_a_batch_fails_in_one_line_and_writes_nothing(
    db: toaster.Database, store: toaster.Store, bad: dict, message: str
) -> None:
    world = _world()
    dist = np.array([1.0, 2.0, 3.0, 4.0])
    store.sync_snapshot("user_producer", "PR2_ROBOT", 10 * S, _batch(world, dist))
    moved = dist + 0.5  # the array path: only the moved numbers are written
    store.sync_snapshot("user_producer", "PR2_ROBOT", 11 * S, _batch(world, moved))
    before, current = _rows(db), _current(db)
    kwargs = {"dist": moved + 0.5, **bad}
    with pytest.raises(InvalidInputError, match=message) as caught:
        store.sync_snapshot("user_producer", "PR2_ROBOT", 12 * S, _batch(world, **kwargs))
    assert "\n" not in str(caught.value)
    assert _rows(db) == before and _current(db) == current
    # The store's memory is untouched: the next good batch writes as if the bad one never came.
    store.sync_snapshot("user_producer", "PR2_ROBOT", 13 * S, _batch(world, moved + 1.0))
    assert _current(db)[("e3", "Distance", "e0")][1] == pytest.approx(5.5)


def test_numbers_a_batch_gives_as_ints_are_stored_as_floats(
    db: toaster.Database, store: toaster.Store
) -> None:
    """A batch whose constants are not floats (an int confidence) takes the fact-by-fact
    check, which normalises them, as before."""
    world = _world()
    dist = np.array([1.0, 2.0, 3.0, 4.0])
    store.sync_snapshot("user_producer", "PR2_ROBOT", 10 * S, _batch(world, dist, conf=1))
    store.sync_snapshot("user_producer", "PR2_ROBOT", 11 * S, _batch(world, dist + 1, conf=1))
    got = _current(db)
    assert got[("e0", "Distance", "e0")] == ("", 2.0, 1.0)
    assert isinstance(got[("e0", "Distance", "e0")][2], float)


def test_a_batch_ends_the_facts_it_no_longer_holds(
    db: toaster.Database, store: toaster.Store
) -> None:
    """The facts a batch drops end with the values stored (read from the store's memory)."""
    world = _world()
    dist = np.array([1.0, 2.0, 3.0, 4.0])
    store.sync_snapshot("user_producer", "PR2_ROBOT", 10 * S, _batch(world, dist))
    store.sync_snapshot("user_producer", "PR2_ROBOT", 11 * S, _batch(world, dist + 0.5))
    result = store.sync_snapshot("user_producer", "PR2_ROBOT", 12 * S, _batch(world, dist[:2]))
    assert result.ended == 4  # two distances, two memberships
    with db.transaction() as conn:
        ended = conn.exec_driver_sql(
            "SELECT k.subject_id, k.property, e.value_num FROM events e "
            "JOIN fact_keys k ON k.id = e.key_id WHERE e.kind = 'ended' ORDER BY 1, 2"
        ).all()
    assert [tuple(r) for r in ended] == [
        ("e2", "Distance", 3.5),
        ("e2", "IsInArea", None),
        ("e3", "Distance", 4.5),
        ("e3", "IsInArea", None),
    ]
    assert set(_current(db)) == {
        ("e0", "Distance", "e0"),
        ("e1", "Distance", "e0"),
        ("e0", "IsInArea", "zone_a"),
        ("e1", "IsInArea", "zone_b"),
    }


def test_int_numbers_of_listed_facts_are_stored_as_floats(
    db: toaster.Database, store: toaster.Store
) -> None:
    """A user's Fact with an int confidence and value beside float ones (PostgreSQL's float
    arrays refused the mix: check_fact compared 1 == 1.0 and kept the int)."""
    facts = [
        toaster.Fact("e0", "Distance", "e1", value_num=2, confidence=1),
        toaster.Fact("e1", "Distance", "e0", value_num=2.5, confidence=0.5),
    ]
    store.sync_snapshot("user_producer", "PR2_ROBOT", 10 * S, facts)
    got = _current(db)
    assert got[("e0", "Distance", "e1")] == ("true", 2.0, 1.0)
    assert all(isinstance(v, float) for v in got[("e0", "Distance", "e1")][1:])
