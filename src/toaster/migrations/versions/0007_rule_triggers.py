"""The belief rule in the database's own triggers; ``fact_inbox``, the write surface of plain SQL.

``belief_runs``: inserting ``(self_id, t_ns, recorded_ns)`` runs the belief rule over the self
keys in ``belief_changed`` (the store does this after each write). ``fact_inbox``: one inserted
row is one write (assert, retract or event), applied as the store applies it, then the rule:
a ``psql`` / ``sqlite3`` script gets the same intervals, events and beliefs as the library, in
its own transaction. ``belief_steps`` and the ``belief_*`` scratch tables serve the triggers;
``store_state.holders_basis`` remembers which agents the nested holders were registered for;
nested holders keep no per-agent views (those are for real agents).
The triggers are those :mod:`toaster.rules.triggers` rendered when this revision was written,
frozen in ``migrations/frozen/0007_triggers.json``; a revision that changes them drops these and
installs its own frozen copy.

Revision ID: 0007
Revises: 0006
Create Date: 2026-11-23
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from toaster.db.views import drop_agent_views
from toaster.migrations.frozen_triggers import run_frozen

revision = "0007"
down_revision = "0006"
branch_labels = None
depends_on = None

_ROW_ID = sa.BigInteger().with_variant(sa.Integer(), "sqlite")
_SCRATCH = (
    "belief_new_chain",
    "belief_mat",
    "belief_freeze",
    "belief_todo",
    "belief_in",
    "belief_seen",
    "belief_focus",
    "belief_changed",
)


def _scratch_tables() -> None:
    op.create_table(
        "belief_changed",
        sa.Column("key_id", sa.BigInteger(), autoincrement=False, nullable=False),
        sa.Column("refreshed", sa.Boolean(), nullable=False),
        sa.Column("prev_num", sa.Float(), nullable=True),
        sa.Column("prev_conf", sa.Float(), nullable=True),
        sa.Column("prev_obs", sa.Float(), nullable=True),
        sa.PrimaryKeyConstraint("key_id", name=op.f("pk_belief_changed")),
    )
    op.create_table(
        "belief_focus",
        sa.Column("entity_id", sa.Text(), nullable=False),
        sa.PrimaryKeyConstraint("entity_id", name=op.f("pk_belief_focus")),
    )
    op.create_table(
        "belief_seen",
        sa.Column("holder_id", sa.Text(), nullable=True),
        sa.Column("entity_id", sa.Text(), nullable=True),
        sa.Column("phase", sa.Text(), nullable=True),
        sa.Column("pconf", sa.Float(), nullable=True),
    )
    op.create_index(
        "ix_belief_seen_entity_holder", "belief_seen", ["entity_id", "phase", "holder_id"]
    )
    op.create_table(
        "belief_in",
        sa.Column("holder_id", sa.Text(), nullable=True),
        sa.Column("self_key", sa.BigInteger(), nullable=True),
        sa.Column("hkey", sa.BigInteger(), nullable=True),
        sa.Column("pconf", sa.Float(), nullable=True),
        sa.Column("seen_again", sa.Integer(), server_default=sa.text("0"), nullable=False),
    )
    op.create_index("ix_belief_in_key", "belief_in", ["self_key", "holder_id"])
    op.create_table(
        "belief_todo",
        sa.Column("holder_id", sa.Text(), nullable=True),
        sa.Column("hkey", sa.BigInteger(), nullable=True),
        sa.Column("self_key", sa.BigInteger(), nullable=True),
        sa.Column("follow_id", sa.BigInteger(), nullable=True),
        sa.Column("action", sa.Text(), nullable=True),
        sa.Column("value_text", sa.Text(), nullable=True),
        sa.Column("value_num", sa.Float(), nullable=True),
        sa.Column("confidence", sa.Float(), nullable=True),
        sa.Column("observability", sa.Float(), nullable=True),
        sa.Column("previous_text", sa.Text(), nullable=True),
        sa.Column("pconf", sa.Float(), nullable=True),
        sa.Column("split_ns", sa.BigInteger(), nullable=True),
    )
    op.create_table(
        "belief_freeze",
        sa.Column("follow_id", sa.BigInteger(), autoincrement=False, nullable=False),
        sa.Column("hkey", sa.BigInteger(), nullable=True),
        sa.Column("from_ns", sa.BigInteger(), nullable=True),
        sa.Column("cut_ns", sa.BigInteger(), nullable=True),
        sa.Column("value_text", sa.Text(), nullable=True),
        sa.Column("value_num", sa.Float(), nullable=True),
        sa.Column("confidence", sa.Float(), nullable=True),
        sa.Column("observability", sa.Float(), nullable=True),
        sa.PrimaryKeyConstraint("follow_id", name=op.f("pk_belief_freeze")),
    )
    op.create_table(
        "belief_mat",
        sa.Column("follow_id", sa.BigInteger(), autoincrement=False, nullable=False),
        sa.PrimaryKeyConstraint("follow_id", name=op.f("pk_belief_mat")),
    )
    op.create_table(
        "belief_new_chain",
        sa.Column("holder_id", sa.Text(), nullable=True),
        sa.Column("position", sa.Integer(), nullable=True),
        sa.Column("member_id", sa.Text(), nullable=True),
    )


def upgrade() -> None:
    with op.batch_alter_table("store_state") as batch:
        batch.add_column(
            sa.Column("holders_basis", sa.Text(), server_default=sa.text("''"), nullable=False)
        )
    op.create_table(
        "fact_inbox",
        sa.Column("id", _ROW_ID, autoincrement=True, nullable=False),
        sa.Column("action", sa.Text(), server_default=sa.text("'assert'"), nullable=False),
        sa.Column("agent_id", sa.Text(), nullable=False),
        sa.Column("subject_id", sa.Text(), nullable=True),
        sa.Column("subject_owner_id", sa.Text(), nullable=True),
        sa.Column("property", sa.Text(), nullable=False),
        sa.Column("property_type", sa.Text(), nullable=True),
        sa.Column("sub_property", sa.Text(), nullable=True),
        sa.Column("target_id", sa.Text(), nullable=True),
        sa.Column("target_owner_id", sa.Text(), nullable=True),
        sa.Column("value_text", sa.Text(), server_default=sa.text("'true'"), nullable=False),
        sa.Column("value_num", sa.Float(), nullable=True),
        sa.Column("confidence", sa.Float(), server_default=sa.text("1.0"), nullable=False),
        sa.Column("observability", sa.Float(), server_default=sa.text("1.0"), nullable=False),
        sa.Column("t_ns", sa.BigInteger(), nullable=False),
        sa.Column("source", sa.Text(), server_default=sa.text("'sql'"), nullable=False),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_fact_inbox")),
    )
    for name in ("belief_runs", "belief_steps"):
        columns = [sa.Column("block", sa.Text(), nullable=False)] if name == "belief_steps" else []
        op.create_table(
            name,
            sa.Column("id", _ROW_ID, autoincrement=True, nullable=False),
            *columns,
            sa.Column("self_id", sa.Text(), nullable=False),
            sa.Column("t_ns", sa.BigInteger(), nullable=False),
            sa.Column("recorded_ns", sa.BigInteger(), nullable=False),
            sa.PrimaryKeyConstraint("id", name=op.f(f"pk_{name}")),
        )
    _scratch_tables()
    bind = op.get_bind()
    # Per-agent views are for real agents: the nested holders' go (the triggers, which register
    # holders from now on, cannot create views).
    for (holder,) in bind.execute(sa.text("SELECT DISTINCT holder_id FROM belief_chain")).all():
        drop_agent_views(bind, holder)
    run_frozen(bind, "0007_triggers", "create")


def downgrade() -> None:
    run_frozen(op.get_bind(), "0007_triggers", "drop")
    for name in (*_SCRATCH, "belief_steps", "belief_runs", "fact_inbox"):
        op.drop_table(name)
    with op.batch_alter_table("store_state") as batch:
        batch.drop_column("holders_basis")
