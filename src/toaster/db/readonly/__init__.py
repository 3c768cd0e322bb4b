"""Read-only SQL for users: one statement that can neither write, end or upgrade its
transaction, switch roles nor act on the server, with its rows, bytes and time bounded.

Three layers (docs/execute.md): a tokenizer that refuses anything but one SELECT-like
statement naming no function with side effects (:mod:`.tokens`); the database (on SQLite a
process of its own, killed at the deadline, with a read-only connection, ``PRAGMA
query_only`` and an authorizer, :mod:`.sqlite`; a read-only transaction, the role
:data:`READER_ROLE` and a ``SECURITY DEFINER`` wrapper, inside which no role can be taken, on
PostgreSQL, :mod:`.postgresql`); checks after the statement, then a rollback whatever
happened. Rows come only from a statement that passed every check, a batch at a time.
:mod:`.bounds` holds the bounds and the rows.
"""

from __future__ import annotations

from toaster.db.readonly.bounds import (
    DEFAULT_MAX_BYTES,
    DEFAULT_MAX_ROWS,
    DEFAULT_TIMEOUT_S,
    Limits,
    ReadRows,
    limits,
)
from toaster.db.readonly.postgresql import READER_ROLE, ensure_reader_role, read_postgresql
from toaster.db.readonly.sqlite import SQLITE_HEAP_LIMIT, read_sqlite
from toaster.db.readonly.tokens import Token, check_statement, pyformat, tokenize

__all__ = [
    "DEFAULT_MAX_BYTES",
    "DEFAULT_MAX_ROWS",
    "DEFAULT_TIMEOUT_S",
    "READER_ROLE",
    "SQLITE_HEAP_LIMIT",
    "Limits",
    "ReadRows",
    "Token",
    "check_statement",
    "ensure_reader_role",
    "limits",
    "pyformat",
    "read_postgresql",
    "read_sqlite",
    "tokenize",
]
