"""Per-agent views: each agent's current facts, memory and events readable as its own table.

For an agent ``X`` toaster creates ``fact_table_X`` (current beliefs), ``memory_table_X`` (past
beliefs, closed intervals) and ``events_table_X``, as in the original, but as views over the
shared tables. Names are quoted identifiers, so any id works (``SELECT * FROM
"fact_table_Bob's robot"``). The agent id never appears in the view's SQL: the view filters on
the agent's small integer ``num``. Names longer than PostgreSQL's 63-byte limit are shortened
with a hash suffix on both backends, so the same name works everywhere.

Each view shows toaster's columns, then the original's (:data:`ORIGINAL`), and
``fact_table_X`` and ``events_table_X`` take writes as the original's tables did
(:mod:`toaster.db.view_writes`, revision 0017, which keeps a frozen copy of
:func:`agent_ddl`).
"""

from __future__ import annotations

import hashlib
import re

from sqlalchemy import Connection

from toaster.db import view_writes
from toaster.db.dialects.base import Cursor
from toaster.db.engine import dbapi

MAX_IDENTIFIER_BYTES = 63
PREFIXES = ("fact_table_", "memory_table_", "events_table_")
#: The original's columns (database_manager's tables) after toaster's: (name, expression).
#: Names are lower case, so that the original's unquoted ``propertyType`` finds them on
#: PostgreSQL too (which folds it); ``end`` is a reserved word there: write ``"end"``.
_FACT_ORIGINAL = (
    ("predicate", "property"),
    ("propertytype", "property_type"),
    ("valuetype", "CASE WHEN value_num IS NULL THEN 0 ELSE 1 END"),
    ("valuestring", "value_text"),
    ("valuedouble", "value_num"),
    ("start", "valid_from_ns"),
    ('"end"', "COALESCE(valid_to_ns, 0)"),
)
ORIGINAL = {
    "fact_table": _FACT_ORIGINAL,
    "memory_table": _FACT_ORIGINAL,
    "events_table": (
        ("predicate", "CASE WHEN kind = 'ended' THEN '!' || property ELSE property END"),
        ("propertytype", "property_type"),
        ("time", "stamp_ns"),
    ),
}
_SOURCES = {"fact_table": "current_facts", "memory_table": "memory", "events_table": "event_log"}
_PLACEHOLDER = re.compile(r"\{\{(\w+)\}\}")


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


def agent_ddl(backend: str) -> list[str]:
    """The statements that (re)create an agent's views and their write triggers, as
    templates: ``{{fact_table}}``, ``{{memory_table}}``, ``{{events_table}}`` (the views'
    quoted names) and ``{{num}}`` (the agent's number). PostgreSQL's triggers call the
    functions of :func:`toaster.db.view_writes.pg_functions`, which revision 0017 installs."""
    found = []
    for view, source in _SOURCES.items():
        extra = ", ".join(f"{expression} AS {name}" for name, expression in ORIGINAL[view])
        found += [
            f"DROP VIEW IF EXISTS {{{{{view}}}}}",
            f"CREATE VIEW {{{{{view}}}}} AS SELECT *, {extra} FROM {source} "
            f"WHERE agent_id = (SELECT id FROM agents WHERE num = {view_writes.NUM})",
        ]
    triggers = (
        view_writes.pg_triggers() if backend == "postgresql" else view_writes.sqlite_triggers()
    )
    return found + triggers


def fill(templates: list[str], agent_id: str, num: int) -> list[str]:
    """``templates`` (:func:`agent_ddl`) for the agent ``agent_id`` numbered ``num``."""
    values = {
        prefix[:-1]: quote_identifier(name)
        for prefix, name in zip(PREFIXES, agent_view_names(agent_id), strict=True)
    }
    values["num"] = str(int(num))
    return [_PLACEHOLDER.sub(lambda m: values[m.group(1)], t) for t in templates]


def create_agent_views(conn: Connection, agent_id: str, num: int) -> None:
    """Create the three views of an agent, and their write triggers, inside the caller's
    transaction."""
    cur = _ddl_cursor(conn)
    for statement in fill(agent_ddl(conn.dialect.name), agent_id, num):
        cur.execute(statement)


def drop_agent_views(conn: Connection, agent_id: str) -> None:
    """Drop an agent's views, and with them their triggers (used when the agent is
    removed)."""
    cur = _ddl_cursor(conn)
    for name in agent_view_names(agent_id):
        cur.execute(f"DROP VIEW IF EXISTS {quote_identifier(name)}")


def schema_ddl(backend: str) -> dict[str, list[str]]:
    """What the schema holds for the views' writes, beside each agent's statements
    (:func:`agent_ddl`): ``create`` and ``drop`` of PostgreSQL's trigger functions (none on
    SQLite). Revision 0017 froze both (``migrations/frozen/0017_agent_views.json``);
    ``tests/migrations/test_agent_views.py`` checks that they are still what this renders."""
    if backend == "postgresql":
        return view_writes.pg_functions()
    return {"create": [], "drop": []}
