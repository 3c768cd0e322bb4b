"""The original's scripts write the per-agent views (issue 27).

Every agent's ``fact_table_X`` / ``memory_table_X`` / ``events_table_X`` is created again
with the original's column names after toaster's (``predicate``, ``propertytype``,
``valuetype``, ``valuestring``, ``valuedouble``, ``start``, ``"end"``; ``time`` for events),
and ``fact_table_X`` and ``events_table_X`` get INSTEAD OF triggers that write through
``fact_inbox`` (:mod:`toaster.db.view_writes`): INSERT asserts, DELETE retracts now, UPDATE of
``"end"`` retracts then, INSERT into the events view records a point event. On PostgreSQL two
functions (``toaster_fact_table_write``, ``toaster_events_table_write``) hold the checks and
writes and each agent's triggers call them with its number; SQLite inlines them in each agent's
triggers. Agents registered without views (recordings) stay so. Frozen in
``0017_agent_views.json`` (``agent``: an agent's statements now, ``agent_before``: as 0016 made
them); the rule's triggers are unchanged.

Revision ID: 0017
Revises: 0016
Create Date: 2026-11-29
"""

from __future__ import annotations

import hashlib

import sqlalchemy as sa
from alembic import op

from toaster.migrations.frozen_triggers import agent_statements, execute_frozen, run_frozen

revision = "0017"
down_revision = "0016"
branch_labels = None
depends_on = None

_FROZEN = "0017_agent_views"
_PREFIXES = ("fact_table_", "memory_table_", "events_table_")


def _view_names(agent_id: str) -> dict[str, str]:
    """The per-agent views' quoted names by placeholder (frozen copy of
    toaster.db.views.view_name and quote_identifier)."""
    names = {}
    for prefix in _PREFIXES:
        name = prefix + agent_id
        if len(name.encode()) > 63:
            digest = hashlib.sha1(agent_id.encode()).hexdigest()[:10]
            room = 63 - len(prefix) - len(digest) - 1
            name = f"{prefix}{agent_id.encode()[:room].decode(errors='ignore')}_{digest}"
        names[prefix[:-1]] = '"' + name.replace('"', '""') + '"'
    return names


def _recreate(which: str) -> None:
    """Make every agent's views (those of agents that have them) as ``which`` froze them."""
    bind = op.get_bind()
    existing = set(sa.inspect(bind).get_view_names())
    for agent_id, num in bind.execute(sa.text("SELECT id, num FROM agents ORDER BY num")).all():
        names = _view_names(agent_id)
        if not any(name[1:-1].replace('""', '"') in existing for name in names.values()):
            continue
        execute_frozen(bind, agent_statements(_FROZEN, bind.dialect.name, which, names, num))


def upgrade() -> None:
    run_frozen(op.get_bind(), _FROZEN, "create")
    _recreate("agent")


def downgrade() -> None:
    _recreate("agent_before")
    run_frozen(op.get_bind(), _FROZEN, "drop")
