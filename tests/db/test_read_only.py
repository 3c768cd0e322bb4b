"""``execute`` without ``write`` is really read-only (docs/execute.md).

Every hostile statement must raise a one-line ToasterError and leave behind: the same rows in
every table, no new file, a living second session, the connecting role, no setting, lock or
large object, and a connection that still works.
"""

from __future__ import annotations

import json
import re
import shutil
import sqlite3
import subprocess
import sys
import time
import uuid
from collections.abc import Iterator
from contextlib import closing
from pathlib import Path
from typing import Any

import psycopg
import pytest
from click.testing import CliRunner
from sqlalchemy import make_url

import toaster
from tests.conftest import BACKENDS, PG_URL, pg_schema, require_postgres
from toaster import queries as q
from toaster.cli import cli
from toaster.db import migrate, open_database
from toaster.db.engine import make_engine
from toaster.db.readonly import READER_ROLE, check_statement, tokenize
from toaster.db.readonly import postgresql as readonly_pg
from toaster.db.readonly import sqlite as readonly_sqlite
from toaster.errors import ReadOnlyError, ToasterError

_ENDLESS = "WITH RECURSIVE c(x) AS (SELECT 1 UNION ALL SELECT x + 1 FROM c) "
BOUNDS = {"timeout_s": 2.0, "max_bytes": 16 * 2**20}
#: (id, SQL) or (id, (SQLite SQL, PostgreSQL SQL)); {tmp} is a scratch folder, {pid} the
#: process id of a second session (PostgreSQL; 0 on SQLite). They run with BOUNDS.
HOSTILE: list[tuple[str, str | tuple[str, str]]] = [
    # several statements, transaction control
    ("commit-drop", "COMMIT; DROP TABLE settings"),
    ("rollback-update", "ROLLBACK; UPDATE settings SET value_json = 'x'"),
    ("read-only-off-delete", "SET transaction_read_only = off; DELETE FROM settings"),
    ("begin-read-write", "BEGIN READ WRITE; DELETE FROM settings; COMMIT"),
    ("select-then-drop", "SELECT 1; DROP TABLE settings"),
    ("semicolon-in-comment", "SELECT 1 /* x */; DELETE FROM settings -- ;"),
    (
        "carriage-return-comment",
        (
            "SELECT 1 -- x\n, load_extension('x')",
            "SELECT 1 -- x\r, set_config('role', 'postgres', true)",
        ),
    ),
    ("e-string-escape", "SELECT E'\\''; DELETE FROM settings; SELECT 1"),
    ("backslash-quote", "SELECT '\\'; DELETE FROM settings; --'"),
    ("dollar-quote", "SELECT $$ x $$; DELETE FROM settings"),
    ("nested-comment", "SELECT 1 /* /* */ ; DELETE FROM settings; /* */"),
    ("commit", "COMMIT"),
    ("rollback", "ROLLBACK"),
    ("begin", "BEGIN"),
    ("end", "END"),
    ("savepoint", "SAVEPOINT s"),
    ("release", "RELEASE SAVEPOINT s"),
    ("prepare-transaction", "PREPARE TRANSACTION 'toaster_pwned'"),
    ("read-only-off", "SET transaction_read_only = off"),
    ("session-read-write", "SET SESSION CHARACTERISTICS AS TRANSACTION READ WRITE"),
    # settings and roles
    ("set-role", "SET ROLE postgres"),
    ("reset-role", "RESET ROLE"),
    ("session-authorization", "SET SESSION AUTHORIZATION postgres"),
    ("set-work-mem", "SET work_mem = '1GB'"),
    ("set-config-role", "SELECT set_config('role', 'postgres', true)"),
    ("set-config-quoted", "SELECT pg_catalog.\"set_config\"('role', 'postgres', false)"),
    ("set-config-comment", "SELECT set_config/**/('statement_timeout', '0', false)"),
    ("set-config-unicode", "SELECT U&\"\\0073et_config\"('role', 'postgres', true)"),
    (
        "query-to-xml",
        "SELECT query_to_xml('SELECT set_config(''role'', ''postgres'', true)', true, false, '')",
    ),
    ("ts-stat", "SELECT * FROM ts_stat('SELECT pg_advisory_lock(1)::text::tsvector')"),
    # SQL given as text to a function (where the statement check cannot see it)
    (
        "query-to-xml-terminate",
        "SELECT query_to_xml('SELECT pg_terminate_backend({pid})', true, false, '')",
    ),
    (
        "query-to-xml-schema",
        "SELECT query_to_xml_and_xmlschema('SELECT pg_advisory_lock(1)', true, false, '')",
    ),
    ("cursor-to-xml", "SELECT cursor_to_xml('c'::refcursor, 1, true, false, '')"),
    (
        "ts-stat-terminate",
        "SELECT * FROM ts_stat('SELECT pg_terminate_backend({pid})::text::tsvector')",
    ),
    (
        "ts-rewrite-query",
        "SELECT ts_rewrite('a'::tsquery, 'SELECT ''a''::tsquery, "
        "pg_terminate_backend({pid})::text::tsquery')::text",
    ),
    (
        "crosstab",
        "SELECT * FROM crosstab('SELECT pg_terminate_backend({pid})::text, "
        "''a'', ''b''') AS t(a text, b text)",
    ),
    (
        "connectby",
        "SELECT * FROM connectby('settings', 'key', 'scope', 'x', 0) AS t(a text, b text, c int)",
    ),
    # toaster's own functions: the read-only wrapper (pg_temp), the triggers' functions
    (
        "wrapper-terminate",
        "SELECT * FROM pg_temp.toaster_readonly_run('SELECT "
        "pg_terminate_backend({pid})::text', 100, 1000000) AS t(a text)",
    ),
    (
        "wrapper-quoted",
        """SELECT * FROM "pg_temp"."toaster_readonly_run"('SELECT """
        """pg_advisory_lock(1)::text', 100, 1000000) AS t(a text)""",
    ),
    (
        "wrapper-set-role",
        "SELECT * FROM pg_temp . toaster_readonly_run /* */ ('SELECT "
        "set_config(''role'', ''postgres'', false)', 1, 1000) AS t(a text)",
    ),
    (
        "wrapper-numbered",
        "SELECT * FROM pg_temp_1.toaster_readonly_run('SELECT 1', 1, 1000) AS t(a int)",
    ),
    ("trigger-function", "SELECT toaster_guard()"),
    ("trigger-function-qualified", "SELECT public.toaster_belief_run()"),
    ("alter-system", "ALTER SYSTEM SET work_mem = '1GB'"),
    ("discard", "DISCARD ALL"),
    # files, programs, large objects
    ("copy-to-program", "COPY (SELECT 1) TO PROGRAM 'touch {tmp}/pwned'"),
    ("copy-from-program", "COPY settings FROM PROGRAM 'touch {tmp}/pwned'"),
    ("copy-to-file", "COPY settings TO '{tmp}/settings.csv'"),
    ("copy-from-file", "COPY settings FROM '/etc/hostname'"),
    ("lo-import", "SELECT lo_import('/etc/hostname')"),
    ("lo-export", "SELECT lo_export(lo_from_bytea(0, 'x'), '{tmp}/lo.bin')"),
    ("read-file", "SELECT pg_read_file('/etc/hostname')"),
    ("ls-dir", "SELECT * FROM pg_ls_dir('.')"),
    ("dblink", "SELECT dblink_exec('dbname=test', 'DROP TABLE settings')"),
    ("create-extension", "CREATE EXTENSION IF NOT EXISTS dblink"),
    # other sessions and the server
    ("terminate", "SELECT pg_terminate_backend({pid})"),
    ("cancel", "SELECT pg_cancel_backend({pid})"),
    ("terminate-from", "SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE pid = {pid}"),
    ("reload-conf", "SELECT pg_reload_conf()"),
    ("advisory-lock", "SELECT pg_advisory_lock(4242)"),
    ("advisory-try", "SELECT pg_try_advisory_lock(4242)::text"),
    ("notify", "NOTIFY toaster_channel, 'x'"),
    ("pg-notify", "SELECT pg_notify('toaster_channel', 'x')"),
    ("listen", "LISTEN toaster_channel"),
    ("sleep", "SELECT pg_sleep(30)::text"),
    ("checkpoint", "CHECKPOINT"),
    # writes and objects
    ("nextval", "SELECT nextval('events_id_seq')"),
    ("setval", "SELECT setval('events_id_seq', 1000)"),
    ("lock-table", "LOCK TABLE settings IN ACCESS EXCLUSIVE MODE"),
    ("temp-table", "CREATE TEMP TABLE pwned (x int)"),
    ("select-into", "SELECT * INTO TEMP pwned FROM settings"),
    ("create-table", "CREATE TABLE pwned AS SELECT * FROM settings"),
    ("prepare", "PREPARE pwned AS SELECT 1"),
    ("declare-hold", "DECLARE pwned CURSOR WITH HOLD FOR SELECT 1"),
    ("do", "DO $$ BEGIN EXECUTE 'DROP TABLE settings'; END $$"),
    ("do-role", "DO $$ BEGIN PERFORM set_config('role', 'postgres', false); END $$"),
    ("call", "CALL pwned()"),
    ("writable-cte", "WITH d AS (DELETE FROM settings RETURNING *) SELECT * FROM d"),
    (
        "writable-cte-insert",
        "WITH i AS (INSERT INTO properties VALUES ('A', 'k', 'v') RETURNING *) SELECT * FROM i",
    ),
    ("for-update", "SELECT * FROM settings FOR UPDATE"),
    ("for-share", "SELECT * FROM entities FOR SHARE"),
    ("explain-analyze-delete", "EXPLAIN ANALYZE DELETE FROM settings"),
    ("insert", "INSERT INTO properties VALUES ('A', 'k', 'v')"),
    ("update", "UPDATE store_state SET cache_epoch = 99"),
    ("delete", "DELETE FROM store_state"),
    ("replace", "REPLACE INTO properties VALUES ('A', 'k', 'v')"),
    ("truncate", "TRUNCATE settings"),
    ("drop", "DROP TABLE settings"),
    ("grant", "GRANT ALL ON settings TO PUBLIC"),
    ("vacuum", "VACUUM"),
    ("analyze", "ANALYZE"),
    # SQLite: files, pragmas, extensions
    ("attach", "ATTACH DATABASE 'x.db' AS x"),
    ("attach-tmp", "ATTACH DATABASE '{tmp}/x.db' AS x"),
    ("detach", "DETACH DATABASE main"),
    ("vacuum-into", "VACUUM INTO '{tmp}/copy.db'"),
    ("pragma-user-version", "PRAGMA user_version = 42"),
    ("pragma-query-only-off", "PRAGMA query_only = OFF"),
    ("pragma-journal-mode", "PRAGMA journal_mode = DELETE"),
    ("pragma-writable-schema", "PRAGMA writable_schema = ON"),
    ("pragma-foreign-keys-off", "PRAGMA foreign_keys = OFF"),
    ("pragma-checkpoint", "PRAGMA wal_checkpoint(TRUNCATE)"),
    ("load-extension", "SELECT load_extension('{tmp}/evil')"),
    # memory and time
    ("zeroblob", ("SELECT zeroblob(1e9)", "SELECT repeat('x', 20000000)")),
    ("randomblob", ("SELECT randomblob(1000000000)", "SELECT lpad('', 20000000, 'x')")),
    (
        "hex-huge",
        (
            "SELECT hex(zeroblob(10000000))",
            "SELECT string_agg(repeat('x', 100000), '') FROM generate_series(1, 200)",
        ),
    ),
    ("endless-count", _ENDLESS + "SELECT count(*) FROM c"),
    ("endless-sort", _ENDLESS + "SELECT x FROM c ORDER BY x DESC LIMIT 1"),
    (
        "endless-wide-rows",
        (
            _ENDLESS + "SELECT x, hex(randomblob(2000)) FROM c",
            _ENDLESS + "SELECT x, repeat('x', 4000) FROM c",
        ),
    ),
]


# ---------------------------------------------------------------------------- helpers
#: The current schema's tables, found through pg_depend (every table depends on its schema)
#: by an index: listing them from pg_class reads all of it, slow when the server's catalog
#: holds many dead rows (schemas made and dropped by tests, without autovacuum).
_PG_TABLES = (
    "SELECT c.relname FROM pg_depend d JOIN pg_class c ON c.oid = d.objid "
    "WHERE d.classid = 'pg_class'::regclass "
    "AND d.refclassid = 'pg_namespace'::regclass "
    "AND d.refobjid = current_schema()::regnamespace AND c.relkind IN ('r', 'p')"
)
#: Sessions that read each PostgreSQL database for :func:`dump`, one per URL (autocommit:
#: each statement sees what is committed); closed at the end of the module.
_OBSERVERS: dict[str, psycopg.Connection[Any]] = {}


@pytest.fixture(scope="module", autouse=True)
def _close_observers() -> Iterator[None]:
    yield
    for conn in _OBSERVERS.values():
        conn.close()
    _OBSERVERS.clear()


def dump(url: str) -> dict[str, list[tuple[Any, ...]]]:
    """Every table's rows, sorted (the database's content, to compare before / after; on
    SQLite its own ``sqlite_*`` tables too)."""
    if url.startswith("postgresql"):
        pg = _OBSERVERS.get(url)
        if pg is None:
            pg = _OBSERVERS[url] = psycopg.connect(
                url.replace("postgresql+psycopg://", "postgresql://"), autocommit=True
            )
        return {
            name: sorted(pg.execute(f'SELECT * FROM "{name}"').fetchall(), key=repr)
            for name in sorted(n for (n,) in pg.execute(_PG_TABLES))
        }
    with closing(sqlite3.connect(url.removeprefix("sqlite:///"))) as lite:
        return {
            name: sorted(lite.execute(f'SELECT * FROM "{name}"').fetchall(), key=repr)
            for name in sorted(
                n for (n,) in lite.execute("SELECT name FROM sqlite_master WHERE type = 'table'")
            )
        }


def files(root: Path) -> set[str]:
    """Every path under ``root`` (relative)."""
    return {str(p.relative_to(root)) for p in root.rglob("*")}


def server_state(db: toaster.Database) -> dict[str, Any]:
    """What a statement could leave in the session or on the server."""
    with db.transaction() as conn:
        if db.dialect_name == "sqlite":
            run = conn.exec_driver_sql
            return {
                "pragmas": [
                    run(f"PRAGMA {p}").scalar()
                    for p in (
                        "query_only",
                        "user_version",
                        "journal_mode",
                        "foreign_keys",
                        "hard_heap_limit",
                        "writable_schema",
                    )
                ],
                "databases": [r[1] for r in run("PRAGMA database_list")],
                "length": conn.connection.dbapi_connection.getlimit(  # type: ignore[union-attr]
                    sqlite3.SQLITE_LIMIT_LENGTH
                ),
            }
        row = conn.exec_driver_sql(
            "SELECT current_user, session_user, current_setting('statement_timeout'), "
            "current_setting('work_mem'), current_setting('transaction_read_only'), "
            "(SELECT count(*) FROM pg_locks WHERE locktype = 'advisory' "
            "AND pid = pg_backend_pid()), (SELECT count(*) FROM pg_largeobject_metadata), "
            "(SELECT count(*) FROM pg_prepared_xacts), (SELECT count(*) FROM pg_prepared_statements "
            "WHERE name = 'pwned'), (SELECT count(*) FROM pg_cursors), "
            "(SELECT count(*) FROM pg_listening_channels())"
        ).one()
        return dict(
            zip(
                (
                    "user",
                    "session",
                    "timeout",
                    "work_mem",
                    "read_only",
                    "advisory",
                    "large_objects",
                    "prepared_xacts",
                    "prepared",
                    "cursors",
                    "listening",
                ),
                row,
                strict=True,
            )
        )


# ---------------------------------------------------------------------------- fixtures
@pytest.fixture(scope="module", params=BACKENDS)
def read_url(
    request: pytest.FixtureRequest, tmp_path_factory: pytest.TempPathFactory, sqlite_template: Path
) -> Iterator[str]:
    """``db_url`` shared by this module's tests that only read (migrating a PostgreSQL schema
    per test is slow): a SQLite file in a folder of its own, or a PostgreSQL schema dropped
    afterwards. Each hostile case checks that the rows, the files (that folder's too) and
    the session are unchanged after its statement, so a case that leaked a change fails."""
    if request.param == "sqlite":
        path = tmp_path_factory.mktemp("shared") / "toaster.db"
        shutil.copy(sqlite_template, path)
        yield f"sqlite:///{path}"
        return
    with pg_schema(migrated=True) as url:
        yield url


@pytest.fixture(scope="module")
def read_db(read_url: str) -> Iterator[toaster.Database]:
    """``db`` shared by this module's tests that only read (on :func:`read_url`)."""
    database = toaster.connect(read_url)
    try:
        yield database
    finally:
        database.close()


@pytest.fixture
def other(read_db: toaster.Database) -> Iterator[psycopg.Connection[Any] | None]:
    """A second session (PostgreSQL) that hostile statements try to end."""
    if read_db.dialect_name != "postgresql":
        yield None
        return
    conn = psycopg.connect(
        PG_URL.replace("postgresql+psycopg://", "postgresql://"), autocommit=True
    )
    try:
        yield conn
    finally:
        conn.close()


@pytest.fixture
def scratch(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty working directory and scratch folder for paths the statements name."""
    cwd = tmp_path / "cwd"
    cwd.mkdir()
    monkeypatch.chdir(cwd)
    return tmp_path


def expect_refused(
    db: toaster.Database,
    url: str,
    sql: str,
    root: Path,
    other: psycopg.Connection[Any] | None,
    *,
    must_raise: bool = True,
    **bounds: Any,
) -> ToasterError | None:
    """Run ``sql`` read-only; check it raised one line (unless not ``must_raise``) and left
    nothing behind."""
    roots = [root]
    if url.startswith("sqlite:///"):  # the database's folder: its journal files
        roots.append(Path(url.removeprefix("sqlite:///")).parent)
    q.execute(db, "SELECT count(*) FROM settings")  # set-up done, files settled
    before, state, paths = dump(url), server_state(db), [files(r) for r in roots]
    error = None
    try:
        q.execute(db, sql, **bounds)
    except ToasterError as exc:
        error = exc
    assert error is not None or not must_raise, "did not raise"
    assert error is None or (str(error) and "\n" not in str(error)), str(error)
    assert [files(r) for r in roots] == paths
    assert dump(url) == before
    assert server_state(db) == state
    if other is not None:
        assert other.execute("SELECT 1").fetchone() == (1,)
    assert q.execute(db, "SELECT 1 AS one").rows == [(1,)]
    return error


# ---------------------------------------------------------------------------- hostile
@pytest.mark.slow
@pytest.mark.parametrize("sql", [pytest.param(sql, id=name) for name, sql in HOSTILE])
def test_hostile_statement_is_refused(
    read_db: toaster.Database,
    read_url: str,
    scratch: Path,
    other: psycopg.Connection[Any] | None,
    sql: str | tuple[str, str],
) -> None:
    """Each raises a one-line ToasterError and changes nothing, on both backends."""
    db = read_db
    if isinstance(sql, tuple):
        sql = sql[db.dialect_name == "postgresql"]
    pid = other.info.backend_pid if other is not None else 0
    expect_refused(db, read_url, sql.format(tmp=scratch, pid=pid), scratch, other, **BOUNDS)


@pytest.mark.slow
def test_the_database_alone_stops_them(
    read_db: toaster.Database,
    read_url: str,
    scratch: Path,
    other: psycopg.Connection[Any] | None,
    monkeypatch: pytest.MonkeyPatch,
) -> None:
    """Defence in depth: with the statement check switched off, the database layers alone
    (authorizer, query_only, limits on SQLite; read-only transaction, reader role, wrapper
    and checks after on PostgreSQL) let no hostile statement leave a trace (some then run,
    harmlessly: their effects are rolled back)."""
    db = read_db
    monkeypatch.setattr(readonly_sqlite, "check_statement", tokenize)
    monkeypatch.setattr(readonly_pg, "check_statement", tokenize)
    pid = other.info.backend_pid if other is not None else 0
    failures = []
    for name, sql in HOSTILE:
        if isinstance(sql, tuple):
            sql = sql[db.dialect_name == "postgresql"]
        try:
            expect_refused(
                db,
                read_url,
                sql.format(tmp=scratch, pid=pid),
                scratch,
                other,
                must_raise=False,
                timeout_s=1.0,
                max_bytes=BOUNDS["max_bytes"],
            )
        except AssertionError as exc:
            failures.append(f"{name}: {exc}")
    assert not failures


def test_the_load_test_statements_are_refused(read_db: toaster.Database) -> None:
    """The issue's examples are refused before they reach the database, as writes."""
    for sql in (
        "COMMIT; DROP TABLE settings",
        "SET transaction_read_only = off",
        "BEGIN READ WRITE",
        "ATTACH DATABASE 'x.db' AS x",
        "WITH d AS (DELETE FROM settings) SELECT 1",
    ):
        with pytest.raises(ReadOnlyError, match="--write"):
            q.execute(read_db, sql)


@pytest.mark.slow
def test_statement_cached_by_a_write_is_authorized_again(db: toaster.Database) -> None:
    """SQLite caches prepared statements: one prepared by --write is checked again."""
    sql = "INSERT INTO settings VALUES ('test', 'colour', '\"red\"')"
    q.execute(db, sql, write=True)
    with pytest.raises(ReadOnlyError):
        q.execute(db, sql)
    assert q.execute(db, "SELECT count(*) FROM settings").rows == [(1,)]


# ---------------------------------------------------------------------------- PostgreSQL roles
@pytest.mark.postgresql
@pytest.mark.backend("postgresql")
def test_statement_runs_as_the_reader_role(read_db: toaster.Database) -> None:
    """A superuser's statement runs as toaster_reader, which holds no attribute; the
    connection is the connecting role's again afterwards."""
    assert q.execute(read_db, "SELECT current_user::text, session_user::text").rows == [
        (READER_ROLE, "postgres")
    ]
    attrs = q.execute(
        read_db,
        "SELECT rolsuper, rolcreaterole, rolcreatedb, rolcanlogin, "
        "rolbypassrls FROM pg_roles WHERE rolname = :r",
        {"r": READER_ROLE},
    )
    assert attrs.rows == [(False, False, False, False, False)]
    with read_db.transaction() as conn:
        assert conn.exec_driver_sql("SELECT current_user").scalar() == "postgres"


@pytest.mark.slow
@pytest.mark.postgresql
@pytest.mark.backend("postgresql")
def test_views_made_after_the_first_read_are_readable(store: toaster.Store) -> None:
    """An agent's views, created after the reader role's grants, are granted on demand."""
    db = store.db
    q.execute(db, "SELECT 1")
    store.add_entity("CAROL", "human", t_ns=1)
    assert q.execute(db, 'SELECT count(*) FROM "fact_table_CAROL"').rows == [(0,)]


@pytest.mark.postgresql
@pytest.mark.backend("postgresql")
def test_a_superuser_never_falls_back(read_url: str, monkeypatch: pytest.MonkeyPatch) -> None:
    """When the reader role cannot be used, a superuser's statement is refused rather than
    run with the superuser's privileges."""
    monkeypatch.setattr(readonly_pg, "ensure_reader_role", lambda cur: "tampered")
    db = toaster.connect(read_url)  # a session of its own: it has no wrapper yet
    try:
        with pytest.raises(ToasterError, match="cannot set up read-only SQL.*tampered"):
            q.execute(db, "SELECT 1")
    finally:
        db.close()


@pytest.fixture
def plain_role_url(db: toaster.Database, db_url: str) -> Iterator[str]:
    """``db_url`` as a fresh login role that cannot create roles and owns nothing (its tests
    are marked ``backend("postgresql")``)."""
    role = f"toaster_plain_{uuid.uuid4().hex[:8]}"
    with db.transaction() as conn:
        run = conn.exec_driver_sql
        run(f"CREATE ROLE {role} LOGIN NOSUPERUSER NOCREATEROLE")
        run(f"GRANT USAGE ON SCHEMA {run('SELECT current_schema()').scalar()} TO {role}")
        run(
            f"GRANT SELECT ON ALL TABLES IN SCHEMA "
            f"{run('SELECT current_schema()').scalar()} TO {role}"
        )
    try:
        yield db_url.replace("postgres@", f"{role}@", 1)
    finally:
        with db.transaction() as conn:  # its sessions' temporary objects go when they end
            conn.exec_driver_sql(
                f"SELECT pg_terminate_backend(pid) FROM pg_stat_activity WHERE usename = '{role}'"
            )
        for _ in range(1200):  # up to 60 s: ending a session takes longer under load
            with db.transaction() as conn:
                if not conn.exec_driver_sql(
                    f"SELECT count(*) FROM pg_stat_activity WHERE usename = '{role}'"
                ).scalar():
                    break
            time.sleep(0.05)
        with db.transaction() as conn:
            conn.exec_driver_sql(f"DROP OWNED BY {role}")
            conn.exec_driver_sql(f"DROP ROLE {role}")


@pytest.mark.slow
@pytest.mark.postgresql
@pytest.mark.backend("postgresql")
def test_a_role_that_cannot_create_roles_falls_back(
    plain_role_url: str, scratch: Path, db_url: str
) -> None:
    """Without CREATEROLE (and not the tables' owner), statements run as the connecting role,
    still in the read-only wrapper: reads work, the hostile ones are still refused, and its
    other session survives."""
    role = plain_role_url.split("//", 1)[1].split("@", 1)[0]
    other = psycopg.connect(
        PG_URL.replace("postgresql+psycopg://", "postgresql://").replace(
            "postgres@", f"{role}@", 1
        ),
        autocommit=True,
    )
    plain = toaster.connect(plain_role_url)
    try:
        assert q.execute(plain, "SELECT current_user::text").rows == [(role,)]
        assert q.execute(plain, "SELECT count(*) FROM settings").rows == [(0,)]
        for sql in (
            "SELECT pg_terminate_backend({pid})",
            "SELECT set_config('role', 'postgres', true)",
            "COMMIT; DELETE FROM settings",
            "SELECT pg_advisory_lock(1)",
            "SET ROLE toaster_reader",
        ):
            expect_refused(
                plain, plain_role_url, sql.format(pid=other.info.backend_pid), scratch, other
            )
    finally:
        plain.close()
        other.close()


def _admin() -> psycopg.Connection[Any]:
    return psycopg.connect(
        PG_URL.replace("postgresql+psycopg://", "postgresql://"), autocommit=True
    )


@pytest.fixture(scope="module")
def owner_url() -> Iterator[str]:
    """A database of its own, owned by a fresh login role without CREATEROLE that migrated
    it (so it owns every table), as that role's URL; both dropped afterwards."""
    require_postgres()
    name = f"toaster_owner_{uuid.uuid4().hex[:8]}"
    with _admin() as admin:
        admin.execute(f"CREATE ROLE {name} LOGIN NOSUPERUSER NOCREATEROLE NOCREATEDB")
        admin.execute(f"CREATE DATABASE {name} OWNER {name}")
    url = make_url(PG_URL).set(username=name, database=name)
    try:
        engine = make_engine(url.render_as_string(hide_password=False))
        migrate.upgrade(engine)
        engine.dispose()
        yield url.render_as_string(hide_password=False)
    finally:
        with _admin() as admin:
            admin.execute(f"DROP DATABASE IF EXISTS {name} WITH (FORCE)")
            admin.execute(f"DROP ROLE IF EXISTS {name}")


#: Finding 1 of issue 24, as reported: toaster's own wrapper, called by name, runs the SQL in
#: its string literal, which the statement check does not read.
WRAPPER_CALL = (
    "SELECT * FROM pg_temp.toaster_readonly_run('SELECT pg_terminate_backend(pid)"
    "::text FROM pg_stat_activity WHERE application_name = ''victim''', 100, "
    "1000000) AS t(a text)"
)


@pytest.mark.slow
@pytest.mark.postgresql
@pytest.mark.parametrize("reader", [False, True], ids=["fallback", "reader-role"])
def test_the_wrapper_cannot_be_called_by_a_statement(
    owner_url: str, reader: bool, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A role owning its database, without CREATEROLE, once ended its own other session
    through ``pg_temp.toaster_readonly_run('...')``. The check refuses pg_temp; with the
    check switched off, the wrapper refuses to run inside a statement (it reads the call
    stack); the session named victim lives on. Both as the role itself (it cannot take the
    reader role) and as the reader role (an administrator granted it)."""
    owner = make_url(owner_url).username
    if reader:  # as an administrator would: the role, its grants, and the owner may take it
        admin_url = make_url(PG_URL).set(database=make_url(owner_url).database)
        with psycopg.connect(
            admin_url.render_as_string(hide_password=False).replace(
                "postgresql+psycopg://", "postgresql://"
            )
        ) as admin:
            assert readonly_pg.ensure_reader_role(admin.cursor()) is None
            admin.execute(f"GRANT {READER_ROLE} TO {owner}")
    victim = psycopg.connect(
        owner_url.replace("postgresql+psycopg://", "postgresql://"),
        application_name="victim",
        autocommit=True,
    )
    try:
        with closing(toaster.connect(owner_url)) as db:
            assert q.execute(db, "SELECT current_user::text").rows == [
                (READER_ROLE if reader else owner,)
            ]
        runner = CliRunner()
        refused = runner.invoke(cli, ["--db", owner_url, "execute", "SQL", WRAPPER_CALL])
        assert (refused.exit_code, victim.execute("SELECT 1").fetchone()) == (1, (1,))
        assert "pg_temp" in refused.output and len(refused.output.splitlines()) == 1
        monkeypatch.setattr(readonly_pg, "check_statement", tokenize)
        unchecked = runner.invoke(cli, ["--db", owner_url, "execute", "SQL", WRAPPER_CALL])
        assert (unchecked.exit_code, victim.execute("SELECT 1").fetchone()) == (1, (1,))
        assert "wrapper cannot be called" in unchecked.output, unchecked.output
    finally:
        victim.close()
        if reader:
            with _admin() as admin:
                admin.execute(f"REVOKE {READER_ROLE} FROM {owner}")


@pytest.mark.postgresql
@pytest.mark.backend("postgresql")
def test_toasters_own_functions_are_refused(read_db: toaster.Database) -> None:
    """Every function in toaster's schema (the triggers' functions of the migrations and
    the belief rules), as the catalog lists them, and the wrapper in pg_temp, however
    spelled, are refused by the statement check."""
    names = [
        name
        for (name,) in q.execute(
            read_db,
            "SELECT proname::text FROM pg_proc WHERE pronamespace = current_schema()::regnamespace",
        ).rows
    ]
    assert "toaster_guard" in names and "toaster_belief_run" in names
    schema = q.execute(read_db, "SELECT current_schema()::text").rows[0][0]
    for name in names:
        for sql in (
            f"SELECT {name}()",
            f'SELECT "{schema}"."{name}"()',
            f"SELECT x FROM {schema}.{name}() AS x",
        ):
            with pytest.raises(ReadOnlyError, match=name):
                check_statement(sql, "postgresql")
    for spelling in (
        "pg_temp",
        '"pg_temp"',
        "PG_TEMP",
        "pg_temp_12",
        "pg_toast_temp_3",
        '"pg_temp_3"',
    ):
        with pytest.raises(ReadOnlyError, match="temporary schema"):
            check_statement(
                f"SELECT * FROM {spelling}.toaster_readonly_run('SELECT 1', 1, 1) AS t(a int)",
                "postgresql",
            )


# ---------------------------------------------------------------------------- reads
@pytest.mark.slow
def test_ordinary_reads_still_work(store: toaster.Store) -> None:
    """Parameters, views, WITH, EXPLAIN, quotes and semicolons in strings, trailing ';'."""
    db = store.db
    store.sync_snapshot("pdg", "PR2_ROBOT", 1, [toaster.Fact("MUG", "IsOn", "TABLE")])
    pg = db.dialect_name == "postgresql"
    positional = "SELECT %s AS a, %s AS b" if pg else "SELECT ? AS a, ? AS b"
    assert q.execute(db, positional, ["x", 2]).rows == [("x", 2)]
    named = q.execute(
        db,
        "SELECT subject_id, '50%; :no' AS s FROM current_facts "
        "WHERE agent_id = :agent AND property = :p;",
        {"agent": "PR2_ROBOT", "p": "IsOn"},
    )
    assert (named.columns, named.rows) == (["subject_id", "s"], [("MUG", "50%; :no")])
    view = q.execute(db, 'SELECT target_id FROM "fact_table_PR2_ROBOT"')
    assert view.rows == [("TABLE",)] and not view.truncated
    with_query = q.execute(db, "WITH n(x) AS (VALUES (1), (2)) SELECT sum(x) AS s FROM n -- ;")
    assert with_query.rows == [(3,)]
    assert q.execute(db, "EXPLAIN SELECT * FROM entities").rows
    if pg:
        assert q.execute(db, "(SELECT 1 AS a) UNION ALL (SELECT 2) ORDER BY 1").rows == [(1,), (2,)]
        assert q.execute(db, "SELECT 2::int AS n, $t$;$t$ AS s, E'\\'' AS q").rows == [
            (2, ";", "'")
        ]
        assert q.execute(db, "SHOW standard_conforming_strings").rows == [("on",)]
        assert q.execute(db, "TABLE store_state").rows
        assert q.execute(db, "EXPLAIN (ANALYZE, COSTS OFF) SELECT 1").rows
    else:
        assert q.execute(db, "PRAGMA table_info(settings)").rows
        assert q.execute(db, "SELECT name FROM pragma_table_info('settings')").rows == [
            ("scope",),
            ("key",),
            ("value_json",),
        ]


def test_row_cap_truncates(read_db: toaster.Database) -> None:
    """Beyond max_rows, the first max_rows rows and ``truncated``; exactly max_rows is whole."""
    endless = q.execute(read_db, _ENDLESS + "SELECT x FROM c", max_rows=10)
    assert endless.rows == [(i,) for i in range(1, 11)] and endless.truncated
    exact = q.execute(read_db, "VALUES (1), (2), (3)", max_rows=3)
    assert len(exact.rows) == 3 and not exact.truncated


def test_byte_cap_and_timeout(read_db: toaster.Database) -> None:
    """Past max_bytes or timeout_s: a one-line error naming the option to raise."""
    wide = (
        "SELECT hex(randomblob(5000))"
        if read_db.dialect_name == "sqlite"
        else "SELECT repeat('x', 10000)"
    )
    with pytest.raises(ToasterError, match="--max-bytes"):
        q.execute(read_db, wide, max_bytes=4096)
    assert q.execute(read_db, wide, max_bytes=20000).rows
    with pytest.raises(ToasterError, match="--timeout"):
        q.execute(read_db, _ENDLESS + "SELECT count(*) FROM c", timeout_s=0.3)


@pytest.mark.slow
@pytest.mark.backend("sqlite")
def test_sqlite_memory_is_bounded(
    read_db: toaster.Database, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A sort of endless rows stops at SQLite's heap limit (lowered here to be quick)."""
    monkeypatch.setattr(readonly_sqlite, "SQLITE_HEAP_LIMIT", 96 * 2**20)
    with pytest.raises(ToasterError, match="memory"):
        q.execute(
            read_db, _ENDLESS + "SELECT x, hex(randomblob(50)) FROM c ORDER BY 2", timeout_s=60
        )
    assert server_state(read_db)["pragmas"][4] == 0  # hard_heap_limit given back


def test_rows_stream_in_batches(read_db: toaster.Database) -> None:
    """execute_stream gives the columns, then the rows as they are fetched (over several
    batches), and says ``truncated`` once they are read; a statement past a bound fails as
    it is opened, before any row."""
    with q.execute_stream(read_db, _ENDLESS + "SELECT x FROM c", max_rows=1000) as rows:
        assert rows.columns == ["x"]
        assert [x for (x,) in rows] == list(range(1, 1001))
    assert rows.truncated
    wide = _ENDLESS + (
        "SELECT x, hex(randomblob(100)) FROM c LIMIT 5000"
        if read_db.dialect_name == "sqlite"
        else "SELECT x, repeat('x', 200) FROM c LIMIT 5000"
    )
    with (
        pytest.raises(ToasterError, match="--max-bytes"),
        q.execute_stream(read_db, wide, max_bytes=100_000),
    ):
        pytest.fail("a refused statement gave rows")


@pytest.mark.backend("sqlite")
def test_sqlite_printf_past_the_bound_is_refused(read_db: toaster.Database) -> None:
    """SQLite's printf() and format() return NULL when their result passes the length limit,
    which would pass for an answer: read-only SQL refuses it, naming --max-bytes."""
    for sql in (
        "SELECT printf('%.*c', 5000, 'x')",
        "SELECT format('%5000d', 1)",
        "SELECT length(printf('%s-%.*c', 'a', 20000000, 'x'))",
    ):
        with pytest.raises(ToasterError, match="printf.*--max-bytes"):
            q.execute(read_db, sql, max_bytes=4096)
    same = (
        "SELECT printf('%d-%s', 5, 'a'), printf(NULL), format('%.3c|%5.1f|%x', 'x', "
        "2.25, x'41'), printf('%s', NULL), printf('%!.3g %q', 1e20, 'it''s')"
    )
    with closing(sqlite3.connect(":memory:")) as plain:
        assert q.execute(read_db, same, max_bytes=4096).rows == [plain.execute(same).fetchone()]


@pytest.mark.slow
@pytest.mark.backend("sqlite")
def test_a_long_function_call_stops_at_the_deadline(read_db: toaster.Database) -> None:
    """SQLite looks at its deadline only between steps of its virtual machine, never inside
    one function call: this instr() alone runs for minutes (its cost is the product of the
    two lengths). The statement's process is killed at the deadline."""
    haystack = "replace(hex(zeroblob(2097152)), '0', 'a')"  # 4 MiB of 'a'
    needle = "replace(hex(zeroblob(1048576)), '0', 'a') || 'b'"  # 2 MiB of 'a', then 'b'
    with pytest.raises(ToasterError, match="--timeout"):
        q.execute(
            read_db, f"SELECT instr({haystack}, {needle})", timeout_s=1.0, max_bytes=8 * 2**20
        )
    assert q.execute(read_db, "SELECT 1").rows == [(1,)]


@pytest.mark.slow
@pytest.mark.backend("sqlite")
def test_the_deadline_starts_when_the_worker_is_ready(
    read_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The deadline bounds the statement, not the start of its process (seconds on a loaded
    machine): a worker that takes 3 s to start runs a statement under a 2 s deadline. One
    that does not start in time, or ends as it starts, is a one-line error."""
    slow = "import time; time.sleep(3); " + readonly_sqlite._CHILD
    monkeypatch.setattr(readonly_sqlite, "_CHILD", slow)
    with closing(toaster.connect(read_url)) as db:  # a worker of its own
        assert q.execute(db, "SELECT 1", timeout_s=2.0).rows == [(1,)]
    monkeypatch.setattr(readonly_sqlite, "START_TIMEOUT_S", 0.5)
    for child, message in (
        (slow, "did not start within 0.5 s"),
        ("raise SystemExit(3)", "ended as it started .exit status 3"),
    ):
        monkeypatch.setattr(readonly_sqlite, "_CHILD", child)
        with (
            closing(toaster.connect(read_url)) as db,
            pytest.raises(ToasterError, match=message) as error,
        ):
            q.execute(db, "SELECT 1")
        assert "\n" not in str(error.value)


def test_in_memory_sqlite_is_refused_in_one_line() -> None:
    """The statement's process cannot open an in-memory database: one line, not a guess."""
    with (
        open_database("sqlite://", allow_memory=True) as db,
        pytest.raises(ToasterError, match="in-memory database"),
    ):
        q.execute(db, "SELECT 1")


#: Runs the CLI (its arguments after the first) in a fresh interpreter, then writes to the
#: first the peak RSS in KiB of that program (VmHWM: getrusage's would start from the pytest
#: process it was forked from) and of its children (the SQLite statement's process).
_PEAK = """
import json, re, resource, sys
from pathlib import Path
from toaster.cli import main
out = sys.argv.pop(1)
sys.argv[0] = "toaster"
try:
    main()
finally:
    own = re.search(r"VmHWM:\\s*(\\d+)", Path("/proc/self/status").read_text()).group(1)
    children = resource.getrusage(resource.RUSAGE_CHILDREN).ru_maxrss
    Path(out).write_text(json.dumps([int(own), children]))
"""


def peak_rss(tmp_path: Path, *args: str) -> tuple[subprocess.CompletedProcess[str], int, int]:
    """The CLI's result (stdout to /dev/null), its peak RSS and its children's, in bytes (a
    child's counts at least its parent's pages from before it ran its own program)."""
    if not Path("/proc/self/status").exists():
        pytest.skip("peak RSS is read from /proc (Linux)")
    out = tmp_path / "rss.json"
    result = subprocess.run(
        [sys.executable, "-c", _PEAK, str(out), *args],
        stdout=subprocess.DEVNULL,
        stderr=subprocess.PIPE,
        text=True,
        check=False,
    )
    own, children = json.loads(out.read_text())
    return result, own * 1024, children * 1024


@pytest.mark.slow
@pytest.mark.parametrize("fmt", ["tsv", "--json"])
def test_a_result_at_the_bound_prints_with_bounded_memory(
    read_url: str, tmp_path: Path, fmt: str
) -> None:
    """Piped output is written as rows arrive: printing ~30 MiB of rows (under --max-bytes
    32 MiB) holds one batch, so the process's peak RSS stays within half the bound of
    printing one row (it held every row, then every formatted cell, before)."""
    bound = 32 * 2**20
    sql = (
        (
            "WITH RECURSIVE c(x) AS (SELECT 1 UNION ALL SELECT x + 1 FROM c LIMIT 30000) "
            "SELECT x, hex(randomblob(500)) FROM c"
        )
        if read_url.startswith("sqlite")
        else "SELECT x, repeat(md5(x::text), 31) FROM generate_series(1, 30000) AS x"
    )
    options = ["--max-bytes", str(bound), *([fmt] if fmt != "tsv" else [])]
    args = ["--db", read_url, "execute", "SQL"]
    base, base_own, _ = peak_rss(tmp_path, *args, "SELECT 1 AS one", *options)
    big, own, children = peak_rss(tmp_path, *args, sql, *options)
    assert (base.returncode, big.returncode) == (0, 0), big.stderr
    assert own - base_own < bound / 2, (own >> 20, base_own >> 20)
    assert children < base_own + 2 * bound, (children >> 20, base_own >> 20)


@pytest.mark.slow
def test_big_values_are_refused_before_they_are_held(read_url: str, tmp_path: Path) -> None:
    """Rows of 900 kB values past a 1 MiB bound are refused at the second row (the whole
    batch of 1000 rows was fetched, ~0.9 GB, before the size was looked at), in one line,
    with nothing printed and memory near that of printing one row."""
    bound = 2**20
    sql = (
        (
            "WITH RECURSIVE c(x) AS (SELECT 1 UNION ALL SELECT x + 1 FROM c LIMIT 1000) "
            "SELECT randomblob(900000) FROM c"
        )
        if read_url.startswith("sqlite")
        else "SELECT decode(repeat('ab', 450000), 'hex') FROM generate_series(1, 1000)"
    )
    args = ["--db", read_url, "execute", "SQL"]
    _, base_own, _ = peak_rss(tmp_path, *args, "SELECT 1 AS one")
    big, own, children = peak_rss(tmp_path, *args, sql, "--max-bytes", str(bound))
    assert big.returncode == 1 and len(big.stderr.splitlines()) == 1, big.stderr
    assert "--max-bytes" in big.stderr and "Traceback" not in big.stderr
    assert max(own, children) < base_own + 64 * 2**20, (own >> 20, children >> 20, base_own >> 20)


#: (id, SQLite SQL, PostgreSQL SQL or None, options, the option the message names)
REFUSALS = [
    (
        "result-bytes",
        _ENDLESS + "SELECT x, hex(randomblob(100)) FROM c",
        _ENDLESS + "SELECT x, repeat('x', 200) FROM c",
        ["--max-bytes", "100000"],
        "--max-bytes",
    ),
    (
        "one-value",
        "SELECT randomblob(2000000)",
        "SELECT repeat('x', 2000000)",
        ["--max-bytes", "1048576"],
        "--max-bytes",
    ),
    (
        "time",
        _ENDLESS + "SELECT count(*) FROM c",
        _ENDLESS + "SELECT count(*) FROM c",
        ["--timeout", "0.5"],
        "--timeout",
    ),
    (
        "printf-null",
        "SELECT length(printf('%.*c', 1000000000, 'x'))",
        None,
        ["--timeout", "2", "--max-bytes", "1048576"],
        "--max-bytes|--timeout",
    ),
]


@pytest.mark.slow
@pytest.mark.parametrize(
    ("sqlite_sql", "pg_sql", "options", "bound"),
    [
        pytest.param(
            *case[1:], id=case[0], marks=[pytest.mark.backend("sqlite")] if case[2] is None else []
        )
        for case in REFUSALS
    ],
)
def test_cli_refusal_names_the_bound(
    read_url: str, sqlite_sql: str, pg_sql: str | None, options: list[str], bound: str
) -> None:
    """Each bound's refusal is one line naming the option that raises it, exit 1, nothing
    on stdout (no row is printed before a statement is known to pass). The reported case:
    printf() made a NULL past the length limit, printed as an empty answer with exit 0."""
    sql = sqlite_sql if read_url.startswith("sqlite") else pg_sql
    assert sql is not None  # a case without PostgreSQL SQL is marked backend("sqlite")
    result = CliRunner().invoke(cli, ["--db", read_url, "execute", "SQL", sql, *options])
    assert (result.exit_code, result.stdout) == (1, ""), result.output
    assert len(result.stderr.splitlines()) == 1, result.stderr
    assert re.search(bound, result.stderr) and "Traceback" not in result.stderr, result.stderr


def test_bad_bounds_are_refused(read_db: toaster.Database) -> None:
    """Bounds are checked with a message naming the value."""
    for bounds in ({"max_rows": 0}, {"max_bytes": 10}, {"timeout_s": 0}):
        with pytest.raises(ToasterError, match=next(iter(bounds))):
            q.execute(read_db, "SELECT 1", **bounds)


def test_bad_text_is_a_one_line_error(read_db: toaster.Database) -> None:
    """NUL, lone surrogates and empty statements: SQL errors, not tracebacks."""
    for sql, params in (
        ("SELECT '\x00'", None),
        ("SELECT '\ud800'", None),
        ("", None),
        (" ; ", None),
        ("SELECT :a", {"a": "\ud800"}),
        ("SELECT :a", {}),
    ):
        with pytest.raises(ToasterError, match="SQL error"):
            q.execute(read_db, sql, params)


def test_read_only_needs_its_own_transaction(read_db: toaster.Database) -> None:
    """Inside an open transaction, read-only SQL refuses to run (it must roll back)."""
    with pytest.raises(ToasterError, match="outside"), read_db.transaction():
        q.execute(read_db, "SELECT 1")


@pytest.mark.slow
def test_write_still_writes(db: toaster.Database) -> None:
    """--write runs the statement as before and bumps the cache epoch."""
    epoch = q.execute(db, "SELECT cache_epoch FROM store_state").rows[0][0]
    q.execute(
        db, "INSERT INTO settings VALUES (:s, 'colour', '\"red\"')", {"s": "test"}, write=True
    )
    assert q.execute(db, "SELECT scope, value_json FROM settings").rows == [("test", '"red"')]
    assert q.execute(db, "SELECT cache_epoch FROM store_state").rows == [(epoch + 1,)]


# ---------------------------------------------------------------------------- tokenizer
@pytest.mark.parametrize(
    ("sql", "dialect", "kinds"),
    [
        ("SELECT E'\\'' ;", "postgresql", ["word", "string", "semi"]),
        ("SELECT $a$ ' $a$, $1", "postgresql", ["word", "string", "op", "param"]),
        ("/* a /* b */ c */ x", "postgresql", ["word"]),
        ("/* a /* b */ x", "sqlite", ["word"]),
        ("-- a\r x\n y", "postgresql", ["word", "word"]),
        ("-- a\r x\n y", "sqlite", ["word"]),
        ("a[1:n]::int", "postgresql", ["word", "op", "number", "op", "word", "op", "op", "word"]),
        ('"a""b" [c] `d` x\'ff\'', "sqlite", ["ident", "ident", "ident", "string"]),
    ],
)
def test_tokenizer(sql: str, dialect: str, kinds: list[str]) -> None:
    """Quotes, dollar quotes, nested comments and identifiers as each database reads them."""
    assert [t.kind for t in tokenize(sql, dialect)] == kinds


@pytest.mark.slow
def test_unterminated_quotes_are_refused() -> None:
    """Unterminated strings, identifiers, dollar quotes and comments: one-line errors."""
    for sql in ("SELECT 'a", 'SELECT "a', "SELECT $$a", "SELECT /* a", "SELECT E'\\'"):
        with pytest.raises(ToasterError, match="unterminated"):
            check_statement(sql, "postgresql")


# ---------------------------------------------------------------------------- CLI
def test_cli_refusal_is_one_line(read_url: str) -> None:
    """``execute SQL`` prints one line and exits 1 on a refused statement; a truncated result
    says so on stderr."""
    runner = CliRunner()
    refused = runner.invoke(
        cli, ["--db", read_url, "execute", "SQL", "COMMIT; DROP TABLE settings"]
    )
    assert refused.exit_code == 1
    assert len(refused.output.strip().splitlines()) == 1
    assert "--write" in refused.output and "Traceback" not in refused.output
    capped = runner.invoke(
        cli,
        ["--db", read_url, "execute", "SQL", "VALUES (1), (2), (3)", "--max-rows", "2", "--csv"],
    )
    assert capped.exit_code == 0, capped.output
    assert capped.stdout.splitlines()[1:] == ["1", "2"]
    assert "--max-rows" in capped.stderr
