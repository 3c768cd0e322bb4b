"""Read-only SQL for users: one statement that can neither write, end or upgrade its
transaction, switch roles nor act on the server, with its rows, bytes and time bounded.

Three layers (docs/execute.md): a tokenizer that refuses anything but one SELECT-like
statement naming no function with side effects; the database (``PRAGMA query_only`` and an
authorizer on SQLite; a read-only transaction, the role :data:`READER_ROLE` and a
``SECURITY DEFINER`` wrapper, inside which no role can be taken, on PostgreSQL); checks after
the statement, then a rollback whatever happened.
"""

from __future__ import annotations

import functools
import json
import re
import sqlite3
import time
import weakref
from collections.abc import Iterator
from contextlib import contextmanager
from typing import Any, NamedTuple

from toaster.errors import InvalidInputError, ReadOnlyError, ToasterError

#: The PostgreSQL role read-only statements run as (NOLOGIN, SELECT on toaster's schema).
READER_ROLE = "toaster_reader"
DEFAULT_MAX_ROWS = 100_000
DEFAULT_MAX_BYTES = 128 * 2**20
DEFAULT_TIMEOUT_S = 60.0
#: SQLite's heap limit (process-wide) while a read-only statement runs.
SQLITE_HEAP_LIMIT = 2**30


class Limits(NamedTuple):
    """Bounds of one read-only statement (checked by :func:`limits`)."""

    max_rows: int
    max_bytes: int
    timeout_s: float


class ReadResult(NamedTuple):
    """Columns and rows (at most ``max_rows``; ``truncated`` when there were more)."""

    columns: list[str]
    rows: list[tuple[Any, ...]]
    truncated: bool


def limits(max_rows: int, max_bytes: int, timeout_s: float) -> Limits:
    """The checked bounds (:class:`~toaster.errors.InvalidInputError` names a bad one)."""
    for name, value, low, high in (("max_rows", max_rows, 1, 2**31 - 2),
                                   ("max_bytes", max_bytes, 1024, 2**62)):
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            msg = (f"{name}={value!r} is not a whole number from {low} to {high}: give e.g. "
                   f"{name}=100000")
            raise InvalidInputError(msg)
    if not (isinstance(timeout_s, int | float) and 0 < timeout_s < 1e7):
        msg = f"timeout_s={timeout_s!r} is not a number of seconds > 0: give e.g. timeout_s=60"
        raise InvalidInputError(msg)
    return Limits(max_rows, max_bytes, float(timeout_s))


# ---------------------------------------------------------------------------- tokens
class Token(NamedTuple):
    """``kind``: word (unquoted name or keyword), ident (quoted), string, number, param,
    op or semi; ``text`` as written, at ``start``."""

    kind: str
    text: str
    start: int

    @property
    def name(self) -> str:
        """A word lower-cased, a quoted identifier without its quotes (lower-cased too)."""
        if self.kind == "ident":
            quote = self.text[0]
            return self.text[1:-1].replace(quote * 2, quote).lower()
        return self.text.lower()


_IDENT = r"A-Za-z_\x80-\U0010ffff"
_WORD = re.compile(rf"[{_IDENT}][{_IDENT}0-9$]*")
_NUMBER = re.compile(r"(?:\d+\.?\d*|\.\d+)(?:[eE][+-]?\d+)?")
_DOLLAR = re.compile(rf"\$(?:[{_IDENT}][{_IDENT}0-9]*)?\$")
_PG_PARAM = re.compile(r"\$\d+")
_SQLITE_PARAM = re.compile(rf"(?:\?\d*|[:@$][{_IDENT}0-9]+)")


def tokenize(sql: str, dialect: str) -> list[Token]:
    """The tokens of ``sql`` as PostgreSQL (standard_conforming_strings on) or SQLite reads
    them, without spaces and comments; unterminated quotes or comments are a ToasterError."""
    pg = dialect == "postgresql"
    tokens: list[Token] = []
    i, n = 0, len(sql)
    while i < n:
        c = sql[i]
        if c in " \t\n\r\f\v":
            i += 1
        elif sql.startswith("--", i):  # to the end of the line (\r too on PostgreSQL)
            end = min((e for e in (sql.find("\n", i), sql.find("\r", i) if pg else -1)
                       if e >= 0), default=n)
            i = end + 1
        elif sql.startswith("/*", i):
            i = _block_comment(sql, i, pg)
        elif c == "'":
            i = _quoted(sql, i, "'", tokens, "string")
        elif c == '"' or (not pg and c == "`"):
            i = _quoted(sql, i, c, tokens, "ident")
        elif not pg and c == "[":
            end = sql.find("]", i)
            if end < 0:
                _unterminated("[identifier")
            tokens.append(Token("ident", '"' + sql[i + 1:end] + '"', i))
            i = end + 1
        elif (word := _WORD.match(sql, i)) is not None:
            i = _word(sql, word.group(), i, pg, tokens)
        elif (number := _NUMBER.match(sql, i)) is not None:
            tokens.append(Token("number", number.group(), i))
            i = number.end()
        elif pg and c == "$":
            i = _dollar(sql, i, tokens)
        elif not pg and (param := _SQLITE_PARAM.match(sql, i)) is not None:
            tokens.append(Token("param", param.group(), i))
            i = param.end()
        elif c == ";":
            tokens.append(Token("semi", c, i))
            i += 1
        else:
            op = "::" if sql.startswith("::", i) else c
            tokens.append(Token("op", op, i))
            i += len(op)
    return tokens


def _unterminated(what: str) -> None:
    msg = f"SQL error: unterminated {what} in the statement: close it"
    raise ToasterError(msg)


def _block_comment(sql: str, i: int, nested: bool) -> int:
    depth, i = 1, i + 2
    while depth:
        close = sql.find("*/", i)
        if close < 0:
            if nested:  # PostgreSQL refuses it; SQLite reads to the end
                _unterminated("/* comment")
            return len(sql)
        opened = sql.find("/*", i, close) if nested else -1
        if opened >= 0:
            depth, i = depth + 1, opened + 2
        else:
            depth, i = depth - 1, close + 2
    return i


def _quoted(sql: str, i: int, quote: str, tokens: list[Token], kind: str,
            backslash: bool = False, start: int | None = None) -> int:
    j = i + 1
    while True:
        end = sql.find(quote, j)
        if backslash:
            slash = sql.find("\\", j)
            if 0 <= slash < end or (end < 0 <= slash):
                j = slash + 2
                continue
        if end < 0:
            _unterminated("quote " + quote)
        if sql.startswith(quote * 2, end):
            j = end + 2
            continue
        begin = i if start is None else start
        tokens.append(Token(kind, sql[begin:end + 1], begin))
        return end + 1


def _word(sql: str, word: str, i: int, pg: bool, tokens: list[Token]) -> int:
    after = i + len(word)
    prefix = word.lower()
    if pg and prefix in ("e", "b", "x", "n") and sql.startswith("'", after):
        return _quoted(sql, after, "'", tokens, "string", backslash=prefix == "e", start=i)
    if not pg and prefix == "x" and sql.startswith("'", after):
        return _quoted(sql, after, "'", tokens, "string", start=i)
    if pg and prefix == "u" and sql.startswith("&'", after):
        return _quoted(sql, after + 1, "'", tokens, "string", start=i)
    if pg and prefix == "u" and sql.startswith('&"', after):
        msg = ('read-only SQL does not take U&"..." identifiers (escapes can hide a name): '
               "write the name plainly or in double quotes")
        raise ReadOnlyError(msg)
    tokens.append(Token("word", word, i))
    return after


def _dollar(sql: str, i: int, tokens: list[Token]) -> int:
    if (param := _PG_PARAM.match(sql, i)) is not None:
        tokens.append(Token("param", param.group(), i))
        return param.end()
    if (tag := _DOLLAR.match(sql, i)) is None:
        tokens.append(Token("op", "$", i))
        return i + 1
    end = sql.find(tag.group(), tag.end())
    if end < 0:
        _unterminated("dollar quote " + tag.group())
    tokens.append(Token("string", sql[i:end + len(tag.group())], i))
    return end + len(tag.group())


# ---------------------------------------------------------------------------- the statement
_READS = {"postgresql": ("select", "with", "values", "table", "explain", "show"),
          "sqlite": ("select", "with", "values", "explain", "pragma")}
#: Statements that write or act (their first word): refused, --write runs them.
_ACTIONS = frozenset((
    "abort", "alter", "analyze", "analyse", "attach", "begin", "call", "checkpoint", "close",
    "cluster", "comment", "commit", "copy", "create", "deallocate", "declare", "delete",
    "detach", "discard", "do", "drop", "end", "execute", "fetch", "grant", "import", "insert",
    "listen", "load", "lock", "merge", "move", "notify", "prepare", "reassign", "refresh",
    "reindex", "release", "replace", "reset", "revoke", "rollback", "savepoint", "security",
    "set", "start", "truncate", "unlisten", "update", "vacuum"))
#: Words that make a read statement write (writable CTEs, SELECT INTO, row locks).
_WRITE_WORDS = frozenset(("insert", "update", "delete", "merge", "truncate", "into"))
#: PostgreSQL functions with effects beyond the transaction or the session's own reads
#: (settings, locks, files, programs, other sessions, SQL run from a string).
_PG_CALLS = frozenset((
    "set_config", "pg_notify", "nextval", "setval", "loread", "lowrite", "pg_read_file",
    "pg_read_binary_file", "pg_stat_file", "pg_terminate_backend", "pg_cancel_backend",
    "pg_reload_conf", "pg_rotate_logfile", "pg_switch_wal", "pg_promote",
    "pg_create_restore_point", "pg_backup_start", "pg_backup_stop", "pg_start_backup",
    "pg_stop_backup", "pg_log_backend_memory_contexts", "pg_logical_emit_message",
    "pg_import_system_collations", "query_to_xml", "query_to_xmlschema",
    "query_to_xml_and_xmlschema", "cursor_to_xml", "cursor_to_xmlschema", "ts_stat",
    "ts_rewrite", "pg_logical_slot_get_changes", "pg_logical_slot_peek_changes"))
_PG_CALL_PREFIXES = ("pg_advisory", "pg_try_advisory", "dblink", "lo_", "pg_ls_", "pg_file_",
                     "pg_stat_reset", "pg_replication_", "pg_create_", "pg_drop_", "pg_copy_",
                     "pg_wal_replay_", "binary_upgrade_", "table_to_xml", "schema_to_xml",
                     "database_to_xml", "pg_logdir_")
#: SQLite functions that load code or touch files.
_SQLITE_CALLS = frozenset(("load_extension", "fts3_tokenizer", "readfile", "writefile", "edit"))


def check_statement(sql: str, dialect: str) -> list[Token]:
    """The tokens of ``sql`` if it is one read statement; else a ReadOnlyError (it writes or
    acts: ``--write`` runs it) or a ToasterError (not SQL toaster reads)."""
    if "\x00" in sql:
        msg = "SQL error: the statement contains a NUL character: remove it"
        raise ToasterError(msg)
    tokens = tokenize(sql, dialect)
    while tokens and tokens[-1].kind == "semi":
        tokens.pop()
    if not tokens:
        msg = 'SQL error: the statement is empty: give one, e.g. "SELECT 1"'
        raise ToasterError(msg)
    if any(t.kind == "semi" for t in tokens):
        msg = ("read-only SQL runs exactly one statement (this has several): run them one at "
               "a time, or all with --write")
        raise ReadOnlyError(msg)
    first = next((t for t in tokens if t.text != "("), tokens[0])
    word = first.name if first.kind == "word" else ""
    if word in _ACTIONS:
        _refuse(f"{word.upper()} statements")
    if word not in _READS[dialect]:
        reads = ", ".join(w.upper() for w in _READS[dialect])
        msg = f"SQL error: read-only SQL starts with {reads}, not {first.text[:40]!r}"
        raise ToasterError(msg)
    if word == "explain":
        _check_explain(tokens[tokens.index(first) + 1:], dialect)
    for index, token in enumerate(tokens):
        if token.kind == "word" and token.name in _WRITE_WORDS:
            _refuse(f"{token.name.upper()} (it writes)")
        if token.kind == "word" and token.name == "for" and index + 1 < len(tokens) and \
                tokens[index + 1].name in ("update", "share", "no", "key"):
            _refuse("row locks (FOR UPDATE / FOR SHARE)")
        called = index + 1 < len(tokens) and tokens[index + 1].text == "("
        if token.kind in ("word", "ident") and _denied_call(token.name, dialect, called):
            _refuse(f"{token.name}() (a side effect beyond the statement)")
    return tokens


def _refuse(what: str) -> None:
    msg = f"statement refused, read-only SQL does not allow {what}: rerun with --write"
    raise ReadOnlyError(msg)


def _check_explain(rest: list[Token], dialect: str) -> None:
    skip = {"analyze", "analyse", "verbose", "query", "plan"}
    index = 0
    if rest and rest[0].text == "(" and dialect == "postgresql":
        depth = 0
        for index, token in enumerate(rest):  # noqa: B007 (index is used after the loop)
            depth += {"(": 1, ")": -1}.get(token.text, 0)
            if depth == 0:
                break
        index += 1
    while index < len(rest) and rest[index].name in skip:
        index += 1
    inner = rest[index].name if index < len(rest) else ""
    if inner not in ("select", "with", "values", "table"):
        _refuse("EXPLAIN of anything but a read")


def _denied_call(name: str, dialect: str, called: bool) -> bool:
    """A denied function's name (anywhere), or a call of a denied family (``lo_…(``)."""
    if dialect == "sqlite":
        return name in _SQLITE_CALLS
    return name in _PG_CALLS or (called and name.startswith(_PG_CALL_PREFIXES))


def pyformat(sql: str, tokens: list[Token]) -> str:
    """``sql`` with its ``:name`` parameters as psycopg's ``%(name)s`` (``%`` doubled
    elsewhere); ``::`` casts, slices ``a[1:n]`` and quoted text are left alone."""
    out, last = [], 0
    for index, colon in enumerate(tokens[:-1]):
        name = tokens[index + 1]
        if colon.text != ":" or name.kind != "word" or name.start != colon.start + 1:
            continue
        prev = tokens[index - 1] if index else None
        if prev is not None and prev.start + len(prev.text) == colon.start and \
                prev.kind in ("word", "number", "ident"):
            continue  # a slice bound (a[1:n]), not a parameter
        out.append(sql[last:colon.start].replace("%", "%%"))
        out.append(f"%({name.text})s")
        last = name.start + len(name.text)
    out.append(sql[last:].replace("%", "%%"))
    return "".join(out)


# ---------------------------------------------------------------------------- SQLite
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
    _own_transaction(conn)
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
                action == sqlite3.SQLITE_FUNCTION and (arg2 or "").lower() in _SQLITE_CALLS):
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
                    _too_big(bounds)
            rows.extend(tuple(r) for r in batch)
    except MemoryError:
        msg = (f"SQL error: the statement needs more than {SQLITE_HEAP_LIMIT >> 20} MiB of "
               "memory (read-only SQL's bound): narrow it (WHERE, LIMIT)")
        raise ToasterError(msg) from None
    except sqlite3.Error as exc:
        raise _sqlite_error(exc, refused, bounds) from None
    except (ValueError, OverflowError) as exc:  # text that is not UTF-8, huge integers
        msg = f"SQL error: {_first_line(exc)}"
        raise ToasterError(msg) from None
    finally:
        cur.close()
    truncated = len(rows) > bounds.max_rows
    return columns, rows[:bounds.max_rows], truncated


def _sqlite_error(exc: sqlite3.Error, refused: list[str], bounds: Limits) -> ToasterError:
    name = getattr(exc, "sqlite_errorname", "")
    reason = (str(exc).strip().splitlines() or [type(exc).__name__])[0]
    if refused or name == "SQLITE_AUTH":
        what = refused[0] if refused else reason
        return ReadOnlyError(f"statement refused, read-only SQL does not allow {what}: "
                             "rerun with --write")
    if name == "SQLITE_READONLY":
        return ReadOnlyError(f"statement refused, the database is opened read-only: rerun "
                             f"with --write ({reason})")
    if name == "SQLITE_INTERRUPT":
        return _timeout(bounds)
    if name == "SQLITE_TOOBIG":
        return ToasterError(f"SQL error: a value is larger than read-only SQL allows "
                            f"({reason}): select less, or raise --max-bytes")
    return ToasterError(f"SQL error: {reason}")


def _timeout(bounds: Limits) -> ToasterError:
    return ToasterError(f"SQL error: the statement ran longer than {bounds.timeout_s:g} s "
                        "(read-only SQL's bound): narrow it (WHERE, LIMIT) or raise --timeout")


def _too_big(bounds: Limits) -> None:
    msg = (f"SQL error: the result is larger than {bounds.max_bytes} bytes (--max-bytes): "
           "select fewer rows or columns, or raise --max-bytes")
    raise ToasterError(msg)


def _own_transaction(conn: Any) -> None:
    if conn.in_transaction():
        msg = ("read-only SQL runs in a transaction of its own: call execute() outside "
               "store.transaction() / db.transaction()")
        raise ToasterError(msg)


# ---------------------------------------------------------------------------- PostgreSQL
_RUN = "pg_temp.toaster_readonly_run"
_RUN_SIGNATURE = f"{_RUN}(text, integer, bigint)"
# SECURITY DEFINER: while it runs, PostgreSQL refuses to change "role" or
# "session_authorization" by any means (SET ROLE, set_config, in any nested function), even
# for a superuser session. Its owner is READER_ROLE (else the connecting role). No SET
# search_path: the statement resolves names as the caller would. Stops after max_rows + 1
# rows (the extra one says "truncated") and before max_bytes of text.
_RUN_BODY = """
DECLARE
  r record;
  n integer := 0;
  size bigint := 0;
BEGIN
  FOR r IN EXECUTE q LOOP
    n := n + 1;
    size := size + coalesce(pg_catalog.octet_length(r::text), 0);
    IF size > max_bytes THEN
      RAISE EXCEPTION 'toaster: result over % bytes', max_bytes USING ERRCODE = '54000';
    END IF;
    RETURN NEXT r;
    EXIT WHEN n > max_rows;
  END LOOP;
END
"""
_CREATE_RUN = (f"CREATE FUNCTION {_RUN}(q text, max_rows integer, max_bytes bigint) "
               "RETURNS SETOF record LANGUAGE plpgsql SECURITY DEFINER "
               f"AS $toaster${_RUN_BODY}$toaster$")
_PID = "pid = pg_catalog.pg_backend_pid()"
_VXID = (f"(SELECT virtualxid FROM pg_catalog.pg_locks WHERE locktype = 'virtualxid' "
         f"AND {_PID})")
_ADVISORY = f"SELECT count(*) FROM pg_catalog.pg_locks WHERE locktype = 'advisory' AND {_PID}"
_SCHEMA = "(SELECT oid FROM pg_catalog.pg_namespace WHERE nspname = current_schema())"
_UNGRANTED = (f"FROM pg_catalog.pg_class c WHERE c.relnamespace = {_SCHEMA} "
              "AND c.relkind IN ('r', 'v', 'm', 'p', 'f') "
              "AND NOT pg_catalog.has_table_privilege(r.oid, c.oid, 'SELECT')")
_SAFE = ("NOT (r.rolsuper OR r.rolcreaterole OR r.rolcreatedb OR r.rolreplication "
         "OR r.rolbypassrls) AND NOT EXISTS (SELECT FROM pg_catalog.pg_auth_members m "
         "WHERE m.member = r.oid)")
_USAGE = ("current_schema() IS NOT NULL "
          "AND pg_catalog.has_schema_privilege(r.oid, current_schema(), 'USAGE')")
# Scans pg_class: only when setting up (a table the reader may not read is found when the
# statement fails on it, then granted, and the statement run again).
_GRANTED = f"{_USAGE} AND NOT EXISTS (SELECT {_UNGRANTED})"
# One round trip: the transaction's bounds, then what the statement needs and what exists.
_SETUP = f"""
SELECT pg_catalog.set_config('statement_timeout', %(timeout)s, true),
  pg_catalog.set_config('standard_conforming_strings', 'on', true),
  pg_catalog.set_config('cursor_tuple_fraction', '1', true),
  CASE WHEN current_setting('is_superuser') = 'on'
    THEN pg_catalog.set_config('temp_file_limit', %(temp)s, true) END,
  {_VXID}, ({_ADVISORY}), current_user, current_setting('is_superuser') = 'on',
  (SELECT pg_catalog.pg_get_userbyid(p.proowner) FROM pg_catalog.pg_proc p
    WHERE p.oid = pg_catalog.to_regprocedure(%(run)s) AND p.prosecdef AND p.prosrc = %(body)s),
  (SELECT {_SAFE} AND pg_catalog.pg_has_role(r.oid, 'MEMBER') AND {_USAGE}
    FROM pg_catalog.pg_roles r WHERE r.rolname = %(reader)s)
"""
_RELATION_DENIED = re.compile(r"permission denied for (table|view|materialized view|relation)")
#: Connections where READER_ROLE cannot be used, and why (they run as their own role).
_NO_READER: weakref.WeakKeyDictionary[Any, str] = weakref.WeakKeyDictionary()


class _Denied(Exception):
    """The reader was refused a relation: grant, then run the statement again."""

    def __init__(self, error: ToasterError) -> None:
        super().__init__(str(error))
        self.error = error


class _State(NamedTuple):
    vxid: str
    advisory: int
    user: str
    superuser: bool
    owner: str | None
    reader_ready: bool | None


def run_postgresql(db: Any, sql: str, params: Any, bounds: Limits) -> ReadResult:
    """Run one read statement on PostgreSQL (see the module's doc); roll back whatever
    happens. Sets up READER_ROLE and the wrapper on first use (:func:`ensure_reader_role`)."""
    raw = db.connection.connection.dbapi_connection
    text = _pg_text(raw, sql, params)
    check_statement(text, "postgresql")
    _own_transaction(db.connection)
    prepared = False
    while True:
        with _pg_transaction(db, raw, bounds) as (cur, state):
            role = _role(raw, state)
            if role is not None:
                try:
                    return _pg_run(db, cur, raw, text, state, role, bounds)
                except _Denied as denied:  # a table made since the grants, perhaps
                    if prepared or role != READER_ROLE:
                        raise denied.error from None
            elif prepared:
                msg = (f"cannot set up read-only SQL on PostgreSQL ({_NO_READER.get(raw)}): "
                       f"fix role {READER_ROLE} or this role's TEMP privilege, or use --write")
                raise ToasterError(msg)
        _prepare(db, raw)
        prepared = True


def ensure_reader_role(cur: Any) -> str | None:
    """Create :data:`READER_ROLE` if missing (NOLOGIN, no attributes), let the current role
    take it, and grant it USAGE on ``current_schema()`` and SELECT on its tables and views.

    Returns None when the role is usable, else why not (read-only SQL then runs as the
    connecting role). Runs in the caller's write transaction (a migration may call it).
    """
    for _ in range(2):  # a concurrent CREATE ROLE may win the race: look again
        cur.execute(f"SELECT {_SAFE}, pg_catalog.pg_has_role(r.oid, 'MEMBER') "
                    "FROM pg_catalog.pg_roles r WHERE r.rolname = %s", [READER_ROLE])
        row = cur.fetchone()
        if row is not None:
            break
        failed = _savepoint(cur, f"CREATE ROLE {READER_ROLE} NOLOGIN")
        if failed and not failed.startswith(("42710", "23505")):  # exists (a race)
            return f"cannot create role {READER_ROLE}: {failed}"
    else:
        return f"role {READER_ROLE} cannot be created"
    safe, member = row
    if not safe:
        return f"role {READER_ROLE} has attributes or memberships it must not have"
    if not member and (failed := _savepoint(cur, f"GRANT {READER_ROLE} TO CURRENT_USER")):
        return f"cannot take role {READER_ROLE}: {failed}"
    cur.execute(f"SELECT pg_catalog.quote_ident(current_schema()), {_GRANTED} "
                "FROM pg_catalog.pg_roles r WHERE r.rolname = %s", [READER_ROLE])
    schema, granted = cur.fetchone()
    if schema is None:
        return "no current schema (search_path names none that exists)"
    if granted:
        return None
    _savepoint(cur, f"GRANT USAGE ON SCHEMA {schema} TO {READER_ROLE}")
    cur.execute(f"SELECT c.oid::regclass::text FROM pg_catalog.pg_roles r, "
                f"pg_catalog.pg_class c WHERE r.rolname = %s AND c.relnamespace = {_SCHEMA} "
                "AND c.relkind IN ('r', 'v', 'm', 'p', 'f') "
                "AND NOT pg_catalog.has_table_privilege(r.oid, c.oid, 'SELECT')",
                [READER_ROLE])
    missing = [name for (name,) in cur.fetchall()]
    if missing:
        _savepoint(cur, f"GRANT SELECT ON TABLE {', '.join(missing)} TO {READER_ROLE}")
    cur.execute(f"SELECT {_GRANTED} FROM pg_catalog.pg_roles r WHERE r.rolname = %s",
                [READER_ROLE])
    if not cur.fetchone()[0]:
        return (f"cannot grant {READER_ROLE} SELECT on every table of schema {schema} "
                "(only their owner can)")
    return None


def _savepoint(cur: Any, statement: str) -> str | None:
    """Run ``statement`` in a savepoint: None, or ``SQLSTATE message`` when it failed."""
    import psycopg

    cur.execute("SAVEPOINT toaster_readonly")
    try:
        cur.execute(statement)
    except psycopg.Error as exc:
        cur.execute("ROLLBACK TO SAVEPOINT toaster_readonly")
        return f"{exc.sqlstate} {_first_line(exc)}"
    cur.execute("RELEASE SAVEPOINT toaster_readonly")
    return None


def _prepare(db: Any, raw: Any) -> None:
    """(Re)create this session's wrapper, owned by READER_ROLE when it is usable."""
    import psycopg

    try:
        with db.transaction(write=True):
            cur = raw.cursor()
            cur.execute("SELECT pg_catalog.pg_advisory_xact_lock("
                        "pg_catalog.hashtext('toaster read-only setup'))")
            reason = ensure_reader_role(cur)
            cur.execute(f"DROP FUNCTION IF EXISTS {_RUN_SIGNATURE}")
            cur.execute(_CREATE_RUN)
            if reason is None and (failed := _savepoint(
                    cur, f"ALTER FUNCTION {_RUN_SIGNATURE} OWNER TO {READER_ROLE}")):
                reason = f"cannot give role {READER_ROLE} the wrapper: {failed}"
    except psycopg.Error as exc:
        _NO_READER[raw] = _first_line(exc)
        return
    if reason is None:
        _NO_READER.pop(raw, None)
    else:
        _NO_READER[raw] = reason


def _role(raw: Any, state: _State) -> str | None:
    """The role the statement runs as, or None when the wrapper must be (re)made. A
    superuser never runs statements as itself (it can always make the reader role)."""
    if state.owner == READER_ROLE and state.reader_ready:
        return READER_ROLE
    if state.owner == state.user and raw in _NO_READER and not state.superuser:
        return state.user
    return None


@contextmanager
def _pg_transaction(db: Any, raw: Any, bounds: Limits) -> Iterator[tuple[Any, _State]]:
    """A read-only transaction with the statement's bounds, always rolled back; then session
    advisory locks it left (they outlive rollbacks) close the connection."""
    import psycopg

    conn = db.connection
    conn.info["write"] = False
    trans = conn.begin()
    before: int | None = None
    try:
        cur = raw.cursor()
        db.backend.set_read_only(cur)
        temp_kb = max(2**20, 2 * bounds.max_bytes >> 10)
        cur.execute(_SETUP, {"timeout": f"{round(bounds.timeout_s * 1000)}ms",
                             "temp": f"{temp_kb}kB", "run": _RUN_SIGNATURE, "body": _RUN_BODY,
                             "reader": READER_ROLE})
        state = _State(*cur.fetchone()[4:])
        before = state.advisory
        yield cur, state
    except psycopg.Error as exc:
        raise _pg_error(exc.sqlstate, _first_line(exc), bounds) from None
    finally:
        trans.rollback()
        if before is not None:
            _check_advisory(conn, raw, before)


def _check_advisory(conn: Any, raw: Any, before: int) -> None:
    import psycopg
    from psycopg import pq

    if raw.closed:
        return
    try:
        result = raw.pgconn.exec_(_ADVISORY.encode())
    except psycopg.Error:
        result = None
    if result is None or result.status != pq.ExecStatus.TUPLES_OK:
        conn.invalidate()  # the session is broken: the original error tells why
        return
    if int(result.get_value(0, 0) or 0) > before:
        conn.invalidate()  # closing the session releases them
        msg = ("statement refused, it took advisory locks that outlive its transaction (the "
               "connection was closed to release them): rerun with --write")
        raise ReadOnlyError(msg)


def _pg_text(raw: Any, sql: str, params: Any) -> str:
    """The statement with its parameters as literals (psycopg's client-side binding)."""
    import psycopg

    try:
        sql.encode(raw.info.encoding)
    except UnicodeEncodeError as exc:
        msg = f"SQL error: the statement is not valid {raw.info.encoding} text ({exc.reason})"
        raise ToasterError(msg) from None
    if not params:
        return sql
    query = pyformat(sql, tokenize(sql, "postgresql")) if isinstance(params, dict) else sql
    try:
        return psycopg.ClientCursor(raw).mogrify(query, params)
    except (psycopg.Error, TypeError, ValueError) as exc:
        msg = f"SQL error: {_first_line(exc)} (give every :name with --param name=VALUE)"
        raise ToasterError(msg) from None


def _pg_run(db: Any, cur: Any, raw: Any, text: str, state: _State, role: str,
            bounds: Limits) -> ReadResult:
    """Describe the statement, run it through the wrapper as ``role``, check what is left."""
    import psycopg
    from psycopg import pq

    if role == READER_ROLE:
        cur.execute(f"SET LOCAL ROLE {READER_ROLE}")
    names, fields = _describe(raw, text, bounds)
    if not names:
        msg = "SQL error: the statement returns no column: select at least one"
        raise ToasterError(msg)
    # The protocol names a domain's base type; a table column's own type keeps the domain.
    cur.execute("SELECT pg_catalog.format_type(coalesce(a.atttypid, u.o), "
                "coalesce(a.atttypmod, u.m)), t.typtype FROM ROWS FROM ("
                "pg_catalog.jsonb_to_recordset(%s::jsonb) AS (o oid, m int4, tb oid, col int2)) "
                "WITH ORDINALITY AS u(o, m, tb, col, i) LEFT JOIN pg_catalog.pg_attribute a "
                "ON a.attrelid = u.tb AND a.attnum = u.col AND u.tb <> 0 "
                "JOIN pg_catalog.pg_type t ON t.oid = coalesce(a.atttypid, u.o) ORDER BY u.i",
                [json.dumps([dict(zip(("o", "m", "tb", "col"), f, strict=True)) for f in fields])])
    types = cur.fetchall()
    for name, (type_name, kind) in zip(names, types, strict=True):
        if kind == "p":
            msg = (f"SQL error: column {name!r} has the pseudo-type {type_name}, which "
                   f"read-only SQL cannot return: cast it, e.g. (...)::text AS {name}")
            raise ToasterError(msg)
    columns = ", ".join(f"c{i} {type_name}" for i, (type_name, _) in enumerate(types))
    try:
        cur.execute(f"SELECT * FROM {_RUN}(%s::text, %s::integer, %s::bigint) "
                    f"AS t({columns})", [text, bounds.max_rows, bounds.max_bytes])
        rows = cur.fetchall()
    except psycopg.Error as exc:
        error = _pg_error(exc.sqlstate, _first_line(exc), bounds)
        if exc.sqlstate == "42501" and _RELATION_DENIED.search(_first_line(exc)):
            raise _Denied(error) from None
        raise error from None
    cur.execute(f"SELECT current_user, current_setting('transaction_read_only'), {_VXID}")
    after = cur.fetchone()
    if raw.info.transaction_status != pq.TransactionStatus.INTRANS or \
            tuple(after) != (role, "on", state.vxid):
        db.connection.invalidate()
        msg = ("statement refused, it left its read-only transaction or role (rolled back, "
               "connection closed): rerun with --write")
        raise ReadOnlyError(msg)
    return ReadResult(names, [tuple(r) for r in rows[:bounds.max_rows]],
                      len(rows) > bounds.max_rows)


def _describe(raw: Any, text: str, bounds: Limits) -> tuple[list[str], list[list[int]]]:
    """Column names and ``[type, modifier, table, column number]`` of ``text``, parsed (not
    run) by the server as one statement of the extended protocol, which refuses several."""
    from psycopg import pq

    encoding = raw.info.encoding
    pgconn = raw.pgconn
    result = pgconn.prepare(b"", text.encode(encoding), None)
    if result.status == pq.ExecStatus.COMMAND_OK:
        result = pgconn.describe_prepared(b"")
    if result.status != pq.ExecStatus.COMMAND_OK:
        sqlstate = (result.error_field(pq.DiagnosticField.SQLSTATE) or b"").decode()
        message = (result.error_field(pq.DiagnosticField.MESSAGE_PRIMARY) or
                   result.error_message or b"error").decode(encoding, "replace")
        raise _pg_error(sqlstate, message.strip().splitlines()[0], bounds)
    fields = range(result.nfields)
    return ([(result.fname(i) or b"").decode(encoding) for i in fields],
            [[result.ftype(i), result.fmod(i), result.ftable(i), result.ftablecol(i)]
             for i in fields])


def _pg_error(sqlstate: str | None, message: str, bounds: Limits) -> ToasterError:
    if sqlstate == "57014":
        return _timeout(bounds)
    if sqlstate == "54000" and message.startswith("toaster: result over"):
        try:
            _too_big(bounds)
        except ToasterError as exc:
            return exc
    if sqlstate == "25006":
        return ReadOnlyError(f"statement refused, the database is opened read-only: rerun "
                             f"with --write ({message})")
    if sqlstate in ("42501", "0A000"):
        return ReadOnlyError(f"statement refused by read-only SQL ({message}): rerun with "
                             "--write")
    if sqlstate == "42804" and "RETURN NEXT" in message:
        return ToasterError("SQL error: a column computed as a domain type cannot be returned "
                            "by read-only SQL: cast it to its base type, e.g. (...)::integer")
    if sqlstate == "42601" and "multiple commands" in message:
        return ReadOnlyError("read-only SQL runs exactly one statement (this has several): "
                             "run them one at a time, or all with --write")
    return ToasterError(f"SQL error: {message}")


def _first_line(exc: BaseException) -> str:
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]
