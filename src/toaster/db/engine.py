"""Engines for the two backends: URL checks, per-connection settings, one-line errors.

Every database error a user can cause (an unreachable server, a file that is no database, a
lock held too long) is turned into a :class:`~toaster.errors.ToasterError` here, by the
engine's ``handle_error`` event, wherever the statement ran (see :func:`database_error`).
"""

from __future__ import annotations

import math
import os
import sqlite3
from pathlib import Path
from typing import TYPE_CHECKING, cast

from sqlalchemy import URL, Connection, Engine, create_engine, event
from sqlalchemy.engine import ExceptionContext, make_url
from sqlalchemy.exc import ArgumentError

from toaster.errors import (
    DatabaseLockedError,
    DatabaseOpenError,
    InvalidInputError,
    ReadOnlyError,
    ToasterError,
)
from toaster.model import check_text, shown

if TYPE_CHECKING:
    import psycopg
    from sqlalchemy.engine.interfaces import DBAPIConnection
    from sqlalchemy.pool import ConnectionPoolEntry

DEFAULT_SQLITE_FILE = "toaster.db"
ENV_VAR = "TOASTER_DB"
#: How long a statement waits for another process's lock before failing (seconds).
LOCK_TIMEOUT_VAR = "TOASTER_LOCK_TIMEOUT"
DEFAULT_LOCK_TIMEOUT_S = 10.0
#: How long connecting to a PostgreSQL server may take (a URL's connect_timeout wins).
CONNECT_TIMEOUT_S = 10
#: libpq's TCP settings for a lost peer (a cut cable, a server host powered off, a roaming
#: robot): without them an idle connection waits for the kernel's two hours and a reply never
#: sent holds a tick for ~15 minutes of retransmissions. Probes after 10 s idle, every 5 s,
#: 3 unanswered: ~25 s; data unacknowledged for 30 s drops the connection. A URL's own win.
TCP_SETTINGS: dict[str, int] = {
    "keepalives": 1,
    "keepalives_idle": 10,
    "keepalives_interval": 5,
    "keepalives_count": 3,
    "tcp_user_timeout": 30_000,
}
_FORMS = "use sqlite:///FILE.db or postgresql://HOST/DBNAME"
_DRIVERS = {"sqlite": "pysqlite", "postgresql": "psycopg"}


def default_url() -> str:
    """``$TOASTER_DB`` or a SQLite file ``toaster.db`` in the working directory."""
    return os.environ.get(ENV_VAR) or f"sqlite:///{DEFAULT_SQLITE_FILE}"


def lock_timeout() -> float:
    """``$TOASTER_LOCK_TIMEOUT`` seconds (default :data:`DEFAULT_LOCK_TIMEOUT_S`)."""
    raw = os.environ.get(LOCK_TIMEOUT_VAR, "").strip()
    if not raw:
        return DEFAULT_LOCK_TIMEOUT_S
    try:
        value = float(raw)
    except ValueError:
        value = math.nan
    if not (math.isfinite(value) and value > 0):
        msg = (
            f"{LOCK_TIMEOUT_VAR}={raw!r} is not a number of seconds > 0: set e.g. "
            f"{LOCK_TIMEOUT_VAR}=10"
        )
        raise InvalidInputError(msg)
    return value


def normalise_url(url: str) -> str:
    """Accept bare ``postgresql://`` / ``postgres://`` URLs and plain file paths.

    ``postgresql://`` is mapped to the psycopg 3 driver explicitly (SQLAlchemy 2.0 would pick
    psycopg2); a path ending in ``.db``/``.sqlite`` becomes a SQLite URL.
    """
    if "://" not in url:
        if url.endswith((".db", ".sqlite", ".sqlite3")) or url == ":memory:":
            return f"sqlite:///{url}"
        msg = f"invalid database URL {url!r}: {_FORMS}"
        raise InvalidInputError(msg)
    for bare in ("postgresql://", "postgres://"):
        if url.startswith(bare):
            return "postgresql+psycopg://" + url[len(bare) :]
    return url


def check_url(url: object) -> str:
    """``url`` if it is text that may name a database: not empty (an empty ``--db`` is a
    mistake, not the default), no NUL, valid UTF-8; else a one-line error."""
    if not isinstance(url, str):
        msg = f"invalid database URL {shown(url)}: give text, e.g. sqlite:///toaster.db"
        raise InvalidInputError(msg)
    if not url.strip():
        msg = (
            f"empty database URL {url!r}: give one ({_FORMS}), or leave --db and "
            f"${ENV_VAR} out for sqlite:///{DEFAULT_SQLITE_FILE}"
        )
        raise InvalidInputError(msg)
    return check_text(url, "database URL")


def parse_url(url: str | None = None, *, allow_memory: bool = False) -> URL:
    """The checked URL of ``url`` (default :func:`default_url`).

    Refused with :class:`~toaster.errors.InvalidInputError`: SQLite URLs that keep nothing
    (``sqlite://``, ``:memory:``; unless ``allow_memory``), name a folder or a missing folder,
    or carry options; PostgreSQL URLs that name no database or carry an option libpq does not
    know; other databases and drivers.
    """
    raw = normalise_url(default_url() if url is None else check_url(url))
    try:
        parsed = make_url(raw)
    except ArgumentError:
        msg = f"invalid database URL {raw!r}: {_FORMS}"
        raise InvalidInputError(msg) from None
    backend = parsed.get_backend_name()
    if backend not in _DRIVERS:
        msg = f"unsupported database {backend!r} in {raw!r}: toaster runs on SQLite and PostgreSQL"
        raise InvalidInputError(msg)
    if parsed.get_driver_name() != _DRIVERS[backend]:
        msg = (
            f"unsupported driver {parsed.get_driver_name()!r} in {describe(parsed)!r}: "
            f"{_FORMS} (toaster uses {_DRIVERS[backend]})"
        )
        raise InvalidInputError(msg)
    if backend == "sqlite":
        _check_sqlite(parsed, raw, allow_memory)
    else:
        _check_postgresql(parsed)
    return parsed


def describe(url: URL) -> str:
    """How messages name a database: the SQLite file, or the URL without its password."""
    if url.get_backend_name() == "sqlite" and url.database:
        return url.database
    return url.set(drivername=url.get_backend_name()).render_as_string(hide_password=True)


def sqlite_file(url: URL) -> Path | None:
    """The file of a SQLite URL (None for PostgreSQL and in-memory SQLite)."""
    if url.get_backend_name() != "sqlite" or is_memory(url):
        return None
    return Path(url.database or "")


def is_memory(url: URL) -> bool:
    """True for SQLite URLs that keep nothing (``sqlite://``, ``sqlite:///:memory:``)."""
    return url.get_backend_name() == "sqlite" and (url.database or "") in ("", ":memory:")


def _check_sqlite(url: URL, shown: str, allow_memory: bool) -> None:
    database = url.database or ""
    if url.query:
        msg = (
            f"SQLite URL {shown!r} takes no options (got {', '.join(url.query)}): "
            "use sqlite:///FILE.db"
        )
        raise InvalidInputError(msg)
    if is_memory(url):
        if allow_memory:
            return
        msg = (
            f"{shown!r} is an in-memory database, which keeps nothing: "
            f"name a file, e.g. sqlite:///{DEFAULT_SQLITE_FILE}"
        )
        raise InvalidInputError(msg)
    if database.startswith("file:"):
        msg = f"SQLite URI filenames are not supported ({shown!r}): use sqlite:///FILE.db"
        raise InvalidInputError(msg)
    path = Path(database)
    if path.is_dir():
        msg = (
            f"SQLite database {database!r} is a folder: name a file in it, "
            f"e.g. sqlite:///{path / DEFAULT_SQLITE_FILE}"
        )
        raise InvalidInputError(msg)
    if path.exists() and not path.is_file():
        msg = f"SQLite database {database!r} is not a regular file: name a file"
        raise InvalidInputError(msg)
    parent = path.resolve().parent
    if not parent.is_dir():
        msg = f"cannot create SQLite database {database!r}: folder {str(parent)!r} does not exist"
        raise InvalidInputError(msg)


def _check_postgresql(url: URL) -> None:
    shown = describe(url)
    if not (url.database or url.query.get("dbname")):
        msg = (
            f"PostgreSQL URL {shown!r} names no database (the server would pick one): "
            "use postgresql://HOST/DBNAME"
        )
        raise InvalidInputError(msg)
    from psycopg import pq

    known = {option.keyword.decode() for option in pq.Conninfo.get_defaults()}
    for name in url.query:
        if name not in known:
            msg = (
                f"unknown PostgreSQL URL option {name!r} in {shown!r}: use libpq's "
                "connection options (e.g. sslmode, connect_timeout, options)"
            )
            raise InvalidInputError(msg)


def make_engine(url: str | None = None, *, allow_memory: bool = False) -> Engine:
    """Create the engine for ``url`` (default: :func:`default_url`), checked by
    :func:`parse_url`. A SQLite file is created on first connection if missing (use
    :func:`toaster.db.database.open_engine` for an atomic creation)."""
    parsed = parse_url(url, allow_memory=allow_memory)
    timeout = lock_timeout()
    if parsed.get_backend_name() == "sqlite":
        engine = _sqlite_engine(parsed, timeout)
    else:
        engine = _postgresql_engine(parsed, timeout)
    where = describe(parsed)

    @event.listens_for(engine, "handle_error")
    def _on_error(context: ExceptionContext) -> BaseException | None:
        if context.is_pre_ping:  # let the pool reconnect
            return None
        conn = context.connection
        raw = None if conn is None or conn.invalidated else conn.connection.dbapi_connection
        return database_error(context.original_exception, where, timeout, raw)

    return engine


def _postgresql_engine(url: URL, timeout: float) -> Engine:
    defaults = {"connect_timeout": CONNECT_TIMEOUT_S, **TCP_SETTINGS}
    connect_args = {key: value for key, value in defaults.items() if key not in url.query}
    engine = create_engine(
        url, pool_pre_ping=True, pool_size=2, max_overflow=4, connect_args=connect_args
    )

    @event.listens_for(engine, "connect")
    def _on_connect(dbapi_connection: psycopg.Connection, _record: ConnectionPoolEntry) -> None:
        with dbapi_connection.cursor() as cursor:
            # The belief rules' recursive queries have huge cost estimates, which make
            # PostgreSQL JIT-compile them: seconds of compilation for milliseconds of work.
            # Short statements never gain from JIT.
            cursor.execute("SET jit = off")
            cursor.execute(f"SET lock_timeout = '{max(1, round(timeout * 1000))}ms'")
        dbapi_connection.commit()

    return engine


def _sqlite_engine(url: URL, timeout: float) -> Engine:
    on_disk = not is_memory(url)
    engine = create_engine(url, connect_args={"timeout": timeout})

    @event.listens_for(engine, "connect")
    def _on_connect(dbapi_connection: sqlite3.Connection, _record: ConnectionPoolEntry) -> None:
        # Let SQLAlchemy emit BEGIN itself (the driver's implicit transactions are off).
        # Nothing here writes to the file: the journal mode (WAL) is set by the migrations
        # and by open_engine, on toaster's databases only.
        dbapi_connection.isolation_level = None
        cursor = dbapi_connection.cursor()
        cursor.execute("PRAGMA foreign_keys=ON")
        cursor.execute(f"PRAGMA busy_timeout={max(1, round(timeout * 1000))}")
        if on_disk:
            cursor.execute("PRAGMA synchronous=NORMAL")
            # A producer tick dirties pages of ~10 indexes at random: a 64 MB page cache (not
            # 2 MB) and a checkpoint every 8,000 WAL pages (not 1,000, so not every tick) make a
            # crowd's ticks shorter (docs/producers.md, "Keeping up with a scene").
            cursor.execute("PRAGMA cache_size=-65536")
            cursor.execute("PRAGMA wal_autocheckpoint=8000")
            cursor.execute("PRAGMA temp_store=MEMORY")
        cursor.close()

    @event.listens_for(engine, "begin")
    def _on_begin(conn: Connection) -> None:
        conn.exec_driver_sql("BEGIN IMMEDIATE" if conn.info.get("write", False) else "BEGIN")

    return engine


def database_error(
    exc: BaseException, where: str, timeout_s: float, raw: object = None
) -> ToasterError | None:
    """The one-line :class:`~toaster.errors.ToasterError` for a driver error ``exc`` (or a
    SQLAlchemy error wrapping one) on database ``where`` (``raw``: the driver's connection,
    if known); None for errors that are not the user's (bugs keep their traceback) or that
    the caller handles (write conflicts)."""
    orig = getattr(exc, "orig", None) or exc
    reason = (str(orig).strip().splitlines() or [type(orig).__name__])[0]
    name = getattr(orig, "sqlite_errorname", None)
    if isinstance(name, str):
        return _sqlite_error(name, reason, where, timeout_s)
    if type(orig).__module__.split(".")[0] != "psycopg":
        return None
    sqlstate = getattr(orig, "sqlstate", None)
    if sqlstate == "55P03":  # lock_not_available: lock_timeout expired
        return _locked(where, timeout_s, "another session")
    if sqlstate is None and type(orig).__name__ == "OperationalError":
        reason = reason.removeprefix("connection failed: ")
        return DatabaseOpenError(
            f"cannot connect to PostgreSQL {where!r} ({reason}): check that the server runs "
            "and the URL's host, port, user and database"
        )
    if sqlstate == "25006":  # read_only_sql_transaction: a hot standby, or a read-only session
        return read_only_error(orig, where, raw)
    if sqlstate == "3F000":  # invalid_schema_name
        return DatabaseOpenError(
            f"PostgreSQL {where!r} has no schema to use ({reason}): create the schema or "
            "fix the URL's search_path"
        )
    return None


def read_only_error(exc: BaseException, where: str, raw: object = None) -> ReadOnlyError | None:
    """The one line of a statement refused because PostgreSQL ``where`` is read-only
    (SQLSTATE 25006: a hot standby, told by ``raw``, the driver's connection, or by the
    reason; or a read-only session), naming the fix; None for any other error."""
    orig = getattr(exc, "orig", None) or exc
    if getattr(orig, "sqlstate", None) != "25006":
        return None
    reason = (str(orig).strip().splitlines() or [type(orig).__name__])[0]
    status = getattr(getattr(raw, "info", None), "parameter_status", None)
    # in_hot_standby is reported by PostgreSQL 14+; "during recovery" by any standby.
    if "during recovery" in reason or (status is not None and status("in_hot_standby") == "on"):
        return ReadOnlyError(
            f"PostgreSQL {where!r} is a hot standby (a read-only replica) and refused this "
            f"({reason}): run it on the primary (docs/databases.md, Beyond one server)"
        )
    return ReadOnlyError(
        f"PostgreSQL {where!r} is read-only and refused this ({reason}): run it on the "
        "primary if this is a hot standby (docs/databases.md), else turn "
        "default_transaction_read_only off"
    )


#: SQLSTATE of a unique key another writer inserted meanwhile: a conflict the store retries,
#: not a refused value (:func:`refused_value`).
_UNIQUE_CONFLICT = "23505"


def refused_value(exc: BaseException) -> InvalidInputError | None:
    """The one-line error of a value the database or its driver cannot take (``exc``, raised
    by a statement of a transaction now rolled back); None for any other error.

    These are values no check of the caller's stopped: integers past 64 bits, text that is
    not UTF-8, a type the driver cannot bind, a constraint the schema enforces (SQLSTATE
    classes 22 and 23 on PostgreSQL, SQLite's integrity errors). A unique key taken by a
    concurrent writer is a conflict the store retries, not a refused value.
    """
    orig = getattr(exc, "orig", None) or exc
    reason = (str(orig).strip().splitlines() or [type(orig).__name__])[0]
    if isinstance(orig, OverflowError):
        return InvalidInputError(
            f"a number the database cannot hold ({reason}): integers and "
            "times in ns go up to 2^63-1 (rolled back, nothing written)"
        )
    if isinstance(orig, UnicodeEncodeError):
        return InvalidInputError(
            f"text the database cannot hold ({reason}): give valid UTF-8 "
            "text (rolled back, nothing written)"
        )
    if _refused_by_database(orig, reason):
        return InvalidInputError(
            f"the database refused a value ({reason}): check the values "
            "given (rolled back, nothing written)"
        )
    return None


def _refused_by_database(orig: BaseException, reason: str) -> bool:
    """A constraint or data error (a value), or a value the driver cannot bind."""
    if isinstance(orig, sqlite3.IntegrityError | sqlite3.DataError):
        return True
    if isinstance(orig, sqlite3.ProgrammingError | sqlite3.InterfaceError):
        return reason.startswith(("Error binding parameter", "Incorrect number of bindings"))
    if type(orig).__module__.split(".")[0] != "psycopg":
        return False
    sqlstate = getattr(orig, "sqlstate", None)
    if sqlstate is None:  # refused by psycopg before sending (NUL in text, a Python type)
        kind = type(orig).__name__
        return kind == "DataError" or (
            kind == "ProgrammingError" and reason.startswith("cannot adapt type")
        )
    return sqlstate[:2] in ("22", "23") and sqlstate != _UNIQUE_CONFLICT


def _sqlite_error(name: str, reason: str, where: str, timeout_s: float) -> ToasterError | None:
    if name.startswith("SQLITE_BUSY"):
        return _locked(where, timeout_s, "another process")
    if name.startswith(("SQLITE_NOTADB", "SQLITE_CORRUPT")):
        return DatabaseOpenError(
            f"{where!r} is not a SQLite database or is corrupted ({reason}): restore it from "
            "a backup, or name another file (a new one is created)"
        )
    if name.startswith(("SQLITE_CANTOPEN", "SQLITE_PERM", "SQLITE_AUTH")):
        return DatabaseOpenError(
            f"cannot open SQLite database {where!r} ({reason}): check that the file and its "
            "folder exist and that you may read and write them"
        )
    if name.startswith("SQLITE_READONLY"):
        return DatabaseOpenError(
            f"cannot write SQLite database {where!r} ({reason}): make the file and its "
            "folder writable"
        )
    if name.startswith(("SQLITE_FULL", "SQLITE_IOERR")):
        return DatabaseOpenError(
            f"cannot write SQLite database {where!r} ({reason}): check the disk (free space, "
            "errors)"
        )
    return None


def _locked(where: str, timeout_s: float, holder: str) -> DatabaseLockedError:
    return DatabaseLockedError(
        f"database {where!r} is locked by {holder} (waited {timeout_s:g} s): the statement "
        f"was rolled back; retry when it is free, or wait longer with "
        f"{LOCK_TIMEOUT_VAR}=SECONDS"
    )


def dbapi(conn: Connection) -> DBAPIConnection:
    """The driver's connection under ``conn`` (sqlite3 or psycopg). SQLAlchemy types it
    Optional: it is None only once ``conn`` is closed or invalidated, never while in use."""
    return cast("DBAPIConnection", conn.connection.dbapi_connection)


def ensure_wal(engine: Engine) -> None:
    """Put a SQLite file in WAL mode (kept in the file: readers never wait for the writer).

    Done when toaster creates, migrates or opens its own database, never on connection: a
    file that turns out not to be toaster's is left as it was.
    """
    if engine.dialect.name != "sqlite" or is_memory(engine.url):
        return
    raw = engine.raw_connection()  # connection errors are translated by handle_error
    try:
        cursor = raw.cursor()
        if cursor.execute("PRAGMA journal_mode").fetchone()[0] != "wal":
            cursor.execute("PRAGMA journal_mode=WAL")
        cursor.close()
    except sqlite3.Error as exc:
        error = database_error(exc, describe(engine.url), lock_timeout())
        if error is None:
            raise
        raise error from None
    finally:
        raw.close()
