"""The original's scripts write the per-agent views (issue 27, revision 0017).

A plain client (Python's sqlite3, psycopg; the sqlite3 and psql programs) writes
``fact_table_ROBOT`` and ``events_table_ROBOT`` with the original's column names; the same
story written through ``fact_inbox`` into a second database must give the same current facts,
memory, events and beliefs for every holder. Bad rows fail with one line and write nothing; a
read-only role cannot write through the views.
"""

from __future__ import annotations

import os
import shutil
import subprocess
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any
from urllib.parse import unquote

import psycopg
import pytest

import toaster
import toaster.queries as q
from tests.conftest import pg_schema
from toaster.beliefs import api
from toaster.db.invariants import violations
from toaster.db.readonly import READER_ROLE
from toaster.errors import ReadOnlyError, ToasterError
from toaster.timeutil import now_ns

S = 1_000_000_000
HUMANS = ("SALLY", "ANNE")
#: The original's columns, in its order (database_manager's fact tables).
ORIGINAL = (
    "subject_id, predicate, propertyType, target_id, valueType, valueString, valueDouble, "
    'observability, confidence, start, "end"'
)
#: The story: ("insert", subject, property, target, value text, number, confidence, t) as the
#: original's row; ("end", subject, property, target, t): the fact ends at t; ("event", subject,
#: property, target, t): a point event.
STORY: list[tuple[Any, ...]] = [
    *[("insert", who, "IsInRoom", "KITCHEN", "true", None, 1.0, 1 * S) for who in HUMANS],
    ("insert", "BASKET", "IsInRoom", "KITCHEN", "true", None, 1.0, 1 * S),
    ("insert", "BOX", "IsInRoom", "KITCHEN", "true", None, 1.0, 1 * S),
    ("insert", "MARBLE", "IsIn", "BASKET", "true", None, 1.0, 1 * S),
    ("insert", "MARBLE", "Distance", "SALLY", "near", 0.5, 0.9, 1 * S),
    ("end", "SALLY", "IsInRoom", "KITCHEN", 2 * S),  # Sally leaves
    ("insert", "SALLY", "IsInRoom", "HALL", "true", None, 1.0, 2 * S),
    ("end", "MARBLE", "IsIn", "BASKET", 3 * S),  # Anne moves the marble behind her back
    ("insert", "MARBLE", "IsIn", "BOX", "true", None, 1.0, 3 * S),
    ("insert", "MARBLE", "Distance", "SALLY", "near", 0.7, 0.8, 3 * S),  # a number refresh
    ("event", "ANNE", "Waves", "SALLY", 4 * S),
    ("insert", "BOX", "IsClosed", "", "true", None, 1.0, 5 * S),
]


def _plain(url: str) -> tuple[Callable[..., Any], Callable[[], None]]:
    """A plain client of ``url`` (no toaster code): ``run(sql, params)`` and ``close()``;
    each statement commits."""
    if url.startswith("sqlite"):
        import sqlite3

        conn = sqlite3.connect(url.removeprefix("sqlite:///"), isolation_level=None)
        return (lambda sql, p=(): conn.execute(sql, p)), conn.close
    pg = psycopg.connect(url.replace("postgresql+psycopg", "postgresql"), autocommit=True)
    return (lambda sql, p=(): pg.execute(sql.replace("?", "%s"), p)), pg.close


def _setup(db: toaster.Database) -> None:
    st = db.store()
    st.add_entity("ROBOT", "robot", is_self=True, t_ns=0)
    for human in HUMANS:
        st.add_entity(human, "human", t_ns=0)
    for thing in ("KITCHEN", "HALL", "BASKET", "BOX", "MARBLE"):
        st.add_entity(thing, "object", t_ns=0)


def _through_views(run: Callable[..., Any]) -> None:
    """The story as the original's scripts write it: rows of the agent's tables."""
    for step in STORY:
        if step[0] == "insert":
            _, subject, prop, target, text, num, conf, t = step
            run(
                f'INSERT INTO "fact_table_ROBOT" ({ORIGINAL}) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)',
                (
                    subject,
                    prop,
                    "",
                    target,
                    int(num is not None),
                    text,
                    num or 0.0,
                    1.0,
                    conf,
                    t,
                    0,
                ),
            )
        elif step[0] == "end":
            _, subject, prop, target, t = step
            run(
                'UPDATE "fact_table_ROBOT" SET "end" = ? WHERE subject_id = ? AND predicate = ? '
                "AND target_id = ?",
                (t, subject, prop, target),
            )
        else:
            _, subject, prop, target, t = step
            run(
                'INSERT INTO "events_table_ROBOT" (subject_id, predicate, target_id, time) '
                "VALUES (?, ?, ?, ?)",
                (subject, prop, target, t),
            )


def _through_inbox(run: Callable[..., Any]) -> None:
    """The same story as fact_inbox rows."""
    sql = (
        "INSERT INTO fact_inbox (action, agent_id, subject_id, property, target_id, value_text, "
        "value_num, confidence, t_ns) VALUES (?, 'ROBOT', ?, ?, ?, ?, ?, ?, ?)"
    )
    for step in STORY:
        if step[0] == "insert":
            _, subject, prop, target, text, num, conf, t = step
            run(sql, ("assert", subject, prop, target or None, text, num, conf, t))
        elif step[0] == "end":
            _, subject, prop, target, t = step
            run(sql, ("retract", subject, prop, target, "true", None, 1.0, t))
        else:
            _, subject, prop, target, t = step
            run(sql, ("event", subject, prop, target, "true", None, 1.0, t))


def _state(db: toaster.Database) -> dict[str, Any]:
    """Every holder's intervals (current and memory) and events, write times and ids left out."""
    return {
        holder: (
            sorted(r._replace(recorded_ns=0) for r in q.history(db, holder)),
            sorted(tuple(e)[1:17] for e in q.events(db, holder)),
        )
        for holder in ["ROBOT", *api.holders(db)]
    }


@contextmanager
def _second(db_url: str, tmp_path: Path) -> Iterator[str]:
    """A second database at head on the backend of ``db_url``."""
    if db_url.startswith("sqlite"):
        path = tmp_path / "second.db"
        shutil.copy(db_url.removeprefix("sqlite:///"), path)
        yield f"sqlite:///{path}"
        return
    with pg_schema(migrated=True) as url:
        yield url


@pytest.mark.slow
def test_the_original_columns_write_as_fact_inbox_does(
    db: toaster.Database, db_url: str, tmp_path: Path
) -> None:
    """INSERT, UPDATE "end" and DELETE on fact_table_ROBOT and INSERT on events_table_ROBOT
    by a plain client give the same facts, memory, events and beliefs as fact_inbox rows."""
    with _second(db_url, tmp_path) as inbox_url, toaster.connect(inbox_url) as other:
        _setup(db)
        _setup(other)
        for url, write in ((db_url, _through_views), (inbox_url, _through_inbox)):
            run, close = _plain(url)
            try:
                write(run)
            finally:
                close()
        views = _state(db)
        assert views == _state(other)
        assert len(views) > 3 and all(views[h][0] for h in HUMANS)  # beliefs were kept
        sally = {(r.subject_id, r.property): r.target_id for r in q.current_facts(db, "SALLY")}
        assert sally[("MARBLE", "IsIn")] == "BASKET"  # her false belief
        rows = q.execute(
            db,
            "SELECT subject_id, predicate, propertytype, target_id, valuetype, valuestring, "
            'valuedouble, start, "end" FROM "fact_table_ROBOT" WHERE predicate = \'Distance\'',
        ).rows
        assert rows == [("MARBLE", "Distance", "", "SALLY", 1, "near", 0.7, 1 * S, 0)]
        events = q.execute(
            db, "SELECT predicate, time FROM \"events_table_ROBOT\" WHERE subject_id = 'MARBLE'"
        ).rows
        assert ("!IsIn", 3 * S) in events and ("IsIn", 3 * S) in events
        # DELETE ends a fact now, as Store.retract_facts without a time does.
        run, close = _plain(db_url)
        before = now_ns()
        try:
            run(
                'DELETE FROM "fact_table_ROBOT" WHERE subject_id = ? AND predicate = ?',
                ("MARBLE", "IsIn"),
            )
        finally:
            close()
        (ended,) = [
            r for r in q.memory(db, "ROBOT") if r.property == "IsIn" and r.target_id == "BOX"
        ]
        assert ended.valid_to_ns is not None
        assert before - 5 * S < ended.valid_to_ns < now_ns() + 5 * S
        other.store().retract_facts(
            "ROBOT", "IsIn", "MARBLE", "BOX", t_ns=ended.valid_to_ns, source="sql"
        )
        assert _state(db) == _state(other)
        with db.transaction() as conn:
            assert violations(conn) == []


#: Bad rows and the message each gets (the part both backends share).
BAD = [
    ("INSERT INTO \"fact_table_ROBOT\" (predicate, start) VALUES ('IsOn', 1)", "give subject_id"),
    (
        "INSERT INTO \"fact_table_ROBOT\" (subject_id, start) VALUES ('MUG', 1)",
        "give predicate (or property)",
    ),
    (
        "INSERT INTO \"fact_table_ROBOT\" (subject_id, predicate) VALUES ('MUG', 'IsOn')",
        "give start (or valid_from_ns)",
    ),
    (
        "INSERT INTO \"fact_table_ROBOT\" (subject_id, predicate, start) VALUES ('MUG', 'IsOn', "
        "'soon')",
        ("start must be an integer", 'invalid input syntax for type bigint: "soon"'),
    ),
    (
        'INSERT INTO "fact_table_ROBOT" (subject_id, predicate, start, confidence) VALUES '
        "('MUG', 'IsOn', 1, 'high')",
        ("confidence must be a number", 'invalid input syntax for type double precision: "high"'),
    ),
    (
        'INSERT INTO "fact_table_ROBOT" (subject_id, predicate, start, confidence) VALUES '
        "('MUG', 'IsOn', 1, 7)",
        "must be between 0 and 1",
    ),
    (
        'INSERT INTO "fact_table_ROBOT" (subject_id, predicate, property, start) VALUES '
        "('MUG', 'IsOn', 'IsIn', 1)",
        "predicate and property are one column under two names",
    ),
    (
        'INSERT INTO "fact_table_ROBOT" (subject_id, predicate, start, "end") VALUES '
        "('MUG', 'IsOn', 1, 2)",
        "end must be 0 or NULL",
    ),
    (
        'INSERT INTO "fact_table_ROBOT" (subject_id, predicate, start, valueType) VALUES '
        "('MUG', 'IsOn', 1, 2)",
        "valueType must be 0",
    ),
    (
        'INSERT INTO "fact_table_ROBOT" (agent_id, subject_id, predicate, start) VALUES '
        "('SALLY', 'MUG', 'IsOn', 1)",
        "agent_id names another agent",
    ),
    ("UPDATE \"fact_table_ROBOT\" SET valueString = 'false'", "UPDATE only ends a fact"),
    ('UPDATE "fact_table_ROBOT" SET "end" = 0', "UPDATE only ends a fact"),
    (
        'INSERT INTO "events_table_ROBOT" (subject_id, predicate, time, kind) VALUES '
        "('MUG', 'IsOn', 1, 'ended')",
        "kind must be NULL or 'event'",
    ),
    (
        "INSERT INTO \"events_table_ROBOT\" (subject_id, predicate) VALUES ('MUG', 'IsOn')",
        "give time",
    ),
    ('DELETE FROM "events_table_ROBOT"', ("cannot modify", "cannot delete from view")),
    (
        "INSERT INTO \"memory_table_ROBOT\" (subject_id) VALUES ('MUG')",
        ("cannot modify", "cannot insert into view"),
    ),
]


def _dump(db: toaster.Database) -> list[Any]:
    with db.transaction() as conn:
        return [
            conn.exec_driver_sql(f"SELECT * FROM {table} ORDER BY 1").all()
            for table in ("facts", "fact_keys", "events", "entities", "belief_follow")
        ]


@pytest.mark.slow
def test_bad_rows_get_one_line_and_write_nothing(db: toaster.Database) -> None:
    """Each bad row fails with one line naming what to fix; nothing is written."""
    _setup(db)
    q.execute(
        db,
        f'INSERT INTO "fact_table_ROBOT" ({ORIGINAL}) VALUES '
        "('MUG', 'IsOn', '', 'TABLE', 0, 'true', 0, 1, 1, 1, 0)",
        write=True,
    )
    before = _dump(db)
    for sql, expected in BAD:
        wanted = expected if isinstance(expected, str) else expected[db.dialect_name != "sqlite"]
        with pytest.raises(ToasterError) as caught:
            q.execute(db, sql, write=True)
        message = str(caught.value)
        assert wanted in message and "\n" not in message, (sql, message)
        assert _dump(db) == before, sql


@pytest.mark.postgresql
@pytest.mark.backend("postgresql")
def test_the_reader_role_cannot_write_through_the_views(db: toaster.Database) -> None:
    """PostgreSQL: read-only SQL is refused, and the reader role itself holds no right to
    write the views (their triggers never run for it)."""
    _setup(db)
    insert = (
        "INSERT INTO \"fact_table_ROBOT\" (subject_id, predicate, start) VALUES ('MUG', 'IsOn', 1)"
    )
    with pytest.raises(ReadOnlyError, match="--write"):
        q.execute(db, insert)
    q.execute(db, 'SELECT count(*) FROM "fact_table_ROBOT"')  # the role exists, granted
    with db.transaction() as conn:
        conn.exec_driver_sql(f"SET LOCAL ROLE {READER_ROLE}")
        for sql in (
            insert,
            'DELETE FROM "fact_table_ROBOT"',
            'UPDATE "fact_table_ROBOT" SET "end" = 2',
        ):
            conn.exec_driver_sql("SAVEPOINT s")
            with pytest.raises(Exception, match="permission denied for view"):
                conn.exec_driver_sql(sql)
            conn.exec_driver_sql("ROLLBACK TO SAVEPOINT s")
    assert q.current_facts(db, "ROBOT") == []


def _program(name: str) -> str:
    found = shutil.which(name)
    if found is None:
        if os.environ.get("CI"):
            pytest.fail(f"the {name} program is missing")
        pytest.skip(f"the {name} program is not installed")
    return found


def _documented_script() -> str:
    """The SQL example of docs/store.md's section on the original's scripts."""
    text = (Path(__file__).parents[2] / "docs" / "store.md").read_text(encoding="utf-8")
    section = text.split("## Writing from SQL like the original's scripts", 1)[1]
    return section.split("```sql\n", 1)[1].split("```", 1)[0]


@pytest.mark.slow
def test_the_documented_script_runs_in_the_command_line_client(
    db: toaster.Database, db_url: str
) -> None:
    """docs/store.md's example, run by the sqlite3 or psql program as a script would."""
    _setup(db)
    env = dict(os.environ)
    if db.dialect_name == "sqlite":
        command = [_program("sqlite3"), "-bail", db_url.removeprefix("sqlite:///")]
    else:
        base, _, options = db_url.replace("postgresql+psycopg", "postgresql").partition("?")
        command = [_program("psql"), "-v", "ON_ERROR_STOP=1", "-q", base]
        env["PGOPTIONS"] = unquote(options.removeprefix("options="))
    done = subprocess.run(
        command,
        input=_documented_script(),
        capture_output=True,
        text=True,
        timeout=120,
        check=False,
        env=env,
    )
    assert done.returncode == 0, done.stderr
    (row,) = q.memory(db, "ROBOT")
    assert (row.subject_id, row.property, row.target_id, row.property_type) == (
        "MARBLE",
        "IsIn",
        "BASKET",
        "position",
    )
    assert (row.valid_from_ns, row.valid_to_ns) == (1 * S, 3 * S)
    assert [(e.kind, e.stamp_ns) for e in q.events(db, "ROBOT")] == [
        ("appeared", 1 * S),
        ("ended", 3 * S),
        ("event", 4 * S),
    ]
