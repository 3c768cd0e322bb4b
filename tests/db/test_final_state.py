"""A bare PostgreSQL schema is made at head by the final-state script
(:mod:`toaster.db.final_state`): the same catalogue as the migrations make (every table,
column, index, constraint, view, function, trigger, sequence, grant, row), falling back to the
migrations whenever the script cannot be had or fails, safe with concurrent creators, and
later migrations (down and up) work on it."""

from __future__ import annotations

import os
import subprocess
import sys
import uuid
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest
from sqlalchemy import Engine, event

import toaster
from tests.conftest import PG_URL, pg_schema
from toaster.db import final_state, migrate, template
from toaster.db.engine import make_engine
from toaster.errors import DatabaseOpenError

pytestmark = [pytest.mark.postgresql, pytest.mark.slow]  # each test makes several schemas

ROOT = Path(__file__).resolve().parents[2]
_NS = "(SELECT oid FROM pg_namespace WHERE nspname = current_schema())"
_Q = "quote_ident(current_schema()) || '.'"  # the schema's prefix, removed from definitions
#: Everything a schema is made of, one query per kind, comparable across schemas.
CATALOGUE = {
    "relations": f"""SELECT relname, relkind, relpersistence, reloptions, relacl::text,
        relowner::regrole::text, relrowsecurity, relforcerowsecurity, relreplident, reltuples,
        relpages FROM pg_class WHERE relnamespace = {_NS}""",
    "columns": f"""SELECT c.relname, a.attname,
        row_number() OVER (PARTITION BY c.oid ORDER BY a.attnum),
        format_type(a.atttypid, a.atttypmod), a.attnotnull, pg_get_expr(d.adbin, d.adrelid),
        a.attidentity, a.attgenerated, a.attcollation, a.attacl::text, a.attstattarget,
        a.attstorage, ARRAY(SELECT o FROM unnest(a.attoptions) o WHERE o NOT LIKE 'pg_attver=%%')
        FROM pg_attribute a JOIN pg_class c ON c.oid = a.attrelid
        LEFT JOIN pg_attrdef d ON d.adrelid = a.attrelid AND d.adnum = a.attnum
        WHERE c.relnamespace = {_NS} AND a.attnum > 0 AND NOT a.attisdropped""",
    "constraints": f"""SELECT c.relname, co.conname, co.contype, pg_get_constraintdef(co.oid),
        co.condeferrable, co.condeferred, co.convalidated, i.relname
        FROM pg_constraint co LEFT JOIN pg_class c ON c.oid = co.conrelid
        LEFT JOIN pg_class i ON i.oid = co.conindid WHERE co.connamespace = {_NS}""",
    "indexes": f"""SELECT c.relname, replace(pg_get_indexdef(i.indexrelid), {_Q}, ''),
        i.indisunique, i.indisprimary, i.indisclustered, i.indisvalid, i.indisreplident
        FROM pg_index i JOIN pg_class c ON c.oid = i.indexrelid WHERE c.relnamespace = {_NS}""",
    "views": f"""SELECT relname, pg_get_viewdef(oid) FROM pg_class
        WHERE relnamespace = {_NS} AND relkind IN ('v', 'm')""",
    "functions": f"""SELECT proname, pg_get_function_identity_arguments(oid),
        replace(pg_get_functiondef(oid), {_Q}, ''), proacl::text, proowner::regrole::text,
        proconfig, provolatile, prosecdef, proleakproof, proparallel, prokind
        FROM pg_proc WHERE pronamespace = {_NS}""",
    "triggers": f"""SELECT c.relname, t.tgname, pg_get_triggerdef(t.oid, true), t.tgenabled
        FROM pg_trigger t JOIN pg_class c ON c.oid = t.tgrelid
        WHERE c.relnamespace = {_NS} AND NOT t.tgisinternal""",
    "sequences": f"""SELECT c.relname, s.seqtypid::regtype::text, s.seqstart, s.seqincrement,
        s.seqmax, s.seqmin, s.seqcache, s.seqcycle, pg_sequence_last_value(c.oid),
        (SELECT o.relname || '.' || a.attname FROM pg_depend d
           JOIN pg_class o ON o.oid = d.refobjid
           JOIN pg_attribute a ON a.attrelid = d.refobjid AND a.attnum = d.refobjsubid
          WHERE d.classid = 'pg_class'::regclass AND d.objid = c.oid AND d.deptype = 'a')
        FROM pg_class c JOIN pg_sequence s ON s.seqrelid = c.oid
        WHERE c.relnamespace = {_NS}""",
    "rules": f"""SELECT c.relname, r.rulename, r.ev_type, r.is_instead FROM pg_rewrite r
        JOIN pg_class c ON c.oid = r.ev_class WHERE c.relnamespace = {_NS}""",
    "policies": f"""SELECT c.relname, p.polname FROM pg_policy p
        JOIN pg_class c ON c.oid = p.polrelid WHERE c.relnamespace = {_NS}""",
    "comments": f"""SELECT d.classoid::regclass::text, d.objsubid, d.description
        FROM pg_description d WHERE d.objoid IN (SELECT oid FROM pg_class
        WHERE relnamespace = {_NS} UNION ALL SELECT oid FROM pg_proc
        WHERE pronamespace = {_NS})""",
    "types": f"SELECT typname, typtype FROM pg_type WHERE typnamespace = {_NS}",
}


def catalogue(url: str) -> dict[str, Any]:
    """Every query of :data:`CATALOGUE` on the schema of ``url`` (rows sorted), and every
    table's rows (``alembic_version`` included)."""
    engine = make_engine(url)
    try:
        with engine.begin() as conn:
            found: dict[str, Any] = {
                kind: sorted(map(tuple, conn.exec_driver_sql(sql).all()), key=repr)
                for kind, sql in CATALOGUE.items()
            }
            tables = [name for name, kind, *_ in found["relations"] if kind == "r"]
            found["rows"] = {
                t: conn.exec_driver_sql(
                    f"SELECT coalesce(json_agg(t ORDER BY t::text), '[]')::text FROM \"{t}\" t"
                ).scalar_one()
                for t in tables
            }
    finally:
        engine.dispose()
    return found


@pytest.fixture
def cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """An empty script cache of this test's own."""
    monkeypatch.setenv(template.CACHE_VAR, str(tmp_path / "cache"))
    return tmp_path / "cache" / "toaster" / "templates"


@pytest.fixture(scope="module")
def reference() -> Iterator[dict[str, Any]]:
    """The catalogue of a schema made by the migrations alone."""
    with pg_schema() as url:
        upgrade(url, script=False)
        yield catalogue(url)


def upgrade(url: str, *, script: bool = True) -> int:
    """``migrate.upgrade`` on ``url``; the number of statements SQLAlchemy sent (the
    migrations send over a hundred, the script's path a few)."""
    engine = make_engine(url)
    try:
        return _counted(engine, lambda: migrate.upgrade(engine, script=script))
    finally:
        engine.dispose()


def _counted(engine: Engine, call: Any) -> int:
    sent = [0]

    def count(*_: object) -> None:
        sent[0] += 1

    event.listen(engine, "before_cursor_execute", count)
    try:
        call()
    finally:
        event.remove(engine, "before_cursor_execute", count)
    return sent[0]


def script_file(cache: Path) -> Path:
    (found,) = cache.glob("postgresql-*.sql")
    return found


def test_the_script_makes_the_schema_the_migrations_make(
    cache: Path, reference: dict[str, Any]
) -> None:
    """The first bare schema is migrated and leaves the script; the next ones run it, in a
    few statements, and equal the migrated one object for object and row for row."""
    with pg_schema() as first:
        assert upgrade(first) > 50
        assert catalogue(first) == reference
    path = script_file(cache)
    assert path.name.startswith(f"postgresql-{template.template_key(migrate.head_revision())}-pg")
    with pg_schema() as second:
        assert upgrade(second) < 15
        assert catalogue(second) == reference
    with pg_schema() as third:  # through the front door
        toaster.connect(third).close()
        assert catalogue(third) == reference


def test_a_script_that_fails_is_rolled_back_and_made_again(
    cache: Path, reference: dict[str, Any]
) -> None:
    """A script that fails half-way leaves nothing (its savepoint), the migrations make the
    schema, and a good script replaces the bad one; a damaged file is not used."""
    with pg_schema() as url:
        upgrade(url)
    path = script_file(cache)
    good = path.read_text()
    cut = good.index("CREATE VIEW")
    path.write_text(good[:cut] + "CREATE VIEW broken AS SELECT nothing;\n" + good[cut:])
    final_state._memo.clear()
    with pg_schema() as url:
        assert upgrade(url) > 50
        assert catalogue(url) == reference
    assert path.read_text() == good
    path.write_text(good[: len(good) // 2])  # truncated: no trailer
    final_state._memo.clear()
    with pg_schema() as url:
        assert upgrade(url) > 50
        assert catalogue(url) == reference
    assert path.read_text() == good


def test_without_a_writable_cache_the_process_keeps_the_script(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, reference: dict[str, Any]
) -> None:
    blocker = tmp_path / "not-a-folder"
    blocker.write_text("")
    monkeypatch.setenv(template.CACHE_VAR, str(blocker))
    with pg_schema() as url:
        assert upgrade(url) > 50
    with pg_schema() as url:
        assert upgrade(url) < 15
        assert catalogue(url) == reference
    assert blocker.read_text() == ""


def test_downgrade_and_upgrade_from_a_script_made_schema(
    cache: Path, reference: dict[str, Any]
) -> None:
    with pg_schema() as url:
        upgrade(url)
    with pg_schema() as url:
        assert upgrade(url) < 15
        engine = make_engine(url)
        try:
            migrate.downgrade(engine, "-1")
            migrate.upgrade(engine)
            assert catalogue(url) == reference
            migrate.downgrade(engine, "base")
            assert migrate.current_revision(engine) is None
            migrate.upgrade(engine)  # not bare (an empty alembic_version): the migrations
            assert catalogue(url) == reference
        finally:
            engine.dispose()


def test_generate_refuses_what_it_would_not_make_again(cache: Path) -> None:
    """Privileges, comments (and the other kinds of ``final_state._UNSUPPORTED``) on the
    migrated schema: no script, so the migrations keep making such schemas."""
    with pg_schema() as url:
        upgrade(url, script=False)
        engine = make_engine(url)
        try:
            with engine.connect() as conn:
                assert isinstance(final_state.generate(conn), str)
                conn.rollback()
                for extra in ("COMMENT ON TABLE facts IS 'x'", "GRANT SELECT ON facts TO PUBLIC"):
                    transaction = conn.begin()
                    conn.exec_driver_sql(extra)
                    assert final_state.generate(conn) is None
                    transaction.rollback()
        finally:
            engine.dispose()


@pytest.mark.parametrize("warm", [True, False], ids=["script", "migrations"])
def test_a_role_that_may_not_create_tables_gets_one_line(cache: Path, warm: bool) -> None:
    """Without CREATE on the schema, the script (a warm cache) and the migrations (none) fail
    alike, in one line, leaving the schema bare and the script as it was."""
    if warm:
        with pg_schema() as url:
            upgrade(url)
    kept = {p.name: p.read_text() for p in cache.glob("postgresql-*.sql")}
    admin = make_engine(PG_URL)
    role = f"pgfresh_{uuid.uuid4().hex[:8]}"
    with pg_schema() as url:
        schema = url.rsplit("%3D", 1)[1]
        with admin.begin() as conn:
            conn.exec_driver_sql(f"CREATE ROLE {role} LOGIN NOSUPERUSER NOCREATEDB NOCREATEROLE")
            conn.exec_driver_sql(f'GRANT USAGE ON SCHEMA "{schema}" TO {role}')
        try:
            with pytest.raises(DatabaseOpenError, match="permission denied for schema") as err:
                toaster.connect(url.replace("postgres@", f"{role}@", 1))
            assert "\n" not in str(err.value)
            engine = make_engine(url)
            with engine.begin() as conn:
                assert final_state.bare_key(conn, migrate.head_revision()) is not None
            engine.dispose()
        finally:
            with admin.begin() as conn:
                conn.exec_driver_sql(f'REVOKE ALL ON SCHEMA "{schema}" FROM {role}')
                conn.exec_driver_sql(f"DROP ROLE {role}")
    admin.dispose()
    assert {p.name: p.read_text() for p in cache.glob("postgresql-*.sql")} == kept
    assert bool(kept) == warm


_CONNECT = "import sys, toaster; toaster.connect(sys.argv[1]).close()"


@pytest.mark.parametrize("warm", [True, False], ids=["script", "no-script-yet"])
def test_two_processes_creating_at_once_make_one_schema(
    cache: Path, reference: dict[str, Any], warm: bool
) -> None:
    """Two processes open one bare schema at once (with a script, and with none yet, where
    one migrates and both may write the script): both succeed, the schema is the migrated
    one, and the script left is whole."""
    if warm:
        with pg_schema() as url:
            upgrade(url)
    env = os.environ | {"PYTHONPATH": os.pathsep.join([str(ROOT / "src"), str(ROOT)])}
    with pg_schema() as url:
        procs = [
            subprocess.Popen([sys.executable, "-c", _CONNECT, url], env=env, cwd=ROOT)
            for _ in range(2)
        ]
        assert [p.wait(timeout=120) for p in procs] == [0, 0]
        assert catalogue(url) == reference
    with pg_schema() as url:
        final_state._memo.clear()
        assert upgrade(url) < 15  # the script the processes left
        assert catalogue(url) == reference
