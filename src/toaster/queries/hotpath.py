"""How the read path's hot statements run (as-of, point reads): one round trip, planned once.

Outside the caller's transaction a read is one autocommitted statement on the shared
connection: its own snapshot, as a transaction of that one statement would be, without the
``BEGIN`` and ``COMMIT`` around it (on PostgreSQL one round trip instead of three; each costs
most when the server waits for a CPU). Inside the caller's transaction it joins it.

``prepare``: PostgreSQL prepares the statement from its first call on the connection; psycopg
would at its 5th, and the server plans a prepared statement anew for its first 5 executions
before it keeps a generic plan, so the first ten calls paid planning, which costs more than
the as-of seeks themselves. sqlite3 keeps its recent statements prepared by their text.
This module is the one place the read path runs statements differently per backend.
"""

from __future__ import annotations

from contextlib import suppress
from typing import TYPE_CHECKING, Any, cast

from toaster.db.engine import dbapi, refused_value

if TYPE_CHECKING:
    import psycopg

    from toaster.db.database import Database
    from toaster.db.dialects.base import Cursor


def fetch(db: Database, sql: str, params: dict[str, Any], *, prepare: bool = False) -> list[Any]:
    """The rows of one read statement ``sql`` (the driver's parameter style). A value the
    database refuses is one :class:`~toaster.errors.InvalidInputError`, as in
    :meth:`~toaster.db.database.Database.transaction`."""
    try:
        return _fetch(db, sql, params, prepare)
    except Exception as exc:  # raw cursors raise the drivers' own errors
        error = refused_value(exc)
        if error is None:
            raise
        raise error from exc


def _fetch(db: Database, sql: str, params: dict[str, Any], prepare: bool) -> list[Any]:
    conn = db.connection
    if conn.in_transaction():
        return _run(db, db.cursor(), sql, params, prepare)
    raw = dbapi(conn)
    if db.dialect_name != "postgresql":  # sqlite3 outside BEGIN runs it autocommitted
        return _run(db, raw.cursor(), sql, params, prepare)
    raw.autocommit = True  # idle between SQLAlchemy's transactions: no round trip
    try:
        rows = _run(db, raw.cursor(), sql, params, prepare)
    except BaseException:
        with suppress(Exception):  # a lost connection refuses it: keep the first error
            raw.autocommit = False
        raise
    raw.autocommit = False
    return rows


def _run(db: Database, cur: Cursor, sql: str, params: dict[str, Any], prepare: bool) -> list[Any]:
    if prepare and db.dialect_name == "postgresql":
        cast("psycopg.Cursor[Any]", cur).execute(sql, params, prepare=True)
    else:
        cur.execute(sql, params)
    rows = list(cur.fetchall())
    cur.close()
    return rows
