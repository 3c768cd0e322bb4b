"""Per-agent views: each agent's current facts, memory and events readable as its own table.

For an agent ``X`` toaster creates ``fact_table_X`` (current beliefs), ``memory_table_X`` (past
beliefs, closed intervals) and ``events_table_X``, as in the original, but as views over the
shared tables. Names are quoted identifiers, so any id works (``SELECT * FROM
"fact_table_Bob's robot"``). The agent id never appears in the view's SQL: the view filters on
the agent's small integer ``num``. Names longer than PostgreSQL's 63-byte limit are shortened
with a hash suffix on both backends, so the same name works everywhere.
"""

from __future__ import annotations

import hashlib

from sqlalchemy import Connection

from toaster.db.dialects.base import Cursor
from toaster.db.engine import dbapi

MAX_IDENTIFIER_BYTES = 63
PREFIXES = ("fact_table_", "memory_table_", "events_table_")
_SOURCES = ("current_facts", "memory", "event_log")


def view_name(prefix: str, agent_id: str) -> str:
    """The view name for ``agent_id`` with ``prefix``, shortened to 63 bytes when needed."""
    name = prefix + agent_id
    if len(name.encode()) <= MAX_IDENTIFIER_BYTES:
        return name
    digest = hashlib.sha1(agent_id.encode()).hexdigest()[:10]
    room = MAX_IDENTIFIER_BYTES - len(prefix) - len(digest) - 1
    head = agent_id.encode()[:room].decode(errors="ignore")
    return f"{prefix}{head}_{digest}"


def agent_view_names(agent_id: str) -> tuple[str, str, str]:
    """``(fact view, memory view, events view)`` of an agent."""
    return tuple(view_name(p, agent_id) for p in PREFIXES)  # type: ignore[return-value]


def quote_identifier(name: str) -> str:
    """Standard SQL quoting (the same on both backends; SQLAlchemy's preparer would double
    ``%`` for psycopg, which raw DDL must not do)."""
    return '"' + name.replace('"', '""') + '"'


def _ddl_cursor(conn: Connection) -> Cursor:
    # DDL goes to the driver without parameters, so that neither SQLAlchemy (':name') nor
    # psycopg ('%s') reads placeholders inside a quoted identifier.
    return dbapi(conn).cursor()


def create_agent_views(conn: Connection, agent_id: str, num: int) -> None:
    """Create the three views of an agent inside the caller's transaction."""
    cur = _ddl_cursor(conn)
    for name, source in zip(agent_view_names(agent_id), _SOURCES, strict=True):
        cur.execute(f"DROP VIEW IF EXISTS {quote_identifier(name)}")
        cur.execute(
            f"CREATE VIEW {quote_identifier(name)} AS SELECT * FROM {source} "
            f"WHERE agent_id = (SELECT id FROM agents WHERE num = {int(num)})"
        )


def drop_agent_views(conn: Connection, agent_id: str) -> None:
    """Drop an agent's views (used when the agent is removed)."""
    cur = _ddl_cursor(conn)
    for name in agent_view_names(agent_id):
        cur.execute(f"DROP VIEW IF EXISTS {quote_identifier(name)}")
