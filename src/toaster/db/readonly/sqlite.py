"""The SQLite guard: read statements run in a worker process, killed at the deadline.

SQLite checks for interrupts (and calls progress handlers) only between steps of its
virtual machine, never inside one function call: ``instr()`` of a 4 MiB text in a 2 MiB
one ran far past a 5 s deadline (its cost is the product of the lengths; docs/execute.md).
So each open database's read-only statements run in a worker process (:func:`serve`, kept between
statements) that the caller kills at the deadline (counted from when the worker says it
is ready: its start-up, seconds on a loaded machine, has a bound of its own). It opens the
file read-only (``mode=ro``) and runs each statement under ``PRAGMA query_only``, an
authorizer, SQLite's length limit (the byte bound: no value larger is ever made) and its
heap limit (the worker's own), in a transaction it rolls back; it holds the rows
(serialized, within the byte bound) until the statement is done and checked, then sends
them, and the caller reads them a batch at a time.
"""

from __future__ import annotations

import marshal
import os
import sqlite3
import subprocess
import sys
import threading
import weakref
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO, TYPE_CHECKING, Any
from urllib.parse import quote

from toaster.db.readonly.bounds import (
    Limits,
    ReadRows,
    first_line,
    require_own_transaction,
    timeout_error,
    too_big_error,
)
from toaster.db.readonly.tokens import SQLITE_CALLS, check_statement
from toaster.errors import ReadOnlyError, ToasterError

if TYPE_CHECKING:
    from toaster.db.database import Database

#: SQLite's heap limit in the worker.
SQLITE_HEAP_LIMIT = 2**30
#: The highest length limit setlimit() takes (SQLite lowers it to its own ceiling).
_MAX_LENGTH = 2**31 - 1
#: How long a new worker may take to start (its imports), apart from any statement's
#: deadline: seconds on a loaded machine (docs/execute.md).
START_TIMEOUT_S = 60.0
#: A batch of rows sent at once: at most this many rows, or one row past this many bytes.
_BATCH_ROWS = 1000
_BATCH_BYTES = 2**20
_SQLITE_ALLOWED = {
    sqlite3.SQLITE_SELECT,
    sqlite3.SQLITE_READ,
    sqlite3.SQLITE_FUNCTION,
    sqlite3.SQLITE_RECURSIVE,
}
#: Pragmas that only read, whatever their argument (a table or index name).
_PRAGMAS_ANY = frozenset(
    (
        "table_info",
        "table_xinfo",
        "table_list",
        "index_list",
        "index_info",
        "index_xinfo",
        "foreign_key_list",
        "foreign_key_check",
        "integrity_check",
        "quick_check",
        "collation_list",
        "function_list",
        "module_list",
        "pragma_list",
        "database_list",
        "compile_options",
    )
)
#: Pragmas that read without an argument (with one, they write).
_PRAGMAS_READ = frozenset(
    (
        "application_id",
        "auto_vacuum",
        "busy_timeout",
        "cache_size",
        "data_version",
        "encoding",
        "foreign_keys",
        "freelist_count",
        "journal_mode",
        "page_count",
        "page_size",
        "query_only",
        "schema_version",
        "synchronous",
        "temp_store",
        "user_version",
        "max_page_count",
    )
)
#: Authorizer action codes, named for messages.
_SQLITE_ACTIONS = {
    getattr(sqlite3, f"SQLITE_{name}"): name.replace("_", " ")
    for name in (
        "ALTER_TABLE",
        "ANALYZE",
        "ATTACH",
        "CREATE_INDEX",
        "CREATE_TABLE",
        "CREATE_TEMP_INDEX",
        "CREATE_TEMP_TABLE",
        "CREATE_TEMP_TRIGGER",
        "CREATE_TEMP_VIEW",
        "CREATE_TRIGGER",
        "CREATE_VIEW",
        "CREATE_VTABLE",
        "DELETE",
        "DETACH",
        "DROP_INDEX",
        "DROP_TABLE",
        "DROP_TEMP_INDEX",
        "DROP_TEMP_TABLE",
        "DROP_TEMP_TRIGGER",
        "DROP_TEMP_VIEW",
        "DROP_TRIGGER",
        "DROP_VIEW",
        "DROP_VTABLE",
        "FUNCTION",
        "INSERT",
        "PRAGMA",
        "REINDEX",
        "SAVEPOINT",
        "TRANSACTION",
        "UPDATE",
    )
}
#: The worker's program: toaster's package from where the caller imported it, nothing from
#: the environment (-I) or site-packages (-S).
_CHILD = (
    "import sys; sys.path.insert(0, {root!r}); "
    "from toaster.db.readonly.sqlite import serve; serve()"
)
_ERRORS = {"ReadOnlyError": ReadOnlyError, "ToasterError": ToasterError}


class _Worker:
    """The process that runs one database's read-only statements, one at a time (starting
    one takes far longer than a statement: it is kept for the next statement, and killed at a
    deadline)."""

    def __init__(self, heap: int) -> None:
        root = str(Path(__file__).resolve().parents[3])
        self.process = subprocess.Popen(
            [sys.executable, "-I", "-S", "-c", _CHILD.format(root=root)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.DEVNULL,
        )
        self.heap = heap
        self.pid = os.getpid()  # a forked copy of this process must not share it
        self.lock = threading.Lock()
        self.ready = False

    def usable(self, heap: int) -> bool:
        return self.pid == os.getpid() and self.heap == heap and self.process.poll() is None

    def wait_ready(self) -> None:
        """Wait for the new process to say it is ready (its start-up is no statement's: a
        statement's deadline starts after it), within :data:`START_TIMEOUT_S`."""
        if self.ready:
            return
        assert self.process.stdout is not None  # a pipe
        clock = _Deadline(self.process, START_TIMEOUT_S)
        try:
            message = _receive(self.process.stdout)
        finally:
            killed = clock.stop()
        if message == ("ready",) and not killed:
            self.ready = True
            return
        self.stop()
        if killed:
            msg = (
                f"SQL error: the read-only statement's process did not start within "
                f"{START_TIMEOUT_S:g} s (is the machine overloaded?): run it again"
            )
        else:
            msg = (
                f"SQL error: the read-only statement's process ended as it started (exit "
                f"status {self.process.returncode}): run it again"
            )
        raise ToasterError(msg)

    def stop(self) -> None:
        """Kill the process (it may be mid-statement) and release its pipes."""
        if self.pid != os.getpid():
            return
        if self.process.poll() is None:
            self.process.kill()
        self.process.wait()
        for stream in (self.process.stdin, self.process.stdout):
            if stream is not None:
                stream.close()


#: Each open database's worker.
_WORKERS: weakref.WeakKeyDictionary[Database, _Worker] = weakref.WeakKeyDictionary()
_WORKERS_LOCK = threading.Lock()


@contextmanager
def _worker(db: Database) -> Iterator[_Worker]:
    """This database's worker, started if needed, for one statement at a time."""
    heap = SQLITE_HEAP_LIMIT
    with _WORKERS_LOCK:
        worker = _WORKERS.get(db)
        if worker is None or not worker.usable(heap):
            if worker is not None:
                worker.stop()
            # Stopped when the database object goes away or at exit; it also ends when its
            # input closes (this process ended).
            worker = _WORKERS[db] = _Worker(heap)
            weakref.finalize(db, worker.stop)
    with worker.lock:
        worker.wait_ready()
        yield worker


class _Deadline:
    """Kills ``process`` after ``seconds`` unless stopped before (once stopped, never)."""

    def __init__(self, process: subprocess.Popen[bytes], seconds: float) -> None:
        self._process = process
        self._lock = threading.Lock()
        self._stopped = False
        self.killed = False
        self._timer = threading.Timer(seconds, self._kill)
        self._timer.daemon = True
        self._timer.start()

    def _kill(self) -> None:
        with self._lock:
            if not self._stopped:
                self.killed = True
                self._process.kill()

    def stop(self) -> bool:
        """Stop the clock; whether the process was killed."""
        self._timer.cancel()
        with self._lock:
            self._stopped = True
        return self.killed


@contextmanager
def read_sqlite(db: Database, sql: str, params: Any, bounds: Limits) -> Iterator[ReadRows]:
    """Run one read statement on SQLite in a process of its own (see the module's doc) and
    give its rows once it is done; the process is killed at the deadline."""
    from toaster.db.engine import lock_timeout, sqlite_file

    check_statement(sql, "sqlite")
    require_own_transaction(db.connection)
    path = sqlite_file(db.engine.url)
    if path is None:
        msg = (
            "read-only SQL runs in a process of its own, which cannot open an in-memory "
            "database: use a database file, or --write"
        )
        raise ToasterError(msg)
    try:
        request = marshal.dumps(
            (str(path.resolve()), sql, params, tuple(bounds), SQLITE_HEAP_LIMIT, lock_timeout())
        )
    except ValueError:
        msg = "SQL error: parameters must be text, numbers, bytes or None"
        raise ToasterError(msg) from None
    with _worker(db) as worker:  # started and ready: the deadline is the statement's
        process = worker.process
        assert process.stdin is not None  # both are pipes
        assert process.stdout is not None
        deadline = _Deadline(process, bounds.timeout_s)
        read = [False]  # every batch read: the worker is ready for the next statement
        try:
            try:
                _write(process.stdin, request)
                process.stdin.flush()
            except OSError:
                pass  # it ended: its answer (or its absence) says why
            head = _receive(process.stdout)
            if deadline.stop():
                raise timeout_error(bounds)
            if head is None:
                raise _ended(process)
            if head[0] == "error":
                read[0] = True
                raise _ERRORS.get(head[1], ToasterError)(head[2])
            yield ReadRows(head[1], _rows(process, head[2], read), bounds.max_rows)
        finally:
            if deadline.stop() or not read[0]:  # killed, ended, or rows left unread
                worker.stop()


def _rows(
    process: subprocess.Popen[bytes], batches: int, read: list[bool]
) -> Iterator[tuple[Any, ...]]:
    """The rows sent by the worker, one batch held at a time."""
    assert process.stdout is not None  # a pipe
    for _ in range(batches):
        batch = _receive(process.stdout)
        if batch is None:
            raise _ended(process)
        yield from batch
    read[0] = True


def _ended(process: subprocess.Popen[bytes]) -> ToasterError:
    """The error of a worker that closed its output without an answer (it died)."""
    try:
        status = process.wait(timeout=1)
    except subprocess.TimeoutExpired:
        process.kill()
        status = process.wait()
    return ToasterError(
        f"SQL error: the read-only statement's process ended without an "
        f"answer (exit status {status}): run it again"
    )


def _send(out: IO[bytes], message: Any) -> None:
    _write(out, marshal.dumps(message))


def _write(out: IO[bytes], data: bytes) -> None:
    """One message: its length (8 bytes), then ``data`` (a value marshalled)."""
    out.write(len(data).to_bytes(8, "big"))
    out.write(data)


def _receive(stream: IO[bytes]) -> Any:
    """The next message, or None at the end of the stream."""
    size = stream.read(8)
    if len(size) < 8:
        return None
    data = stream.read(int.from_bytes(size, "big"))
    if len(data) < int.from_bytes(size, "big"):
        return None
    return marshal.loads(data)


# ---------------------------------------------------------------------------- the worker
def serve() -> None:
    """The worker: ``("ready",)`` on stdout, then for each request on stdin (until it
    closes) ``("error", class, message)``, or ``("rows", columns, batches)`` then that many
    batches of rows."""
    out = sys.stdout.buffer
    _send(out, ("ready",))  # imported: what follows is the statements'
    out.flush()
    reader: _Reader | None = None
    while (request := _receive(sys.stdin.buffer)) is not None:
        path, sql, params, bounds, heap, lock_timeout_s = request
        try:
            if reader is None or reader.opened != (path, heap, lock_timeout_s):
                if reader is not None:
                    reader.close()
                reader = None  # (if opening fails, the next request tries again)
                reader = _Reader(path, heap, lock_timeout_s)
            columns, batches = reader.run(sql, params, Limits(*bounds))
        except ToasterError as exc:
            _send(out, ("error", type(exc).__name__, str(exc)))
        except Exception as exc:  # anything else is one line too, never a traceback
            _send(out, ("error", "ToasterError", f"SQL error: {first_line(exc)}"))
        else:
            _send(out, ("rows", columns, len(batches)))
            for batch in batches:
                _write(out, batch)
            del batches
        out.flush()


class _Reader:
    """The worker's read-only connection to the database file (kept between statements:
    opening it reads the schema), with ``query_only``, the heap limit and checked
    ``printf``/``format``; each statement runs in a transaction rolled back after it."""

    def __init__(self, path: str, heap: int, lock_timeout_s: float) -> None:
        self.opened = (path, heap, lock_timeout_s)
        self.heap = heap
        self.raw = sqlite3.connect(
            f"file:{quote(path)}?mode=ro", uri=True, timeout=lock_timeout_s, isolation_level=None
        )
        self.helper = sqlite3.connect(":memory:")
        for pragma in (
            "query_only = ON",
            "foreign_keys = ON",
            "temp_store = MEMORY",
            f"hard_heap_limit = {int(heap)}",
        ):
            self.raw.execute(f"PRAGMA {pragma}").fetchall()  # done: no statement stays active
        self.failed: list[ToasterError] = []  # what a checked function refused
        self.bounds = Limits(1, 1024, 1.0)
        for name in ("printf", "format"):
            self.raw.create_function(name, -1, self._printf, deterministic=True)

    def close(self) -> None:
        self.raw.close()
        self.helper.close()

    def run(self, sql: str, params: Any, bounds: Limits) -> tuple[list[str], list[bytes]]:
        """Run the statement; its columns and its rows as sent (marshalled batches), once it
        is done and nothing was changed. Rolled back whatever happens."""
        raw = self.raw
        # No value past the bound is ever made (a blob of exactly the bound fits; text needs
        # one more byte, its terminator).
        for conn in (raw, self.helper):
            conn.setlimit(sqlite3.SQLITE_LIMIT_LENGTH, min(_MAX_LENGTH, bounds.max_bytes + 1))
        self.bounds, self.failed = bounds, []
        refused: list[str] = []  # what the authorizer denied
        raw.execute("BEGIN")
        changes = raw.total_changes
        raw.set_authorizer(_authorizer(refused))
        try:
            columns, batches = _fetch(
                raw.cursor(), sql, params, bounds, (refused, self.failed), self.heap
            )
        finally:
            raw.set_authorizer(None)
            query_only = raw.execute("PRAGMA query_only").fetchone()[0]
            changed = not raw.in_transaction or raw.total_changes != changes
            if raw.in_transaction:
                raw.execute("ROLLBACK")
        if changed or query_only != 1:
            msg = (
                "statement refused: it ended its transaction or changed the database "
                "(rolled back): rerun with --write"
            )
            raise ReadOnlyError(msg)
        return columns, batches

    def _printf(self, *args: Any) -> Any:
        """SQLite's ``printf`` (``format``), refused past the length limit, where SQLite's
        returns NULL, which would pass for an answer: a NULL from a format that is not NULL
        (it runs on the helper connection, whose limit is the same)."""
        marks = ", ".join("?" * len(args))
        value = self.helper.execute(f"SELECT printf({marks})", args).fetchone()[0]
        if value is None and args and args[0] is not None:
            self.failed.append(too_big_error(self.bounds, "a value made by printf() or format()"))
            raise OverflowError(str(self.failed[-1]))
        return value


def _authorizer(
    refused: list[str],
) -> Callable[[int, str | None, str | None, str | None, str | None], int]:
    """Allow reading tables, functions but :data:`SQLITE_CALLS` and reading pragmas; deny
    the rest (transactions, savepoints, ATTACH, writes, DDL), noting what in ``refused``."""

    def authorize(action: int, arg1: str | None, arg2: str | None, *_: Any) -> int:
        if action in _SQLITE_ALLOWED and not (
            action == sqlite3.SQLITE_FUNCTION and (arg2 or "").lower() in SQLITE_CALLS
        ):
            return sqlite3.SQLITE_OK
        if action == sqlite3.SQLITE_PRAGMA and (
            (arg1 or "").lower() in _PRAGMAS_ANY
            or (arg2 is None and (arg1 or "").lower() in _PRAGMAS_READ)
        ):
            return sqlite3.SQLITE_OK
        if action == sqlite3.SQLITE_UPDATE and arg1 == "sqlite_master":
            # SQLite's own nested statement on first use of a pragma table-valued function
            # (pragma_table_info): IGNORE leaves the column unchanged.
            return sqlite3.SQLITE_IGNORE
        what = _SQLITE_ACTIONS.get(action, f"action {action}")
        detail = " ".join(str(a) for a in (arg1, arg2) if a is not None)
        refused.append(f"{what} {detail}".strip())
        return sqlite3.SQLITE_DENY

    return authorize


def _fetch(
    cur: sqlite3.Cursor,
    sql: str,
    params: Any,
    bounds: Limits,
    denials: tuple[list[str], list[ToasterError]],
    heap: int,
) -> tuple[list[str], list[bytes]]:
    """The columns and the rows (at most ``max_rows`` + 1, the last saying "truncated"), as
    marshalled batches; a row that takes the result past ``max_bytes`` is refused. ``denials``:
    what the authorizer denied, what a checked function refused (they explain errors)."""
    batches: list[bytes] = []
    try:
        cur.execute(sql, params or ())
        columns = [d[0] for d in cur.description] if cur.description else []
        batch: list[tuple[Any, ...]] = []
        size = held = 0
        for count, row in enumerate(cur if columns else (), 1):
            # Text and blobs count their length, other values 8 bytes, and so does a short
            # text: what is held is bounded by max_bytes, however small the values.
            row_size = sum(max(len(v), 8) if isinstance(v, str | bytes) else 8 for v in row)
            size += row_size
            if size > bounds.max_bytes:
                raise too_big_error(bounds)
            batch.append(row)
            held += row_size
            if len(batch) == _BATCH_ROWS or held >= _BATCH_BYTES:
                batches.append(marshal.dumps(batch))
                batch, held = [], 0
            if count > bounds.max_rows:
                break
        if batch:
            batches.append(marshal.dumps(batch))
    except MemoryError:
        msg = (
            f"SQL error: the statement needs more than {heap >> 20} MiB of memory "
            "(read-only SQL's bound): narrow it (WHERE, LIMIT)"
        )
        raise ToasterError(msg) from None
    except sqlite3.Error as exc:
        raise _sqlite_error(exc, *denials, bounds) from None
    except (ValueError, OverflowError) as exc:  # text that is not UTF-8, huge integers
        msg = f"SQL error: {first_line(exc)}"
        raise ToasterError(msg) from None
    finally:
        cur.close()
    return columns, batches


def _sqlite_error(
    exc: sqlite3.Error, refused: list[str], failed: list[ToasterError], bounds: Limits
) -> ToasterError:
    name = getattr(exc, "sqlite_errorname", "")
    reason = first_line(exc)
    if failed:
        return failed[0]
    if refused or name == "SQLITE_AUTH":
        what = refused[0] if refused else reason
        return ReadOnlyError(
            f"statement refused, read-only SQL does not allow {what}: rerun with --write"
        )
    if name == "SQLITE_READONLY":
        return ReadOnlyError(
            f"statement refused, the database is opened read-only: rerun with --write ({reason})"
        )
    if name == "SQLITE_TOOBIG":
        return too_big_error(bounds, "a value")
    return ToasterError(f"SQL error: {reason}")
