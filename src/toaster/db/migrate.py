"""Alembic, driven from Python on a given connection (one code path for CLI, tests, library).

Every migration runs in one transaction that first takes the migration lock (SQLite's write
lock, a PostgreSQL advisory lock on the schema): concurrent first openings migrate once, and
a crash leaves the database as it was. A new SQLite file is built aside and moved into place
at head (:func:`create_sqlite_file`), as a copy of a migrated template when it is made at
head (:mod:`toaster.db.template`); a bare PostgreSQL schema gets the head's final-state script
(:mod:`toaster.db.final_state`).
"""

from __future__ import annotations

import contextlib
import functools
import os
import time
from collections.abc import Iterator
from importlib import resources
from pathlib import Path

from alembic import command
from alembic.config import Config
from alembic.runtime.migration import MigrationContext
from alembic.script import ScriptDirectory
from alembic.util.exc import CommandError
from sqlalchemy import Connection, Engine, inspect

from toaster.db import final_state, template
from toaster.db.engine import describe, ensure_wal, lock_timeout, make_engine
from toaster.db.schema import metadata
from toaster.errors import (
    DatabaseLockedError,
    DatabaseOpenError,
    InvalidInputError,
    SchemaOutdatedError,
)

VERSION_TABLE = "alembic_version"
_TEMP_INFIX = ".tmp-"
_SIDE_FILES = ("-wal", "-shm", "-journal")


def alembic_config(connection: Connection | None = None) -> Config:
    """An Alembic config pointing at the migrations shipped in the package."""
    config = Config()
    config.set_main_option("script_location", str(resources.files("toaster") / "migrations"))
    if connection is not None:
        config.attributes["connection"] = connection
    return config


@functools.cache
def _scripts() -> ScriptDirectory:
    """The shipped revisions, loaded once per process (Alembic compiles every file on each
    load: 20 ms a call, twice per opening)."""
    scripts = ScriptDirectory.from_config(alembic_config())
    scripts.get_current_head()  # loads the revision map now, once
    return scripts


def head_revision() -> str:
    """The newest revision this toaster knows."""
    head = _scripts().get_current_head()
    assert head is not None
    return head


def current_revision(engine: Engine) -> str | None:
    """The database's revision, or None for a database toaster never touched."""
    with engine.connect() as conn:
        return MigrationContext.configure(conn).get_current_revision()


def toaster_revision(conn: Connection, where: str) -> str | None:
    """The revision of a toaster database, None for an empty one (no table, or only an empty
    ``alembic_version``); :class:`DatabaseOpenError` for another application's database."""
    names = _relation_names(conn, where)
    revision = (
        MigrationContext.configure(conn).get_current_revision() if VERSION_TABLE in names else None
    )
    others = sorted(names - {VERSION_TABLE})
    if revision is None and others:
        listed = ", ".join(others[:5]) + (", ..." if len(others) > 5 else "")
        msg = (
            f"{where!r} is not a toaster database (it holds {listed} and no toaster "
            "revision): name a new file or an empty database"
        )
        raise DatabaseOpenError(msg)
    return revision


#: The tables and views of the current schema, and the schema (NULL: none selected).
_PG_RELATIONS = (
    "SELECT current_schema(), ARRAY(SELECT relname FROM pg_class WHERE relnamespace = "
    "(SELECT oid FROM pg_namespace WHERE nspname = current_schema()) "
    "AND relkind IN ('r', 'p', 'v', 'm', 'f'))"
)


def _relation_names(conn: Connection, where: str) -> set[str]:
    """The names of the database's tables and views (PostgreSQL: of the current schema, in
    one round trip; none selected is an error)."""
    if conn.dialect.name != "postgresql":
        inspector = inspect(conn)
        return set(inspector.get_table_names()) | set(inspector.get_view_names())
    schema, names = conn.exec_driver_sql(_PG_RELATIONS).one()
    if schema is None:
        msg = (
            f"PostgreSQL {where!r} selects no existing schema: create it or fix the URL's "
            "options=-csearch_path=SCHEMA"
        )
        raise DatabaseOpenError(msg)
    return set(names)


def is_empty(engine: Engine) -> bool:
    """True when the database holds no toaster schema and nothing else (a new file, a new
    PostgreSQL database, one downgraded to base)."""
    with engine.connect() as conn:
        inspector = inspect(conn)
        names = set(inspector.get_table_names()) | set(inspector.get_view_names())
        if not names - {VERSION_TABLE}:
            return MigrationContext.configure(conn).get_current_revision() is None
        return False


def _check_revision(revision: str) -> None:
    """A one-line error unless ``revision`` is one Alembic can go to."""
    known = _known_revisions()
    relative = revision[:1] in ("-", "+") and revision[1:].isdigit()  # -1: one step down
    if revision in known or revision in ("head", "base", "heads") or relative:
        return
    shown = ", ".join(sorted(known))
    msg = f"unknown revision {revision!r}: give one of {shown}, head, base or -N"
    raise InvalidInputError(msg)


@contextlib.contextmanager
def _revision_errors(revision: str) -> Iterator[None]:
    """Alembic's refusal of a revision it cannot go to (``+1`` at head) as one line."""
    try:
        yield
    except CommandError as exc:
        msg = (
            f"cannot migrate to {revision!r} ({str(exc).splitlines()[0]}): give head, base "
            "or a revision between them"
        )
        raise InvalidInputError(msg) from None


def upgrade(engine: Engine, revision: str = "head", *, script: bool = True) -> None:
    """Migrate the database up to ``revision``, in one transaction under the migration lock
    (a concurrent upgrade waits, then finds nothing left to do).

    A bare PostgreSQL schema going to head runs the head's final-state script instead
    (:mod:`toaster.db.final_state`; ``script=False``: the migrations always), and a schema
    that the migrations took from bare to head leaves that script for the next ones.
    """
    _check_revision(revision)
    with _migrating(engine) as conn, _revision_errors(revision):
        name = _final_state_key(conn, revision)
        if not (name and script and final_state.apply(conn, name)):
            command.upgrade(alembic_config(conn), revision)
            if name:
                final_state.save(conn, name)
        if name:  # a new schema: analyzed in the transaction that made it
            _analyze(conn)
    if not name and engine.dialect.name == "postgresql":
        with engine.begin() as conn:  # an existing database: after the commit, unlocked
            _analyze(conn)


def _final_state_key(conn: Connection, revision: str) -> str | None:
    """The final-state script's key when ``conn`` is on a bare PostgreSQL schema and
    ``revision`` is the head, else None."""
    head = head_revision()
    if conn.dialect.name != "postgresql" or revision not in ("head", head):
        return None
    return final_state.bare_key(conn, head)


def downgrade(engine: Engine, revision: str) -> None:
    """Migrate the database down to ``revision`` (``base`` removes everything)."""
    _check_revision(revision)
    with _migrating(engine) as conn, _revision_errors(revision):
        command.downgrade(alembic_config(conn), revision)


@contextlib.contextmanager
def _migrating(engine: Engine) -> Iterator[Connection]:
    """One transaction holding the migration lock, on a toaster (or empty) database; then
    SQLite's journal goes to WAL (after the check: another application's file stays as is)."""
    with engine.connect() as conn:
        conn.info["write"] = True  # SQLite: BEGIN IMMEDIATE, the write lock up front
        try:
            with conn.begin():
                if engine.dialect.name == "postgresql":
                    # Transaction-scoped: a killed migrator's lock ends with its session.
                    conn.exec_driver_sql(
                        "SELECT pg_advisory_xact_lock(hashtext('toaster migrations ' || "
                        "current_schema()))"
                    )
                toaster_revision(conn, describe(engine.url))  # refuses others' databases
                yield conn
        finally:
            conn.info["write"] = False
    ensure_wal(engine)


def _analyze(conn: Connection) -> None:
    # Fresh statistics so that PostgreSQL plans sensibly on tables that started empty: toaster's
    # own tables only (a bare ANALYZE would also sample every other schema of a shared server,
    # and record another writer's uncommitted first tick as empty tables).
    if conn.dialect.name == "postgresql":
        present = set(conn.dialect.get_table_names(conn))
        names = [t.name for t in metadata.sorted_tables if t.name in present]
        if names:
            conn.exec_driver_sql("ANALYZE " + ", ".join(f'"{n}"' for n in names))


def is_new_file(path: Path) -> bool:
    """True when no SQLite database is at ``path``: no file, or an empty one (left by a crash
    or ``touch``) whose write-ahead log is empty too."""
    try:
        if path.stat().st_size > 0:
            return False
    except FileNotFoundError:
        return True
    wal = Path(f"{path}-wal")
    return not wal.exists() or wal.stat().st_size == 0


def create_sqlite_file(path: Path, revision: str = "head") -> bool:
    """Make a new SQLite database at ``path``, migrated to ``revision``, atomically.

    It is built in a hidden file of the same folder (``.NAME.tmp-PID``) and moved onto
    ``path`` once migrated, under a lock on the folder: a crash leaves no half-made database
    at ``path`` (its leftover is removed by the next creation). False when another process
    made the database meanwhile (theirs is kept).
    """
    folder = path.resolve().parent
    try:
        with _folder_lock(folder, path):
            if not is_new_file(path):
                return False
            for stale in folder.glob(f".{path.name}{_TEMP_INFIX}*"):
                stale.unlink(missing_ok=True)
            temp = folder / f".{path.name}{_TEMP_INFIX}{os.getpid()}"
            try:
                if not _from_template(temp, revision):
                    _build(temp, revision)
                for suffix in _SIDE_FILES:  # a deleted database's log must not replay on ours
                    Path(f"{path}{suffix}").unlink(missing_ok=True)
                os.replace(temp, path)
                _fsync(folder)
            finally:
                for leftover in (temp, *(Path(f"{temp}{s}") for s in _SIDE_FILES)):
                    leftover.unlink(missing_ok=True)
    except OSError as exc:
        msg = (
            f"cannot create SQLite database {str(path)!r} ({exc.strerror or exc}): check "
            f"that folder {str(folder)!r} is writable"
        )
        raise DatabaseOpenError(msg) from None
    return True


def _build(temp: Path, revision: str) -> None:
    engine = make_engine(f"sqlite:///{temp}")
    try:
        upgrade(engine, revision)
    finally:
        engine.dispose()  # the last connection closed: SQLite removes -wal and -shm
    wal = Path(f"{temp}-wal")
    if wal.exists() and wal.stat().st_size > 0:
        msg = f"cannot create SQLite database {str(temp)!r}: its log could not be checkpointed"
        raise DatabaseOpenError(msg)
    _fsync(temp)


def _from_template(temp: Path, revision: str) -> bool:
    """Make ``temp`` a copy of the head's template (:mod:`toaster.db.template`); False when
    ``revision`` is not the head or no template can be had."""
    head = head_revision()
    if revision not in ("head", head):
        return False
    source = template.template(head, lambda build: _build(build, head))
    if source is None or not template.copy_template(source, temp):
        return False
    _fsync(temp)
    return True


def _fsync(path: Path) -> None:
    fd = os.open(path, os.O_RDONLY)
    try:
        os.fsync(fd)
    finally:
        os.close(fd)


@contextlib.contextmanager
def _folder_lock(folder: Path, path: Path) -> Iterator[None]:
    """An exclusive ``flock`` on the folder, released by the kernel if the process dies."""
    try:
        import fcntl
    except ImportError:  # not POSIX: no lock (the existence check still guards most races)
        yield
        return
    fd = os.open(folder, os.O_RDONLY)
    try:
        timeout = lock_timeout()
        deadline = time.monotonic() + timeout
        while True:
            try:
                fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
                break
            except BlockingIOError:
                if time.monotonic() > deadline:
                    msg = (
                        f"database {str(path)!r} is being created by another process "
                        f"(waited {timeout:g} s): retry, or wait longer with "
                        "TOASTER_LOCK_TIMEOUT=SECONDS"
                    )
                    raise DatabaseLockedError(msg) from None
                time.sleep(0.02)
        yield
    finally:
        os.close(fd)  # releases the lock


def check_at_head(engine: Engine, *, url_hint: str = "") -> None:
    """Raise :class:`SchemaOutdatedError` with the fix when the database is not at head."""
    current = current_revision(engine)
    head = head_revision()
    if current == head:
        return
    where = f" --db {url_hint}" if url_hint else ""
    if current is None:
        msg = (
            f"database has no toaster schema (this toaster expects revision {head}): "
            f"run `toaster db upgrade{where}`"
        )
    elif current in _known_revisions():
        msg = (
            f"database is at revision {current}, this toaster expects {head}: "
            f"run `toaster db upgrade{where}`"
        )
    else:
        msg = (
            f"database is at revision {current}, which this toaster does not know "
            f"(it expects {head}): it was written by a newer toaster; upgrade toaster"
        )
    raise SchemaOutdatedError(msg)


def _known_revisions() -> set[str]:
    return {rev.revision for rev in _scripts().walk_revisions()}
