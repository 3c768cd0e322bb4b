"""Migrations: the schema they build equals schema.py; up, down, up again on both backends."""

from __future__ import annotations

import pytest
from alembic.autogenerate import compare_metadata
from alembic.runtime.migration import MigrationContext
from sqlalchemy import inspect

import toaster
from toaster.db import migrate
from toaster.db.engine import make_engine
from toaster.db.schema import metadata
from toaster.errors import SchemaOutdatedError


def test_migrations_match_the_declared_schema(empty_url: str) -> None:
    """Upgrading an empty database yields exactly the tables and indexes of schema.py."""
    engine = make_engine(empty_url)
    migrate.upgrade(engine)
    with engine.connect() as conn:
        diff = compare_metadata(MigrationContext.configure(conn), metadata)
    engine.dispose()
    assert diff == []


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


def test_empty_database_is_created_on_first_use(empty_url: str) -> None:
    """connect() on an empty database migrates it to head."""
    with toaster.connect(empty_url) as db:
        assert migrate.current_revision(db.engine) == migrate.head_revision()


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
