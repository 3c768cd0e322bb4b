"""The PostgreSQL guard: a read-only transaction, the role :data:`READER_ROLE` (made and
granted by :func:`ensure_reader_role`) and a ``SECURITY DEFINER`` wrapper, inside which no
role can be taken; checks after the statement, then a rollback whatever happened."""

from __future__ import annotations

import json
import re
import weakref
from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, NamedTuple, cast

from toaster.db.readonly.bounds import (
    Limits,
    ReadRows,
    first_line,
    require_own_transaction,
    timeout_error,
    too_big_error,
)
from toaster.db.readonly.tokens import check_statement, pyformat, tokenize
from toaster.errors import ReadOnlyError, ToasterError

if TYPE_CHECKING:
    import psycopg
    from sqlalchemy import Connection

    from toaster.db.database import Database
    from toaster.db.dialects.base import Cursor

#: The PostgreSQL role read-only statements run as (NOLOGIN, SELECT on toaster's schema).
READER_ROLE = "toaster_reader"
_RUN = "pg_temp.toaster_readonly_run"
_RUN_SIGNATURE = f"{_RUN}(text, integer, bigint)"
# SECURITY DEFINER: while it runs, PostgreSQL refuses to change "role" or
# "session_authorization" by any means (SET ROLE, set_config, in any nested function), even
# for a superuser session. Its owner is READER_ROLE (else the connecting role). No SET
# search_path: the statement resolves names as the caller would. Stops after max_rows + 1
# rows (the extra one says "truncated") and before max_bytes of text. It runs only as the
# outermost call: PG_CONTEXT (the call stack, which no statement can forge) is one line
# then, and longer when a statement calls it, e.g. to run SQL hidden in a string literal.
_RUN_BODY = """
DECLARE
  r record;
  n integer := 0;
  size bigint := 0;
  stack text;
BEGIN
  GET DIAGNOSTICS stack = PG_CONTEXT;
  IF pg_catalog.strpos(stack, E'\\n') > 0 THEN
    RAISE EXCEPTION 'toaster: the read-only wrapper cannot be called by a statement'
      USING ERRCODE = '42501';
  END IF;
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
_CREATE_RUN = (
    f"CREATE FUNCTION {_RUN}(q text, max_rows integer, max_bytes bigint) "
    "RETURNS SETOF record LANGUAGE plpgsql SECURITY DEFINER "
    f"AS $toaster${_RUN_BODY}$toaster$"
)
_PID = "pid = pg_catalog.pg_backend_pid()"
_VXID = f"(SELECT virtualxid FROM pg_catalog.pg_locks WHERE locktype = 'virtualxid' AND {_PID})"
_ADVISORY = f"SELECT count(*) FROM pg_catalog.pg_locks WHERE locktype = 'advisory' AND {_PID}"
_SCHEMA = "(SELECT oid FROM pg_catalog.pg_namespace WHERE nspname = current_schema())"
_UNGRANTED = (
    f"FROM pg_catalog.pg_class c WHERE c.relnamespace = {_SCHEMA} "
    "AND c.relkind IN ('r', 'v', 'm', 'p', 'f') "
    "AND NOT pg_catalog.has_table_privilege(r.oid, c.oid, 'SELECT')"
)
_SAFE = (
    "NOT (r.rolsuper OR r.rolcreaterole OR r.rolcreatedb OR r.rolreplication "
    "OR r.rolbypassrls) AND NOT EXISTS (SELECT FROM pg_catalog.pg_auth_members m "
    "WHERE m.member = r.oid)"
)
_USAGE = (
    "current_schema() IS NOT NULL "
    "AND pg_catalog.has_schema_privilege(r.oid, current_schema(), 'USAGE')"
)
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
    FROM pg_catalog.pg_roles r WHERE r.rolname = %(reader)s),
  pg_catalog.pg_is_in_recovery()
"""
#: The cursor over the wrapper's result, and how many rows each FETCH takes.
_CURSOR = "toaster_rows"
_BATCH = 256
_RELATION_DENIED = re.compile(r"permission denied for (table|view|materialized view|relation)")
#: A hot standby can create nothing, not even the session's wrapper (a temporary function).
_STANDBY = (
    "read-only SQL cannot run on a hot standby (its guard needs a temporary function, which a "
    "standby cannot create): run it on the primary, or on the standby with a SQL client "
    "such as psql (the standby refuses every write itself)"
)
#: Connections where READER_ROLE cannot be used, and why (they run as their own role).
_NO_READER: weakref.WeakKeyDictionary[psycopg.Connection, str] = weakref.WeakKeyDictionary()


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
    standby: bool


@contextmanager
def read_postgresql(db: Database, sql: str, params: Any, bounds: Limits) -> Iterator[ReadRows]:
    """Run one read statement on PostgreSQL (see the module's doc) and give its rows, fetched
    in batches from the wrapper's result (held by the server) while the transaction is open;
    roll back whatever happens. Sets up READER_ROLE and the wrapper on first use
    (:func:`ensure_reader_role`)."""
    raw = cast("psycopg.Connection", db.connection.connection.dbapi_connection)  # psycopg's
    text = _pg_text(raw, sql, params)
    check_statement(text, "postgresql")
    require_own_transaction(db.connection)
    prepared = False
    while True:
        with _pg_transaction(db, raw, bounds) as (cur, state):
            role = _role(raw, state)
            if role is None and state.standby:
                raise ToasterError(_STANDBY)
            if role is not None:
                try:
                    rows = _pg_start(db, cur, raw, text, state, role, bounds)
                except _Denied as denied:  # a table made since the grants, perhaps
                    if prepared or role != READER_ROLE:
                        raise denied.error from None
                else:
                    yield rows
                    return
            elif prepared:
                msg = (
                    f"cannot set up read-only SQL on PostgreSQL ({_NO_READER.get(raw)}): "
                    f"fix role {READER_ROLE} or this role's TEMP privilege, or use --write"
                )
                raise ToasterError(msg)
        _prepare(db, raw)
        prepared = True


def ensure_reader_role(cur: Cursor) -> str | None:
    """Create :data:`READER_ROLE` if missing (NOLOGIN, no attributes), let the current role
    take it, and grant it USAGE on ``current_schema()`` and SELECT on its tables and views.

    Returns None when the role is usable, else why not (read-only SQL then runs as the
    connecting role). Runs in the caller's write transaction (a migration may call it).
    """
    for _ in range(2):  # a concurrent CREATE ROLE may win the race: look again
        cur.execute(
            f"SELECT {_SAFE}, pg_catalog.pg_has_role(r.oid, 'MEMBER') "
            "FROM pg_catalog.pg_roles r WHERE r.rolname = %s",
            [READER_ROLE],
        )
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
    cur.execute(
        f"SELECT pg_catalog.quote_ident(current_schema()), {_GRANTED} "
        "FROM pg_catalog.pg_roles r WHERE r.rolname = %s",
        [READER_ROLE],
    )
    schema, granted = cur.fetchone()
    if schema is None:
        return "no current schema (search_path names none that exists)"
    if granted:
        return None
    _savepoint(cur, f"GRANT USAGE ON SCHEMA {schema} TO {READER_ROLE}")
    cur.execute(
        f"SELECT c.oid::regclass::text FROM pg_catalog.pg_roles r, "
        f"pg_catalog.pg_class c WHERE r.rolname = %s AND c.relnamespace = {_SCHEMA} "
        "AND c.relkind IN ('r', 'v', 'm', 'p', 'f') "
        "AND NOT pg_catalog.has_table_privilege(r.oid, c.oid, 'SELECT')",
        [READER_ROLE],
    )
    missing = [name for (name,) in cur.fetchall()]
    if missing:
        _savepoint(cur, f"GRANT SELECT ON TABLE {', '.join(missing)} TO {READER_ROLE}")
    cur.execute(f"SELECT {_GRANTED} FROM pg_catalog.pg_roles r WHERE r.rolname = %s", [READER_ROLE])
    if not cur.fetchone()[0]:
        return (
            f"cannot grant {READER_ROLE} SELECT on every table of schema {schema} "
            "(only their owner can)"
        )
    return None


def _savepoint(cur: Cursor, statement: str) -> str | None:
    """Run ``statement`` in a savepoint: None, or ``SQLSTATE message`` when it failed."""
    import psycopg

    cur.execute("SAVEPOINT toaster_readonly")
    try:
        cur.execute(statement)
    except psycopg.Error as exc:
        cur.execute("ROLLBACK TO SAVEPOINT toaster_readonly")
        return f"{exc.sqlstate} {first_line(exc)}"
    cur.execute("RELEASE SAVEPOINT toaster_readonly")
    return None


def _prepare(db: Database, raw: psycopg.Connection) -> None:
    """(Re)create this session's wrapper, owned by READER_ROLE when it is usable."""
    import psycopg

    try:
        with db.transaction(write=True):
            cur = raw.cursor()
            cur.execute(
                "SELECT pg_catalog.pg_advisory_xact_lock("
                "pg_catalog.hashtext('toaster read-only setup'))"
            )
            reason = ensure_reader_role(cur)
            cur.execute(f"DROP FUNCTION IF EXISTS {_RUN_SIGNATURE}")
            cur.execute(_CREATE_RUN)
            if reason is None and (
                failed := _savepoint(cur, f"ALTER FUNCTION {_RUN_SIGNATURE} OWNER TO {READER_ROLE}")
            ):
                reason = f"cannot give role {READER_ROLE} the wrapper: {failed}"
    except psycopg.Error as exc:
        _NO_READER[raw] = first_line(exc)
        return
    if reason is None:
        _NO_READER.pop(raw, None)
    else:
        _NO_READER[raw] = reason


def _role(raw: psycopg.Connection, state: _State) -> str | None:
    """The role the statement runs as, or None when the wrapper must be (re)made. A
    superuser never runs statements as itself (it can always make the reader role)."""
    if state.owner == READER_ROLE and state.reader_ready:
        return READER_ROLE
    if state.owner == state.user and raw in _NO_READER and not state.superuser:
        return state.user
    return None


@contextmanager
def _pg_transaction(
    db: Database, raw: psycopg.Connection, bounds: Limits
) -> Iterator[tuple[Cursor, _State]]:
    """A read-only transaction with the statement's bounds, always rolled back; then session
    advisory locks it left (they outlive rollbacks) close the connection."""
    import psycopg

    conn = db.connection
    conn.info["write"] = False
    trans = conn.begin()
    before: int | None = None
    try:
        cur: Cursor = raw.cursor()
        db.backend.set_read_only(cur)
        temp_kb = max(2**20, 2 * bounds.max_bytes >> 10)
        cur.execute(
            _SETUP,
            {
                "timeout": f"{round(bounds.timeout_s * 1000)}ms",
                "temp": f"{temp_kb}kB",
                "run": _RUN_SIGNATURE,
                "body": _RUN_BODY,
                "reader": READER_ROLE,
            },
        )
        state = _State(*cur.fetchone()[4:])
        before = state.advisory
        yield cur, state
    except psycopg.Error as exc:
        raise _pg_error(exc.sqlstate, first_line(exc), bounds) from None
    finally:
        trans.rollback()
        if before is not None:
            _check_advisory(conn, raw, before)


def _check_advisory(conn: Connection, raw: psycopg.Connection, before: int) -> None:
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
        msg = (
            "statement refused, it took advisory locks that outlive its transaction (the "
            "connection was closed to release them): rerun with --write"
        )
        raise ReadOnlyError(msg)


def _pg_text(raw: psycopg.Connection, sql: str, params: Any) -> str:
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
        msg = f"SQL error: {first_line(exc)} (give every :name with --param name=VALUE)"
        raise ToasterError(msg) from None


def _pg_start(
    db: Database,
    cur: Cursor,
    raw: psycopg.Connection,
    text: str,
    state: _State,
    role: str,
    bounds: Limits,
) -> ReadRows:
    """Describe the statement, run it through the wrapper as ``role`` (a plpgsql set-returning
    function runs to its end on the first FETCH), check what is left, then give its rows."""
    import psycopg
    from psycopg import pq

    if role == READER_ROLE:
        cur.execute(f"SET LOCAL ROLE {READER_ROLE}")
    names, fields = _describe(raw, text, bounds)
    if not names:
        msg = "SQL error: the statement returns no column: select at least one"
        raise ToasterError(msg)
    # The protocol names a domain's base type; a table column's own type keeps the domain.
    cur.execute(
        "SELECT pg_catalog.format_type(coalesce(a.atttypid, u.o), "
        "coalesce(a.atttypmod, u.m)), t.typtype FROM ROWS FROM ("
        "pg_catalog.jsonb_to_recordset(%s::jsonb) AS (o oid, m int4, tb oid, col int2)) "
        "WITH ORDINALITY AS u(o, m, tb, col, i) LEFT JOIN pg_catalog.pg_attribute a "
        "ON a.attrelid = u.tb AND a.attnum = u.col AND u.tb <> 0 "
        "JOIN pg_catalog.pg_type t ON t.oid = coalesce(a.atttypid, u.o) ORDER BY u.i",
        [json.dumps([dict(zip(("o", "m", "tb", "col"), f, strict=True)) for f in fields])],
    )
    types = cur.fetchall()
    for name, (type_name, kind) in zip(names, types, strict=True):
        if kind == "p":
            msg = (
                f"SQL error: column {name!r} has the pseudo-type {type_name}, which "
                f"read-only SQL cannot return: cast it, e.g. (...)::text AS {name}"
            )
            raise ToasterError(msg)
    columns = ", ".join(f"c{i} {type_name}" for i, (type_name, _) in enumerate(types))
    try:
        cur.execute(
            f"DECLARE {_CURSOR} NO SCROLL CURSOR FOR SELECT * FROM "
            f"{_RUN}(%s::text, %s::integer, %s::bigint) AS t({columns})",
            [text, bounds.max_rows, bounds.max_bytes],
        )
        first = _fetch(cur)
    except psycopg.Error as exc:
        error = _pg_error(exc.sqlstate, first_line(exc), bounds)
        if exc.sqlstate == "42501" and _RELATION_DENIED.search(first_line(exc)):
            raise _Denied(error) from None
        raise error from None
    cur.execute(
        f"SELECT current_user, current_setting('transaction_read_only'), {_VXID}, ({_ADVISORY})"
    )
    after = cur.fetchone()
    if raw.info.transaction_status != pq.TransactionStatus.INTRANS or tuple(after) != (
        role,
        "on",
        state.vxid,
        state.advisory,
    ):
        db.connection.invalidate()
        msg = (
            "statement refused, it left its read-only transaction or role, or took locks "
            "(rolled back, connection closed): rerun with --write"
        )
        raise ReadOnlyError(msg)
    return ReadRows(names, _pg_rows(cur, first, bounds), bounds.max_rows)


def _fetch(cur: Cursor) -> list[tuple[Any, ...]]:
    cur.execute(f"FETCH FORWARD {_BATCH} FROM {_CURSOR}")
    return [tuple(r) for r in cur.fetchall()]


def _pg_rows(
    cur: Cursor, batch: list[tuple[Any, ...]], bounds: Limits
) -> Iterator[tuple[Any, ...]]:
    """The rows, a batch at a time: the client holds one batch."""
    import psycopg

    while True:
        yield from batch
        if len(batch) < _BATCH:
            return
        try:
            batch = _fetch(cur)
        except psycopg.Error as exc:
            raise _pg_error(exc.sqlstate, first_line(exc), bounds) from None


def _describe(
    raw: psycopg.Connection, text: str, bounds: Limits
) -> tuple[list[str], list[list[int]]]:
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
        message = (
            result.error_field(pq.DiagnosticField.MESSAGE_PRIMARY)
            or result.error_message
            or b"error"
        ).decode(encoding, "replace")
        raise _pg_error(sqlstate, message.strip().splitlines()[0], bounds)
    fields = range(result.nfields)
    return (
        [(result.fname(i) or b"").decode(encoding) for i in fields],
        [[result.ftype(i), result.fmod(i), result.ftable(i), result.ftablecol(i)] for i in fields],
    )


def _pg_error(sqlstate: str | None, message: str, bounds: Limits) -> ToasterError:
    if sqlstate == "57014":
        return timeout_error(bounds)
    if sqlstate == "54000" and message.startswith("toaster: result over"):
        return too_big_error(bounds)
    if sqlstate == "25006":
        return ReadOnlyError(
            f"statement refused, the database is opened read-only: rerun with --write ({message})"
        )
    if sqlstate in ("42501", "0A000"):
        return ReadOnlyError(f"statement refused by read-only SQL ({message}): rerun with --write")
    if sqlstate == "42804" and "RETURN NEXT" in message:
        return ToasterError(
            "SQL error: a column computed as a domain type cannot be returned "
            "by read-only SQL: cast it to its base type, e.g. (...)::integer"
        )
    if sqlstate == "42601" and "multiple commands" in message:
        return ReadOnlyError(
            "read-only SQL runs exactly one statement (this has several): "
            "run them one at a time, or all with --write"
        )
    return ToasterError(f"SQL error: {message}")
