"""Revision 0017: the per-agent views with the original's columns and their write triggers.

Its frozen file is what the package renders; ``toaster db upgrade`` from 0016 on a database
with agents keeps the data and makes every agent's views writable (agents without views stay
so, and ``toaster db views`` makes theirs writable too); ``downgrade 0016`` gives back 0016's
views without triggers.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner
from sqlalchemy import inspect

import toaster
import toaster.queries as q
from toaster.cli import cli
from toaster.db import migrate, views
from toaster.db.engine import make_engine

FROZEN = Path(toaster.__file__).parent / "migrations" / "frozen" / "0017_agent_views.json"
BACKENDS = ("sqlite", "postgresql")
AGENTS = ("ROBOT", 'Bob\'s "twin"', "X" * 70)  # a quoted id, a shortened name


@pytest.mark.parametrize("backend", BACKENDS)
def test_the_revision_froze_what_the_package_renders(backend: str) -> None:
    """A change of the views or of their triggers needs a revision of its own."""
    frozen = json.loads(FROZEN.read_text(encoding="utf-8"))[backend]
    assert frozen["agent"] == views.agent_ddl(backend)
    assert {k: frozen[k] for k in ("create", "drop")} == views.schema_ddl(backend)


def _objects(engine: Any) -> dict[str, Any]:
    """The per-agent views (name -> columns) and the write triggers and functions."""
    with engine.connect() as conn:
        inspector = inspect(conn)
        found: dict[str, Any] = {
            name: [c["name"] for c in inspector.get_columns(name)]
            for name in inspector.get_view_names()
            if name.startswith(views.PREFIXES)
        }
        if engine.dialect.name == "sqlite":
            triggers = conn.exec_driver_sql(
                "SELECT name, tbl_name FROM sqlite_master WHERE type = 'trigger' "
                "AND name LIKE 'toaster_agent_%' ORDER BY name"
            ).all()
            functions: list[Any] = []
        else:
            triggers = conn.exec_driver_sql(
                "SELECT t.tgname, c.relname FROM pg_trigger t JOIN pg_class c ON c.oid = "
                "t.tgrelid WHERE c.relnamespace = current_schema()::regnamespace AND c.relkind "
                "= 'v' ORDER BY 2"
            ).all()
            functions = conn.exec_driver_sql(
                "SELECT proname FROM pg_proc WHERE pronamespace = current_schema()::regnamespace "
                "AND proname IN ('toaster_fact_table_write', 'toaster_events_table_write') ORDER BY 1"
            ).all()
    return {"views": found, "triggers": [tuple(t) for t in triggers], "functions": functions}


def _data(db: toaster.Database) -> list[Any]:
    return [
        q.execute(db, f"SELECT * FROM {table} ORDER BY 1").rows
        for table in ("facts", "fact_keys", "events", "agents", "entities")
    ]


def _insert(db: toaster.Database, t: int) -> None:
    q.execute(
        db,
        'INSERT INTO "fact_table_ROBOT" (subject_id, predicate, target_id, start) VALUES '
        f"('MUG', 'IsOn', 'TABLE', {t})",
        write=True,
    )


@pytest.mark.slow
def test_upgrade_from_0016_keeps_the_data_and_adds_the_triggers(empty_url: str) -> None:
    """Both backends, through ``toaster db upgrade`` / ``downgrade``."""
    with toaster.connect(empty_url) as db:
        store = db.store()
        store.add_entity(AGENTS[0], "robot", is_self=True, t_ns=0)
        for agent in AGENTS[1:]:
            store.add_entity(agent, "human", t_ns=0)
        store.add_entities([("CROWD_1", "human", "CROWD_1", "", True)], t_ns=0, views=False)
        store.add_entity("MUG", "object", t_ns=0)
        _insert(db, 1_000_000_000)
        head = _objects(db.engine)
        data = _data(db)
    assert len(head["views"]) == 9 and "CROWD_1" not in str(head["views"])
    assert "predicate" in head["views"]["fact_table_ROBOT"]
    sqlite = empty_url.startswith("sqlite")
    assert (len(head["triggers"]), len(head["functions"])) == ((12, 0) if sqlite else (6, 2))
    runner = CliRunner()
    result = runner.invoke(cli, ["--db", empty_url, "db", "downgrade", "0016"])
    assert result.exit_code == 0, result.output
    engine = make_engine(empty_url)
    old = _objects(engine)
    with pytest.raises(Exception, match="cannot (modify|insert into view)"), engine.begin() as conn:
        conn.exec_driver_sql(  # the finding, as 0016 has it
            'INSERT INTO "fact_table_ROBOT" (subject_id, property, valid_from_ns) '
            "VALUES ('MUG', 'IsOn', 3)"
        )
    engine.dispose()
    assert old["views"].keys() == head["views"].keys()
    assert "predicate" not in old["views"]["fact_table_ROBOT"]
    assert old["triggers"] == [] and old["functions"] == []
    result = runner.invoke(cli, ["--db", empty_url, "db", "upgrade"])
    assert result.exit_code == 0, result.output
    assert f"database at revision {migrate.head_revision()} (was 0016)" in result.output
    with toaster.connect(empty_url) as db:
        assert _objects(db.engine) == head
        assert _data(db) == data
        _insert(db, 2_000_000_000)  # a value that did not change: nothing new
        assert _data(db) == data
        q.execute(db, 'DELETE FROM "fact_table_ROBOT"', write=True)
        assert [r.property for r in q.memory(db, "ROBOT")] == ["IsOn"]
        assert migrate.current_revision(db.engine) == migrate.head_revision()
    # An agent registered without views gets them, triggers included, from `toaster db views`.
    result = runner.invoke(cli, ["--db", empty_url, "db", "views", "CROWD_1"])
    assert result.exit_code == 0, result.output
    with toaster.connect(empty_url) as db:
        made = _objects(db.engine)
        assert len(made["triggers"]) == len(head["triggers"]) * 4 // 3
        q.execute(
            db,
            'INSERT INTO "events_table_CROWD_1" (subject_id, predicate, time) '
            "VALUES ('CROWD_1', 'Waves', 5)",
            write=True,
        )
        assert [e.kind for e in q.events(db, "CROWD_1")] == ["event"]
