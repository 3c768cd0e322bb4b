"""Robots whose people never meet run their belief rules side by side (revision 0024).

Each holder has its own clock (``holders.clock_ns``): a run takes the clocks of the holders
its robot's facts name and, on PostgreSQL, locks their rows only. Two robots in one database,
each with its own people: robot R1's run holds its transaction open while R2's tick commits;
a third robot that sees one of R1's people waits for R1 (and, past the lock timeout, fails in
one line, rolled back). The beliefs are those of the same ticks written one after another,
in either order, and ``toaster db check`` finds nothing.
"""

from __future__ import annotations

import shutil
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path

import pytest
import sqlalchemy as sa

import toaster
from tests.conftest import pg_schema
from toaster.db.invariants import violations
from toaster.errors import DatabaseLockedError
from toaster.model import Fact

S = 1_000_000_000
#: Each robot's room, its people, its mug and the mug's two places.
WORLDS = {
    "R1": ("KITCHEN", ("ANNE", "BOB"), "MUG", ("SHELF", "BOX")),
    "R2": ("HALL", ("CARL", "DORA"), "CUP", ("TABLE", "DRAWER")),
}


def _register(db: toaster.Database) -> None:
    store = db.store()
    with store.transaction():
        for robot, (room, people, thing, places) in WORLDS.items():
            store.add_entity(robot, "robot", is_self=True, t_ns=0)
            for person in people:
                store.add_entity(person, "human", t_ns=0)
            for entity in (room, thing, *places):
                store.add_entity(entity, "object", t_ns=0)
        store.add_entity("R3", "robot", is_self=True, t_ns=0)


def _tick(store: toaster.Store, robot: str, t_ns: int, place: int) -> None:
    room, people, thing, places = WORLDS[robot]
    facts = [Fact(person, "IsInRoom", room) for person in people]
    facts += [Fact(thing, "IsInRoom", room), Fact(thing, "IsIn", places[place])]
    store.sync_many(robot, t_ns, [("scene", facts)])


def _beliefs(db: toaster.Database) -> tuple[list[tuple[object, ...]], list[tuple[object, ...]]]:
    """Every agent's and holder's intervals and events, and the invariants hold."""
    with db.transaction() as conn:
        assert violations(conn) == []
        history = conn.execute(
            sa.text(
                "SELECT agent_id, subject_id, property, target_id, value_text, valid_from_ns, "
                "valid_to_ns FROM fact_history ORDER BY 1, 2, 3, 4, 6"
            )
        ).all()
        events = conn.execute(
            sa.text(
                "SELECT agent_id, subject_id, property, target_id, kind, stamp_ns "
                "FROM event_log ORDER BY 1, 2, 3, 4, 6, 5"
            )
        ).all()
    return [tuple(r) for r in history], [tuple(r) for r in events]


def _serial(url: str, order: tuple[str, ...]) -> tuple[list[tuple[object, ...]], ...]:
    with toaster.connect(url) as db:
        _register(db)
        store = db.store()
        for robot in WORLDS:
            _tick(store, robot, 1 * S, 0)
        for robot in order:
            _tick(store, robot, 2 * S, 1)
        return _beliefs(db)


@contextmanager
def _another(db_url: str, tmp_path: Path, sqlite_template: Path) -> Iterator[str]:
    """A second fresh database on ``db_url``'s backend."""
    if db_url.startswith("sqlite"):
        shutil.copy(sqlite_template, tmp_path / "other.db")
        yield f"sqlite:///{tmp_path / 'other.db'}"
        return
    with pg_schema() as url:
        yield url


def test_disjoint_robots_runs_do_not_depend_on_their_order(
    db_url: str, tmp_path: Path, sqlite_template: Path
) -> None:
    """Robots with their own people, ticking at the same times: their runs at one time give
    the same intervals and events, row for row, in either order (with one clock for all, the
    second run came 1 ns after the first), each holder taking its robot's changes at the
    tick's time."""
    first = _serial(db_url, ("R1", "R2"))
    with _another(db_url, tmp_path, sqlite_template) as url:
        assert _serial(url, ("R2", "R1")) == first
    history, _ = first
    for holder, thing, places in (
        ("ANNE", "MUG", ("SHELF", "BOX")),
        ("DORA", "CUP", ("TABLE", "DRAWER")),
    ):
        rows = sorted((r[5], r[3], r[6]) for r in history if r[:3] == (holder, thing, "IsIn"))
        assert rows == [(1 * S, places[0], 2 * S), (2 * S, places[1], None)]


@pytest.mark.postgresql
def test_a_run_waits_only_for_runs_sharing_a_holder(
    pg_schema_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """R1's tick holds its transaction open after its run: R2 (other people) ticks and
    commits meanwhile; R3, which sees R1's ANNE, waits for R1's holders and, past the lock
    timeout, fails in one line with nothing written. Once R1 commits, R3 ticks. The beliefs
    equal those of the same ticks written one after another."""
    monkeypatch.setenv("TOASTER_LOCK_TIMEOUT", "0.5")
    with toaster.connect(pg_schema_url) as a, toaster.connect(pg_schema_url) as b:
        _register(a)
        store_a, store_b = a.store(), b.store()
        for robot in WORLDS:
            _tick(store_a, robot, 1 * S, 0)
        with store_a.transaction():
            _tick(store_a, "R1", 2 * S, 1)  # R1's run: its holders locked until the commit
            _tick(store_b, "R2", 2 * S, 1)  # other people: commits at once
            with b.transaction() as conn:
                carl = conn.execute(
                    sa.text(
                        "SELECT target_id FROM current_facts WHERE agent_id = 'CARL' "
                        "AND subject_id = 'CUP' AND property = 'IsIn'"
                    )
                ).scalar_one()
            assert carl == "DRAWER"
            with pytest.raises(DatabaseLockedError) as caught:  # shares ANNE with R1's run
                store_b.sync_many("R3", 2 * S, [("scene", [Fact("ANNE", "IsInRoom", "KITCHEN")])])
            assert "\n" not in str(caught.value)
            assert "(waited 0.5 s)" in str(caught.value)
        with b.transaction() as conn:  # R3's tick was rolled back whole
            assert (
                conn.execute(
                    sa.text("SELECT COUNT(*) FROM fact_keys WHERE agent_id = 'R3'")
                ).scalar_one()
                == 0
            )
        concurrent = _beliefs(a)
    with pg_schema() as url:
        assert concurrent == _serial(url, ("R1", "R2"))


@pytest.mark.postgresql
def test_a_robots_producers_take_turns_on_its_clock(
    pg_schema_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """R1's rooms hold their transaction open after their run; R1's things, naming nobody,
    wait for it (revision 0031: a run locks its own robot's clock) and, past the lock timeout,
    fail in one line with nothing written. Before, they committed at once, and a statement of
    the rooms' run that came after read them: a fact that began after the run's time, taken
    with an event no interval began at (tests/db/test_many_writers.py)."""
    monkeypatch.setenv("TOASTER_LOCK_TIMEOUT", "0.5")
    room, people, thing, places = WORLDS["R1"]
    with toaster.connect(pg_schema_url) as a, toaster.connect(pg_schema_url) as b:
        _register(a)
        store_a, store_b = a.store(), b.store()
        with store_a.transaction():
            rooms = [Fact(person, "IsInRoom", room) for person in (*people, places[0])]
            store_a.sync_many("R1", 1 * S, [("rooms", rooms)])
            with pytest.raises(DatabaseLockedError) as caught:
                store_b.sync_many("R1", 1 * S, [("things", [Fact(thing, "IsIn", places[0])])])
            assert "\n" not in str(caught.value)
        store_b.sync_many("R1", 2 * S, [("things", [Fact(thing, "IsIn", places[0])])])
        _, events = _beliefs(a)
    assert [e for e in events if e[0] == "ANNE" and e[1] == thing] == [
        ("ANNE", thing, "IsIn", places[0], "appeared", 2 * S)
    ]
