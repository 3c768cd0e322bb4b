"""Engines for the two backends: URL normalisation and per-connection settings."""

from __future__ import annotations

import os
from pathlib import Path

from sqlalchemy import Engine, create_engine, event
from sqlalchemy.engine import make_url
from sqlalchemy.exc import ArgumentError

from toaster.errors import InvalidInputError

DEFAULT_SQLITE_FILE = "toaster.db"
ENV_VAR = "TOASTER_DB"


def default_url() -> str:
    """``$TOASTER_DB`` or a SQLite file ``toaster.db`` in the working directory."""
    return os.environ.get(ENV_VAR) or f"sqlite:///{DEFAULT_SQLITE_FILE}"


def normalise_url(url: str) -> str:
    """Accept bare ``postgresql://`` / ``postgres://`` URLs and plain file paths.

    ``postgresql://`` is mapped to the psycopg 3 driver explicitly (SQLAlchemy 2.0 would pick
    psycopg2); a path ending in ``.db``/``.sqlite`` becomes a SQLite URL.
    """
    if "://" not in url:
        if url.endswith((".db", ".sqlite", ".sqlite3")) or url == ":memory:":
            return f"sqlite:///{url}"
        msg = f"invalid database URL {url!r}: use sqlite:///FILE.db or postgresql://HOST/DB"
        raise InvalidInputError(msg)
    for bare in ("postgresql://", "postgres://"):
        if url.startswith(bare):
            return "postgresql+psycopg://" + url[len(bare):]
    return url


def make_engine(url: str | None = None) -> Engine:
    """Create the engine for ``url`` (default: :func:`default_url`)."""
    raw = normalise_url(url or default_url())
    try:
        parsed = make_url(raw)
    except ArgumentError:
        msg = f"invalid database URL {raw!r}: use sqlite:///FILE.db or postgresql://HOST/DB"
        raise InvalidInputError(msg) from None
    backend = parsed.get_backend_name()
    if backend == "sqlite":
        return _sqlite_engine(parsed)
    if backend == "postgresql":
        return _postgresql_engine(parsed)
    msg = f"unsupported database {backend!r} in {raw!r}: toaster runs on SQLite and PostgreSQL"
    raise InvalidInputError(msg)


def _postgresql_engine(url) -> Engine:
    engine = create_engine(url, pool_pre_ping=True, pool_size=2, max_overflow=4)

    @event.listens_for(engine, "connect")
    def _on_connect(dbapi_connection, _record) -> None:
        # The belief rules' recursive queries have huge cost estimates, which make PostgreSQL
        # JIT-compile them: seconds of compilation for milliseconds of work. Short statements
        # never gain from JIT.
        with dbapi_connection.cursor() as cursor:
            cursor.execute("SET jit = off")
        dbapi_connection.commit()

    return engine


def _sqlite_engine(url) -> Engine:
    database = url.database or ""
    if database and database != ":memory:" and not database.startswith("file:"):
        parent = Path(database).expanduser().resolve().parent
        if not parent.is_dir():
            msg = (f"cannot create SQLite database {database!r}: "
                   f"folder {str(parent)!r} does not exist")
            raise InvalidInputError(msg)
    engine = create_engine(url)

    @event.listens_for(engine, "connect")
    def _on_connect(dbapi_connection, _record) -> None:
        # Let SQLAlchemy emit BEGIN itself (the driver's implicit transactions are off).
        dbapi_connection.isolation_level = None
        cursor = dbapi_connection.cursor()
        cursor.execute("PRAGMA foreign_keys=ON")
        cursor.execute("PRAGMA busy_timeout=10000")
        if database and database != ":memory:":
            cursor.execute("PRAGMA journal_mode=WAL")
            cursor.execute("PRAGMA synchronous=NORMAL")
            # A producer tick dirties pages of ~10 indexes at random: a 64 MB page cache (not
            # 2 MB) and a checkpoint every 8,000 WAL pages (not 1,000, so not every tick) took
            # a 400-person crowd tick from 145 to 103 ms (bench_run.py, "400 at once").
            cursor.execute("PRAGMA cache_size=-65536")
            cursor.execute("PRAGMA wal_autocheckpoint=8000")
            cursor.execute("PRAGMA temp_store=MEMORY")
        cursor.close()

    @event.listens_for(engine, "begin")
    def _on_begin(conn) -> None:
        conn.exec_driver_sql("BEGIN IMMEDIATE" if conn.info.get("write", False) else "BEGIN")

    return engine
