"""beliefs_at against a brute-force answer computed in Python from the stored rows.

A random story (tests/beliefs' rooms, box, colours, temperatures, visibility) is replayed by a
robot whose humans follow its keys (followed periods) and who also hold beliefs of their own;
numbers move beyond their tolerance (samples). At every boundary of an interval, a period or
a sample (and one either side of it) the as-of answer of every holder must be, field for field
and in order, the intervals holding then, read straight from ``facts``, ``belief_follow`` and
``fact_samples`` by the definitions of docs/store.md and docs/beliefs.md.
"""

from __future__ import annotations

import random
from collections import defaultdict
from typing import Any

import pytest

import toaster
import toaster.queries as q
from tests.beliefs.test_follow import HUMANS, OBJECTS, ROOMS, Story
from toaster import Fact
from toaster.beliefs import api
from toaster.model import FactRow

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)


def _replay(db: toaster.Database, seed: int, ticks: int) -> None:
    """The robot R perceives the story; each human also writes a few beliefs of its own."""
    rng = random.Random(seed)
    st = db.store()
    st.add_entity("R", "robot", is_self=True, t_ns=0)
    for h in HUMANS:
        st.add_entity(h, "human", t_ns=0)
    for e in (*OBJECTS, "BOX", *ROOMS):
        st.add_entity(e, "object", t_ns=0)
    story = Story(seed)
    for tick in range(1, ticks + 1):
        story.step()
        st.sync_snapshot("world", "R", tick * 10, story.facts())
        for h in HUMANS:
            if rng.random() < 0.3:
                own = [
                    Fact(o, "Likes", h, value_text=rng.choice(("yes", "no")), value_num=float(i))
                    for i, o in enumerate(OBJECTS)
                    if rng.random() < 0.5
                ]
                st.sync_snapshot("mind", h, tick * 10 + 5, own)


def _table(db: toaster.Database, sql: str) -> list[tuple[Any, ...]]:
    return q.execute(db, sql, max_rows=10**6).rows


def _brute(db: toaster.Database) -> dict[str, Any]:
    keys = {
        r[0]: r[1:]
        for r in _table(
            db,
            "SELECT id, agent_id, subject_id, subject_owner_id, "
            "property, property_type, sub_property, target_id, "
            "target_owner_id FROM fact_keys",
        )
    }
    facts = defaultdict(list)
    for r in _table(
        db,
        "SELECT id, key_id, value_text, value_num, confidence, observability, "
        "valid_from_ns, valid_to_ns, recorded_ns, source FROM facts",
    ):
        facts[r[1]].append(r)
    samples = defaultdict(list)
    for r in _table(
        db,
        "SELECT fact_id, until_ns, value_num, confidence, observability "
        "FROM fact_samples ORDER BY fact_id, until_ns",
    ):
        samples[r[0]].append(r)
    follows = defaultdict(list)
    for r in _table(db, "SELECT hkey, self_key, from_ns, to_ns, pconf FROM belief_follow"):
        follows[r[0]].append(r)
    return {"keys": keys, "facts": facts, "samples": samples, "follows": follows}


def _holds(start: int, end: int | None, t: int) -> bool:
    return start <= t and (end is None or end > t)


def _numbers(stored: dict[str, Any], f: tuple[Any, ...], t: int) -> tuple[Any, Any, Any]:
    """value_num, confidence, observability of interval ``f`` at ``t``: its first sample
    after ``t``, else its own."""
    after = [s for s in stored["samples"][f[0]] if s[1] > t]
    return tuple(after[0][2:]) if after else (f[3], f[4], f[5])


def _expected(stored: dict[str, Any], agent: str, t: int) -> list[FactRow]:
    rows: list[tuple[tuple[Any, ...], FactRow]] = []
    for key_id, key in stored["keys"].items():
        if key[0] != agent:
            continue
        for f in stored["facts"][key_id]:  # own intervals holding at t
            if _holds(f[6], f[7], t):
                rows.append((key_id, FactRow(*key, f[2], *_numbers(stored, f, t), *f[6:])))
        for _, self_key, start, end, pconf in stored["follows"][key_id]:
            if not _holds(start, end, t):
                continue
            for f in stored["facts"][self_key]:  # the self's interval, clipped to the period
                if _holds(f[6], f[7], t):
                    num, conf, obs = _numbers(stored, f, t)
                    clipped_to = f[7] if end is None else end if f[7] is None else min(f[7], end)
                    row = FactRow(
                        *key,
                        f[2],
                        num,
                        min(1.0, conf * pconf),
                        obs,
                        max(f[6], start),
                        clipped_to,
                        f[8],
                        "beliefs",
                    )
                    rows.append((key_id, row))
    rows.sort(key=lambda kr: (kr[1].subject_id, kr[1].property, kr[1].target_id, kr[0]))
    return [row for _, row in rows]


def _instants(stored: dict[str, Any], rng: random.Random) -> list[int]:
    edges = {0}
    for intervals in stored["facts"].values():
        edges.update(t for f in intervals for t in (f[6], f[7]) if t is not None)
    for periods in stored["follows"].values():
        edges.update(t for p in periods for t in (p[2], p[3]) if t is not None)
    for samples in stored["samples"].values():
        edges.update(s[1] for s in samples)
    near = {t + d for t in edges for d in (-1, 0, 1) if t + d >= 0}
    return sorted(near | {rng.randrange(max(near) + 10) for _ in range(20)})


@pytest.mark.parametrize("seed", [4, 5])
def test_as_of_equals_brute_force_over_a_random_memory(db: toaster.Database, seed: int) -> None:
    _replay(db, seed, 50)
    stored = _brute(db)
    assert any(stored["follows"].values()), "the story gave no followed period"
    assert any(stored["samples"].values()), "the story gave no sample"
    rng = random.Random(seed)
    holders = api.holders(db)
    checked = followed = 0
    for t in _instants(stored, rng):
        for agent in ("R", *holders):
            expected = _expected(stored, agent, t)
            assert q.beliefs_at(db, agent, t) == expected, (agent, t)
            checked += len(expected)
            followed += sum(r.source == "beliefs" for r in expected)
    assert checked > 1000 and followed > 100, (checked, followed)


def test_as_of_filters_equal_brute_force(db: toaster.Database) -> None:
    """Filters (a list included) and source, on own and followed rows alike."""
    _replay(db, 6, 40)
    stored = _brute(db)
    cases: list[tuple[dict[str, Any], Any]] = [
        ({"subject": "MUG"}, lambda r: r.subject_id == "MUG"),
        ({"property": ["IsInRoom", "Likes"]}, lambda r: r.property in ("IsInRoom", "Likes")),
        ({"source": "beliefs"}, lambda r: r.source == "beliefs"),
        ({"source": "mind"}, lambda r: r.source == "mind"),
        (
            {"source": ["world", "beliefs"], "target": "HALL"},
            lambda r: r.source in ("world", "beliefs") and r.target_id == "HALL",
        ),
        ({"value": "red"}, lambda r: r.value_text == "red"),
        ({"value": ["yes", "blue"], "source": "NULL"}, lambda r: r.value_text in ("yes", "blue")),
        ({"source": []}, lambda r: False),
        ({"value": []}, lambda r: False),
        ({"source": "NULL"}, lambda r: True),
    ]
    for t in range(0, 420, 7):
        for agent in ("R", *HUMANS):
            everything = _expected(stored, agent, t)
            for filters, keep in cases:
                got = q.beliefs_at(db, agent, t, **filters)
                assert got == [r for r in everything if keep(r)], (agent, t, filters)


@pytest.mark.backend("sqlite")
def test_sqlite_merges_the_halves_in_key_order(db: toaster.Database) -> None:
    """Revision 0022's index gives the agent's keys in the result's order: no sort."""
    from toaster.queries import facts

    sql = facts._as_of_sql("sqlite", "k.agent_id = :agent_id", "1 = 1", True)
    with db.transaction() as conn:
        plan = [r[-1] for r in conn.exec_driver_sql(f"EXPLAIN QUERY PLAN {sql}", ("R", 5))]
    assert "MERGE (UNION ALL)" in plan and not any("TEMP B-TREE" in p for p in plan), plan
    assert sum("ix_fact_keys_agent_order" in p for p in plan) == 2, plan


def test_as_of_joins_the_callers_transaction_and_leaves_none(db: toaster.Database) -> None:
    """Inside a transaction it reads that transaction's writes; outside it leaves the shared
    connection as it found it (no transaction, PostgreSQL's autocommit off)."""
    st = db.store()
    st.add_entity("R", "robot", is_self=True, t_ns=0)
    st.sync_snapshot("world", "R", 10, [Fact("MUG", "IsOn", "TABLE")])
    with db.transaction(write=True):
        st.sync_snapshot("world", "R", 20, [Fact("MUG", "IsOn", "SHELF")])
        assert [r.target_id for r in q.beliefs_at(db, "R", 25)] == ["SHELF"]
        assert db.connection.in_transaction()
    assert [r.target_id for r in q.beliefs_at(db, "R", 15)] == ["TABLE"]
    assert not db.connection.in_transaction()
    if db.dialect_name == "postgresql":
        from toaster.db.engine import dbapi

        assert dbapi(db.connection).autocommit is False
    st.sync_snapshot("world", "R", 30, [])  # the store's own transactions go on as before
    assert q.beliefs_at(db, "R", 35) == []
    assert [r.target_id for r in q.beliefs_at(db, "R", 29)] == ["SHELF"]
