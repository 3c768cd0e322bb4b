"""Belief holders in their own table: nested holders are no longer entities or agents.

``holders``: one row per holder whose beliefs are kept: each agent (``agent_id`` = ``id``,
depth 1; a trigger on ``agents`` adds it, whoever registers the agent) and each nested holder
``A>B`` (``agent_id`` NULL, depth = the length of its chain in ``belief_chain``), registered by
the belief rule. ``fact_keys.agent_id`` and ``belief_chain.holder_id`` now refer to
``holders``; the nested holders' rows in ``agents`` and ``entities`` (kind ``belief``) go.
The rule's triggers are replaced by the frozen copy of this revision (``holders`` registers
into ``holders``; nobody new is ``belief_new_chain``, not a changed count of agents).

SQLite cannot alter a foreign key: the two ``CREATE TABLE`` texts are edited in place
(``PRAGMA writable_schema``, the way SQLite's documentation gives for changes that leave the
stored rows as they are), so that the guarded tables keep their rows, indexes and triggers.

Revision ID: 0008
Revises: 0007
Create Date: 2026-11-24
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from toaster.migrations.frozen_triggers import run_frozen

revision = "0008"
down_revision = "0007"
branch_labels = None
depends_on = None

#: (table, column, constraint prefix): the foreign keys that move from agents to holders.
_MOVED = (("fact_keys", "agent_id"), ("belief_chain", "holder_id"))
_AGENT_HOLDER = {
    "sqlite": [
        "CREATE TRIGGER agents_holder AFTER INSERT ON agents BEGIN "
        "INSERT INTO holders (id, agent_id, depth, registered_ns) "
        "VALUES (NEW.id, NEW.id, 1, NEW.registered_ns); END",
    ],
    "postgresql": [
        "CREATE FUNCTION toaster_agent_holder() RETURNS trigger LANGUAGE plpgsql AS $$ BEGIN "
        "INSERT INTO holders (id, agent_id, depth, registered_ns) "
        "VALUES (NEW.id, NEW.id, 1, NEW.registered_ns); RETURN NULL; END $$",
        "CREATE TRIGGER agents_holder AFTER INSERT ON agents FOR EACH ROW "
        "EXECUTE FUNCTION toaster_agent_holder()",
    ],
}
_DROP_AGENT_HOLDER = {
    "sqlite": ["DROP TRIGGER agents_holder"],
    "postgresql": ["DROP TRIGGER agents_holder ON agents", "DROP FUNCTION toaster_agent_holder()"],
}


def _clause(table: str, column: str, target: str) -> str:
    return (
        f"CONSTRAINT fk_{table}_{column}_{target} FOREIGN KEY({column}) "
        f"REFERENCES {target} (id) ON DELETE CASCADE"
    )


def _move_foreign_keys(old: str, new: str) -> None:
    bind = op.get_bind()
    if bind.dialect.name == "postgresql":
        for table, column in _MOVED:
            op.drop_constraint(f"fk_{table}_{column}_{old}", table, type_="foreignkey")
            op.create_foreign_key(
                f"fk_{table}_{column}_{new}", table, new, [column], ["id"], ondelete="CASCADE"
            )
        return
    cursor = bind.connection.dbapi_connection.cursor()  # type: ignore[union-attr]
    version = cursor.execute("PRAGMA schema_version").fetchone()[0]
    cursor.execute("PRAGMA writable_schema = ON")
    try:
        for table, column in _MOVED:
            before, after = _clause(table, column, old), _clause(table, column, new)
            cursor.execute(
                "UPDATE sqlite_master SET sql = replace(sql, ?, ?) "
                "WHERE type = 'table' AND name = ? AND instr(sql, ?) > 0",
                (before, after, table, before),
            )
            if cursor.rowcount != 1:
                msg = f"{table}: its foreign key {before!r} is not as revision 0001 made it"
                raise RuntimeError(msg)
        cursor.execute(f"PRAGMA schema_version = {int(version) + 1}")
    finally:
        cursor.execute("PRAGMA writable_schema = OFF")


def _writer_role() -> None:
    """PostgreSQL fires the guard of ``belief_chain`` for the (empty) cascades of deleted agents:
    take the store's writer role for this transaction (SQLite's row guards do not fire)."""
    if op.get_bind().dialect.name == "postgresql":
        op.execute("SELECT set_config('toaster.writer', 'rules', true)")


def upgrade() -> None:
    op.create_table(
        "holders",
        sa.Column("id", sa.Text(), nullable=False),
        sa.Column("agent_id", sa.Text(), nullable=True),
        sa.Column("depth", sa.Integer(), nullable=False),
        sa.Column("registered_ns", sa.BigInteger(), nullable=False),
        sa.CheckConstraint(
            "(depth = 1 AND agent_id = id) OR (depth >= 2 AND agent_id IS NULL)",
            name=op.f("ck_holders_agent_or_nested"),
        ),
        sa.ForeignKeyConstraint(
            ["agent_id"], ["agents.id"], ondelete="CASCADE", name=op.f("fk_holders_agent_id_agents")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_holders")),
        sa.UniqueConstraint("agent_id", name=op.f("uq_holders_agent_id")),
    )
    op.execute(
        "INSERT INTO holders (id, agent_id, depth, registered_ns) "
        "SELECT id, id, 1, registered_ns FROM agents "
        "WHERE id NOT IN (SELECT holder_id FROM belief_chain)"
    )
    op.execute(
        "INSERT INTO holders (id, agent_id, depth, registered_ns) "
        "SELECT c.holder_id, NULL, MAX(c.position), MIN(a.registered_ns) "
        "FROM belief_chain c JOIN agents a ON a.id = c.holder_id GROUP BY c.holder_id"
    )
    _move_foreign_keys("agents", "holders")
    _writer_role()
    # The nested holders' entity rows (kind 'belief'); their agent rows go with them.
    op.execute("DELETE FROM entities WHERE id IN (SELECT id FROM holders WHERE depth >= 2)")
    for statement in _AGENT_HOLDER[op.get_bind().dialect.name]:
        op.execute(statement)
    run_frozen(op.get_bind(), "0007_triggers", "drop")
    run_frozen(op.get_bind(), "0008_triggers", "create")


def downgrade() -> None:
    """Nested holders become entities (kind ``belief``) and agents again."""
    run_frozen(op.get_bind(), "0008_triggers", "drop")
    run_frozen(op.get_bind(), "0007_triggers", "create")
    for statement in _DROP_AGENT_HOLDER[op.get_bind().dialect.name]:
        op.execute(statement)
    _writer_role()
    op.execute(
        "INSERT INTO entities (id, name, kind, owner_id, created_ns) "
        "SELECT id, id, 'belief', '', registered_ns FROM holders WHERE depth >= 2"
    )
    op.execute(
        "INSERT INTO agents (id, num, is_self, registered_ns) "
        "SELECT id, (SELECT COALESCE(MAX(num), 0) FROM agents) "
        "+ ROW_NUMBER() OVER (ORDER BY id), false, registered_ns "
        "FROM holders WHERE depth >= 2"
    )
    _move_foreign_keys("holders", "agents")
    op.drop_table("holders")
