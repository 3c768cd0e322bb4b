"""Migrations: the schema they build equals schema.py; up, down, up again on both backends."""

from __future__ import annotations

import hashlib
import itertools
import sqlite3
from pathlib import Path
from typing import Any

import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import inspect

import toaster
import toaster.queries as q
from tests.migrations import beliefs_story
from toaster.db import migrate
from toaster.db.engine import make_engine
from toaster.db.schema import metadata
from toaster.errors import SchemaOutdatedError


@pytest.mark.slow
def test_migrations_match_the_declared_schema(empty_url: str) -> None:
    """Upgrading an empty database yields exactly the tables and indexes of schema.py."""
    engine = make_engine(empty_url)
    migrate.upgrade(engine)
    with engine.connect() as conn:
        diff = compare_metadata(MigrationContext.configure(conn), metadata)
    engine.dispose()
    assert diff == []


@pytest.mark.slow
def test_upgrade_downgrade_upgrade(empty_url: str) -> None:
    """Down to base removes every table and view (agents' views included); up again works."""
    with toaster.connect(empty_url) as db:
        db.store().add_entity("SALLY", "human")
    engine = make_engine(empty_url)
    migrate.downgrade(engine, "base")
    with engine.connect() as conn:
        inspector = inspect(conn)
        assert inspector.get_view_names() == []
        assert set(inspector.get_table_names()) <= {"alembic_version"}
    migrate.upgrade(engine)
    assert migrate.current_revision(engine) == migrate.head_revision()
    engine.dispose()


def test_new_database_is_created_and_old_one_refused(empty_url: str) -> None:
    """A new database is migrated on first use; one behind the code gets the fix in the error."""
    engine = make_engine(empty_url)
    migrate.upgrade(engine, "0001")
    engine.dispose()
    if migrate.head_revision() == "0001":
        pytest.skip("only one revision exists")
    with pytest.raises(SchemaOutdatedError, match="run `toaster db upgrade"):
        toaster.connect(empty_url)


@pytest.mark.slow
def test_empty_database_is_created_on_first_use(empty_url: str) -> None:
    """connect() on an empty database migrates it to head."""
    with toaster.connect(empty_url) as db:
        assert migrate.current_revision(db.engine) == migrate.head_revision()


@pytest.mark.slow
def test_downgrade_with_nested_holders_named_oddly(empty_url: str) -> None:
    """Agents and nested holders whose ids hold ':', '%', quotes are dropped cleanly."""
    from toaster import Fact
    from toaster.beliefs import api

    odd = ["a:b %s", "c'd \"e\""]
    with toaster.connect(empty_url) as db:
        store = db.store()
        store.add_entity("R", "robot", is_self=True, t_ns=0)
        for agent in odd:
            store.add_entity(agent, "human", t_ns=0)
        store.add_entity("MUG", "object", t_ns=0)
        room = [Fact(agent, "IsInRoom", "LAB") for agent in odd] + [Fact("MUG", "IsInRoom", "LAB")]
        store.sync_snapshot("s", "R", 1, room)
        store.sync_snapshot("s", "R", 2, [*room, Fact("MUG", "IsOn", "TABLE")])
        assert f"{odd[0]}>{odd[1]}" in api.holders(db)
    engine = make_engine(empty_url)
    migrate.downgrade(engine, "base")
    with engine.connect() as conn:
        assert inspect(conn).get_view_names() == []
    engine.dispose()


# -- Databases from before the belief revisions were squashed (0002 + 0003 -> 0003) ---------

LEGACY_DUMP = Path(__file__).parent / "data" / "beliefs_0005.sql"
TICKS = [t * 10 for t in range(9)]


def _timelines(db: toaster.Database) -> dict[str, Any]:
    """Every holder's history, events and as-of beliefs at each tick (write times left out)."""
    from toaster.beliefs import api

    return {holder: (
        sorted(row._replace(recorded_ns=0) for row in q.history(db, holder)),
        sorted(row[1:17] for row in q.events(db, holder)),  # no id, no recorded_ns
        [sorted(row._replace(recorded_ns=0) for row in q.beliefs_at(db, holder, t))
         for t in TICKS],
    ) for holder in ["R", *api.holders(db)]}


def _schema_matches(engine: Any) -> None:
    with engine.connect() as conn:
        assert compare_metadata(MigrationContext.configure(conn), metadata) == []
        assert "belief_rules" not in inspect(conn).get_table_names()


@pytest.mark.slow
def test_a_database_written_before_the_squash_upgrades(tmp_path: Path) -> None:
    """A SQLite database written at 0005 by the code of the unsquashed 0002/0003 (data dump):
    it upgrades to the declared schema, reads the same, and the rules go on: the robot's
    timeline and the holders are those of a database made now, every holder's timeline stays
    well formed. (The holders' first half differs from a database made now: 0009 changed what
    a move shows, so their continuations are not compared row for row.)"""
    old = tmp_path / "old.db"
    raw = sqlite3.connect(old)
    raw.executescript(LEGACY_DUMP.read_text(encoding="utf-8"))
    raw.close()
    engine = make_engine(f"sqlite:///{old}")
    assert migrate.current_revision(engine) == "0005"
    with engine.connect() as conn:
        before = conn.exec_driver_sql("SELECT * FROM fact_history ORDER BY fact_id, key_id").all()
    migrate.upgrade(engine)
    _schema_matches(engine)
    with engine.connect() as conn:
        assert conn.exec_driver_sql(
            "SELECT * FROM fact_history ORDER BY fact_id, key_id").all() == before
        views: dict[str, str] = dict(conn.exec_driver_sql(
            "SELECT name, sql FROM sqlite_master WHERE type = 'view'").all())
        # Nested holders moved out of entities and agents into holders (revision 0008).
        nested = conn.exec_driver_sql("SELECT id, depth FROM holders WHERE depth >= 2").all()
        assert nested and all(">" in h for h, _ in nested)
        assert conn.exec_driver_sql(
            "SELECT count(*) FROM entities WHERE kind = 'belief' OR id LIKE '%>%'").scalar() == 0
        assert conn.exec_driver_sql("SELECT count(*) FROM agents WHERE id LIKE '%>%'").scalar() == 0
    engine.dispose()
    fresh = tmp_path / "fresh.db"
    with toaster.connect(f"sqlite:///{fresh}") as db:
        beliefs_story.first_half(db)
        with db.transaction() as conn:
            assert dict(conn.exec_driver_sql(
                "SELECT name, sql FROM sqlite_master WHERE type = 'view'").all()) == views
        expected = _timelines(db)
        beliefs_story.second_half(db)
        expected_after = _timelines(db)
    with toaster.connect(f"sqlite:///{old}") as db:
        got = _timelines(db)
        assert got["R"] == expected["R"] and got.keys() == expected.keys()
        beliefs_story.second_half(db)
        got = _timelines(db)
        assert got["R"] == expected_after["R"] and got.keys() == expected_after.keys()
        for holder in got:
            _assert_well_formed(q.history(db, holder))


def _assert_well_formed(rows: list[Any]) -> None:
    """Per key: intervals in order, none overlapping, at most the last one open."""
    by_key: dict[tuple[Any, ...], list[Any]] = {}
    for row in rows:
        key = (row.subject_id, row.subject_owner_id, row.property, row.sub_property,
               row.target_id, row.target_owner_id)
        by_key.setdefault(key, []).append(row)
    for key, intervals in by_key.items():
        intervals.sort(key=lambda r: r.valid_from_ns)
        for a, b in itertools.pairwise(intervals):
            assert a.valid_to_ns is not None and a.valid_to_ns <= b.valid_from_ns, key


@pytest.mark.slow
def test_a_database_at_the_previous_head_upgrades(empty_url: str, tmp_path: Path) -> None:
    """Both backends: a database as 0005 left it (defaults stored as settings rows, the
    ``belief_rules`` table of the unsquashed 0002) upgrades and the rules go on unchanged."""
    with toaster.connect(empty_url) as db:
        beliefs_story.first_half(db)
        expected = _timelines(db)
    engine = make_engine(empty_url)
    migrate.downgrade(engine, "0005")
    with engine.begin() as conn:
        conn.exec_driver_sql("CREATE TABLE belief_rules (backend TEXT NOT NULL, step TEXT NOT "
                             "NULL, sql_text TEXT NOT NULL, CONSTRAINT pk_belief_rules "
                             "PRIMARY KEY (backend, step))")
        conn.exec_driver_sql("INSERT INTO belief_rules VALUES ('sqlite', '99_clear', "
                             "'DELETE FROM belief_changed')")
    migrate.upgrade(engine)
    _schema_matches(engine)
    engine.dispose()
    with toaster.connect(f"sqlite:///{tmp_path / 'fresh.db'}") as fresh:
        beliefs_story.first_half(fresh)
        beliefs_story.second_half(fresh)
        expected_after = _timelines(fresh)
    with toaster.connect(empty_url) as db:
        assert _timelines(db) == expected
        beliefs_story.second_half(db)
        assert _timelines(db) == expected_after  # the same as SQLite's, written now


#: The sha256 of every released frozen trigger file. A database migrated through a revision
#: holds exactly its file's triggers, so a released file never changes: a rule change is a new
#: revision with a file of its own, pinned here when it is released.
RELEASED_FROZEN = {
    "0007_triggers.json": "e63fc43ff4c21f67058f8094f57a937e444b715e3dabccffe3b4c67e28cff5b0",
    "0008_triggers.json": "3aa9ba3afc530fd351615c3d1424f28b43edb3dadef5c6d79eb601a3388932dd",
    "0009_triggers.json": "2ea049aa6b38310dcadc010e6ddfdec9fb4427a8a54f17b35f9f777a8d4fc503",
    "0010_triggers.json": "4d521db3badf27fbf94e2431a8ee17524c4fbb02929e3eac9e2539ad47aa2e61",
    "0011_triggers.json": "1e3b6c26f967f398e3f99bd450c0ff1bbb789477dcd0b4020671cea002aadf64",
    "0012_triggers.json": "22e6d469450a7363c40017a8f784cde45bda3050518c5213b7c9900952640885",
    "0013_triggers.json": "547f86302e3d674714215160c0860f974d44e24dbe1bd2ded68a79856a4007b5",
    "0014_triggers.json": "a7a9a5db02fb811c6b6286df5d1a33268b2de2a0e495f5e2033620ed543a825c",
    "0015_triggers.json": "4c713be8ba342c5d22b2af7c9948e6d9e5287ddf053170e60cf8d17bad2cf436",
}


def test_released_frozen_triggers_never_change() -> None:
    frozen = Path(toaster.__file__).parent / "migrations" / "frozen"
    found = {path.name: hashlib.sha256(path.read_bytes()).hexdigest()
             for path in frozen.glob("*.json")}
    changed = sorted(name for name in RELEASED_FROZEN if found.get(name) != RELEASED_FROZEN[name])
    assert not changed, f"released frozen triggers changed: {changed} (write a new revision)"
    assert sorted(found) == sorted(RELEASED_FROZEN), "pin a new revision's frozen file here"
