"""Belief rules: nested belief holders, the rule statements of each backend, default settings.

The statements are frozen in ``toaster/migrations/sql/0002/<backend>-NN_step.sql`` and copied
into ``belief_rules`` for the database's backend; every store process runs them from there
(see :mod:`toaster.beliefs.rules`). Rule configuration is data in ``settings`` (scope
``beliefs``).

Revision ID: 0002
Revises: 0001
Create Date: 2026-11-23
"""

from __future__ import annotations

import hashlib
import json
from importlib import resources

import sqlalchemy as sa
from alembic import op

revision = "0002"
down_revision = "0001"
branch_labels = None
depends_on = None

#: Defaults of the belief rules, frozen as of this revision (scope ``beliefs``).
DEFAULT_SETTINGS = {
    "enabled": True,
    "depth": 2,
    "copresence": ["IsInRoom"],
    "containment": ["IsIn", "IsOn"],
    "visibility": {"IsVisibleBy": "target", "CanSee": "subject", "IsLookingToward": "subject"},
    "closed": "IsClosed",
    "refute_by_target": ["IsOn"],
    "self_perception": False,
}


def _statements(backend: str) -> list[tuple[str, str]]:
    folder = resources.files("toaster") / "migrations" / "sql" / "0002"
    prefix = backend + "-"
    files = sorted((p for p in folder.iterdir()
                    if p.name.startswith(prefix) and p.name.endswith(".sql")),
                   key=lambda p: p.name)
    return [(p.name[len(prefix):-4], p.read_text(encoding="utf-8")) for p in files]


def upgrade() -> None:
    """Create ``belief_chain`` and ``belief_rules``; install statements and settings."""
    op.create_table(
        "belief_chain",
        sa.Column("holder_id", sa.Text(), nullable=False),
        sa.Column("position", sa.Integer(), nullable=False),
        sa.Column("member_id", sa.Text(), nullable=False),
        sa.CheckConstraint("position >= 1", name=op.f("ck_belief_chain_position_positive")),
        sa.ForeignKeyConstraint(["holder_id"], ["agents.id"], ondelete="CASCADE",
                                name=op.f("fk_belief_chain_holder_id_agents")),
        sa.ForeignKeyConstraint(["member_id"], ["agents.id"], ondelete="CASCADE",
                                name=op.f("fk_belief_chain_member_id_agents")),
        sa.PrimaryKeyConstraint("holder_id", "position", name=op.f("pk_belief_chain")),
    )
    with op.batch_alter_table("belief_chain", schema=None) as batch_op:
        batch_op.create_index("ix_belief_chain_member_id", ["member_id"], unique=False)
    op.create_table(
        "belief_rules",
        sa.Column("backend", sa.Text(), nullable=False),
        sa.Column("step", sa.Text(), nullable=False),
        sa.Column("sql_text", sa.Text(), nullable=False),
        sa.PrimaryKeyConstraint("backend", "step", name=op.f("pk_belief_rules")),
    )
    bind = op.get_bind()
    backend = bind.dialect.name
    rules = sa.table("belief_rules", sa.column("backend"), sa.column("step"), sa.column("sql_text"))
    op.bulk_insert(rules, [{"backend": backend, "step": step, "sql_text": body}
                           for step, body in _statements(backend)])
    settings = sa.table("settings", sa.column("scope"), sa.column("key"), sa.column("value_json"))
    existing = {row[0] for row in bind.execute(
        sa.text("SELECT key FROM settings WHERE scope = 'beliefs'"))}
    op.bulk_insert(settings, [{"scope": "beliefs", "key": key, "value_json": json.dumps(value)}
                              for key, value in DEFAULT_SETTINGS.items() if key not in existing])


def _view_names(agent_id: str) -> list[str]:
    names = []
    for prefix in ("fact_table_", "memory_table_", "events_table_"):
        name = prefix + agent_id
        if len(name.encode()) > 63:
            digest = hashlib.sha1(agent_id.encode()).hexdigest()[:10]
            room = 63 - len(prefix) - len(digest) - 1
            name = f"{prefix}{agent_id.encode()[:room].decode(errors='ignore')}_{digest}"
        names.append(name)
    return names


def downgrade() -> None:
    """Remove nested holders (their beliefs and views), the tables and the settings."""
    bind = op.get_bind()
    # Raw cursor and standard quoting: no ':name' or '%' placeholder parsing in identifiers.
    cursor = bind.connection.dbapi_connection.cursor()
    holders = [row[0] for row in bind.execute(
        sa.text("SELECT DISTINCT holder_id FROM belief_chain"))]
    for holder in holders:
        for name in _view_names(holder):
            quoted = '"' + name.replace('"', '""') + '"'
            cursor.execute(f"DROP VIEW IF EXISTS {quoted}")
        for table in ("events", "facts", "fact_keys"):
            if table == "facts":
                bind.execute(sa.text("DELETE FROM facts WHERE key_id IN "
                                     "(SELECT id FROM fact_keys WHERE agent_id = :h)"),
                             {"h": holder})
            else:
                bind.execute(sa.text(f"DELETE FROM {table} WHERE agent_id = :h"), {"h": holder})
        bind.execute(sa.text("DELETE FROM belief_chain WHERE holder_id = :h"), {"h": holder})
        bind.execute(sa.text("DELETE FROM agents WHERE id = :h"), {"h": holder})
        bind.execute(sa.text("DELETE FROM entities WHERE id = :h"), {"h": holder})
    with op.batch_alter_table("belief_chain", schema=None) as batch_op:
        batch_op.drop_index("ix_belief_chain_member_id")
    op.drop_table("belief_chain")
    op.drop_table("belief_rules")
    op.execute("DELETE FROM settings WHERE scope = 'beliefs'")
