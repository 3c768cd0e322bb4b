"""load_save's database side (toaster.ros1.dbcalls, no ROS): SQLite's backup API on SQLite,
a one-line refusal on PostgreSQL."""

from __future__ import annotations

import pytest

import toaster
from toaster.errors import InvalidInputError
from toaster.ros1 import dbcalls


def test_save_on_sqlite_refusal_on_postgresql(db_url: str, tmp_path) -> None:
    with toaster.connect(db_url) as db:
        check(db, tmp_path / "copy.db")


def check(db: toaster.Database, target) -> None:
    if db.dialect_name == "postgresql":
        with pytest.raises(InvalidInputError, match="PostgreSQL.*pg_dump"):
            dbcalls.load_save(db, str(target), True)
        assert not target.exists()
        return
    db.store().add_entity("cup", "object")
    dbcalls.load_save(db, str(target), True)
    with toaster.connect(f"sqlite:///{target}") as copy:
        assert [e.id for e in toaster.queries.entities(copy, "cup")] == ["cup"]
    with pytest.raises(InvalidInputError, match="another file than the live one"):
        dbcalls.load_save(db, db.url.removeprefix("sqlite:///"), True)
