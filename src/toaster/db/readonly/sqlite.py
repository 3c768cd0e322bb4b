"""The SQLite guard: ``PRAGMA query_only``, an authorizer, length, heap and time limits for
one statement, checks after it, then a rollback whatever happened."""

from __future__ import annotations

import functools
import sqlite3
import time
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any

from toaster.db.readonly.bounds import (
    Limits,
    ReadResult,
    first_line,
    require_own_transaction,
    timeout_error,
    too_big_error,
)
from toaster.db.readonly.tokens import SQLITE_CALLS, check_statement
from toaster.errors import ReadOnlyError, ToasterError

#: SQLite's heap limit (process-wide) while a read-only statement runs.
SQLITE_HEAP_LIMIT = 2**30
_SQLITE_ALLOWED = {sqlite3.SQLITE_SELECT, sqlite3.SQLITE_READ, sqlite3.SQLITE_FUNCTION,
                   sqlite3.SQLITE_RECURSIVE}
#: Pragmas that only read, whatever their argument (a table or index name).
_PRAGMAS_ANY = frozenset((
    "table_info", "table_xinfo", "table_list", "index_list", "index_info", "index_xinfo",
    "foreign_key_list", "foreign_key_check", "integrity_check", "quick_check",
    "collation_list", "function_list", "module_list", "pragma_list", "database_list",
    "compile_options"))
#: Pragmas that read without an argument (with one, they write).
_PRAGMAS_READ = frozenset((
    "application_id", "auto_vacuum", "busy_timeout", "cache_size", "data_version", "encoding",
    "foreign_keys", "freelist_count", "journal_mode", "page_count", "page_size", "query_only",
    "schema_version", "synchronous", "temp_store", "user_version", "max_page_count"))
#: Authorizer action codes, named for messages.
_SQLITE_ACTIONS = {getattr(sqlite3, f"SQLITE_{name}"): name.replace("_", " ") for name in (
    "ALTER_TABLE", "ANALYZE", "ATTACH", "CREATE_INDEX", "CREATE_TABLE", "CREATE_TEMP_INDEX",
    "CREATE_TEMP_TABLE", "CREATE_TEMP_TRIGGER", "CREATE_TEMP_VIEW", "CREATE_TRIGGER",
    "CREATE_VIEW", "CREATE_VTABLE", "DELETE", "DETACH", "DROP_INDEX", "DROP_TABLE",
    "DROP_TEMP_INDEX", "DROP_TEMP_TABLE", "DROP_TEMP_TRIGGER", "DROP_TEMP_VIEW", "DROP_TRIGGER",
    "DROP_VIEW", "DROP_VTABLE", "FUNCTION", "INSERT", "PRAGMA", "REINDEX", "SAVEPOINT",
    "TRANSACTION", "UPDATE")}


def run_sqlite(db: Any, sql: str, params: Any, bounds: Limits) -> ReadResult:
    """Run one read statement on SQLite (see the module's doc); roll back whatever happens."""
    check_statement(sql, "sqlite")
    conn = db.connection
    require_own_transaction(conn)
    raw = conn.connection.dbapi_connection
    refused: list[str] = []
    conn.info["write"] = False
    trans = conn.begin()
    try:
        cur = raw.cursor()
        db.backend.set_read_only(cur)
        changes = raw.total_changes
        with _sqlite_guard(raw, cur, bounds, refused):
            columns, rows, truncated = _sqlite_fetch(raw.cursor(), sql, params, bounds,
                                                     refused)
        query_only = cur.execute("PRAGMA query_only").fetchone()[0]
        if not raw.in_transaction or raw.total_changes != changes or query_only != 1:
            msg = ("statement refused: it ended its transaction or changed the database "
                   "(rolled back): rerun with --write")
            raise ReadOnlyError(msg)
        return ReadResult(columns, rows, truncated)
    finally:
        try:
            db.backend.clear_read_only(raw.cursor())
        finally:
            trans.rollback()


@contextmanager
def _sqlite_guard(raw: Any, cur: Any, bounds: Limits, refused: list[str]) -> Iterator[None]:
    """The authorizer, the length and heap limits and the deadline, for one statement."""
    heap = _hard_heap_limit(cur, -1)
    if heap == 0 or heap > SQLITE_HEAP_LIMIT:
        _hard_heap_limit(cur, SQLITE_HEAP_LIMIT)
    length = raw.getlimit(sqlite3.SQLITE_LIMIT_LENGTH)
    raw.setlimit(sqlite3.SQLITE_LIMIT_LENGTH, min(length, max(bounds.max_bytes, 2**20)))
    deadline = time.monotonic() + bounds.timeout_s

    def authorize(action: int, arg1: str | None, arg2: str | None, *_: Any) -> int:
        if action in _SQLITE_ALLOWED and not (
                action == sqlite3.SQLITE_FUNCTION and (arg2 or "").lower() in SQLITE_CALLS):
            return sqlite3.SQLITE_OK
        if action == sqlite3.SQLITE_PRAGMA and ((arg1 or "").lower() in _PRAGMAS_ANY or (
                arg2 is None and (arg1 or "").lower() in _PRAGMAS_READ)):
            return sqlite3.SQLITE_OK
        if action == sqlite3.SQLITE_UPDATE and arg1 == "sqlite_master":
            # SQLite's own nested statement on first use of a pragma table-valued function
            # (pragma_table_info): IGNORE leaves the column unchanged.
            return sqlite3.SQLITE_IGNORE
        what = _SQLITE_ACTIONS.get(action, f"action {action}")
        detail = " ".join(str(a) for a in (arg1, arg2) if a is not None)
        refused.append(f"{what} {detail}".strip())
        return sqlite3.SQLITE_DENY

    raw.set_progress_handler(lambda: int(time.monotonic() > deadline), 10_000)
    raw.set_authorizer(authorize)  # expires prepared statements: all are authorized again
    try:
        yield
    finally:
        raw.set_authorizer(None)
        raw.set_progress_handler(None, 0)
        raw.setlimit(sqlite3.SQLITE_LIMIT_LENGTH, length)
        _hard_heap_limit(cur, heap)


@functools.cache
def _heap_function() -> Any:
    """``sqlite3_hard_heap_limit64`` of the SQLite library Python uses (None if hidden)."""
    try:
        import _sqlite3
        import ctypes

        function = ctypes.CDLL(_sqlite3.__file__).sqlite3_hard_heap_limit64
    except (ImportError, OSError, AttributeError):
        return None
    function.restype, function.argtypes = ctypes.c_int64, [ctypes.c_int64]
    return function


def _hard_heap_limit(cur: Any, limit: int) -> int:
    """Set SQLite's process-wide heap limit (0: none, < 0: only ask); return the previous.

    ``PRAGMA hard_heap_limit`` can only lower it, so it is set through the C function when
    reachable (else the pragma lowers it for good)."""
    function = _heap_function()
    if function is not None:
        return int(function(limit))
    previous = int(cur.execute("PRAGMA hard_heap_limit").fetchone()[0])
    if limit > 0:
        cur.execute(f"PRAGMA hard_heap_limit = {int(limit)}")
    return previous


def _sqlite_fetch(cur: Any, sql: str, params: Any, bounds: Limits,
                  refused: list[str]) -> tuple[list[str], list[tuple[Any, ...]], bool]:
    try:
        cur.execute(sql, params or ())
        columns = [d[0] for d in cur.description] if cur.description else []
        rows: list[tuple[Any, ...]] = []
        size = 0
        while columns and len(rows) <= bounds.max_rows:
            batch = cur.fetchmany(min(1000, bounds.max_rows + 1 - len(rows)))
            if not batch:
                break
            for row in batch:
                size += sum(len(v) if isinstance(v, str | bytes) else 8 for v in row)
                if size > bounds.max_bytes:
                    raise too_big_error(bounds)
            rows.extend(tuple(r) for r in batch)
    except MemoryError:
        msg = (f"SQL error: the statement needs more than {SQLITE_HEAP_LIMIT >> 20} MiB of "
               "memory (read-only SQL's bound): narrow it (WHERE, LIMIT)")
        raise ToasterError(msg) from None
    except sqlite3.Error as exc:
        raise _sqlite_error(exc, refused, bounds) from None
    except (ValueError, OverflowError) as exc:  # text that is not UTF-8, huge integers
        msg = f"SQL error: {first_line(exc)}"
        raise ToasterError(msg) from None
    finally:
        cur.close()
    truncated = len(rows) > bounds.max_rows
    return columns, rows[:bounds.max_rows], truncated


def _sqlite_error(exc: sqlite3.Error, refused: list[str], bounds: Limits) -> ToasterError:
    name = getattr(exc, "sqlite_errorname", "")
    reason = first_line(exc)
    if refused or name == "SQLITE_AUTH":
        what = refused[0] if refused else reason
        return ReadOnlyError(f"statement refused, read-only SQL does not allow {what}: "
                             "rerun with --write")
    if name == "SQLITE_READONLY":
        return ReadOnlyError(f"statement refused, the database is opened read-only: rerun "
                             f"with --write ({reason})")
    if name == "SQLITE_INTERRUPT":
        return timeout_error(bounds)
    if name == "SQLITE_TOOBIG":
        return ToasterError(f"SQL error: a value is larger than read-only SQL allows "
                            f"({reason}): select less, or raise --max-bytes")
    return ToasterError(f"SQL error: {reason}")

