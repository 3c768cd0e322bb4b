"""Holders that perceive alike share the rule's work (issue 13, many holders).

- ``belief_groups(holder_id, rep_id)``: holders that perceive exactly as their group's
  representative does and follow the same self keys (guarded like the other rule tables);
  ``store_state.groups_for``: the self agent they were formed for (NULL: none hold).
- Setting ``group_holders`` (default true; the view ``belief_settings`` is replaced).
- The rule's triggers (frozen copy of this revision): while no perception fact changes, a
  run computes perception and decisions once per group (steps 15_ungroup, 32_expand,
  94_keep_groups, 96_regroup); writes to ``settings`` or ``agents`` end the groups.

Revision ID: 0011
Revises: 0010
Create Date: 2026-11-24
"""

from __future__ import annotations

import importlib

import sqlalchemy as sa
from alembic import op

from toaster.migrations.frozen_triggers import run_frozen

revision = "0011"
down_revision = "0010"
branch_labels = None
depends_on = None

_guards = importlib.import_module("toaster.migrations.versions.0006_belief_settings_guard")
_previous = importlib.import_module("toaster.migrations.versions.0009_moves_actor_tell")
#: The defaults from this revision on (frozen: a change of default is a new revision).
DEFAULTS = {**_previous.DEFAULTS, "group_holders": True}
_TABLES = ("belief_groups",)


def upgrade() -> None:
    backend = op.get_bind().dialect.name
    run_frozen(op.get_bind(), "0010_triggers", "drop")
    op.create_table(
        "belief_groups",
        sa.Column("holder_id", sa.Text(), nullable=False),
        sa.Column("rep_id", sa.Text(), nullable=False),
        sa.ForeignKeyConstraint(
            ["holder_id"],
            ["holders.id"],
            ondelete="CASCADE",
            name=op.f("fk_belief_groups_holder_id_holders"),
        ),
        sa.ForeignKeyConstraint(
            ["rep_id"],
            ["holders.id"],
            ondelete="CASCADE",
            name=op.f("fk_belief_groups_rep_id_holders"),
        ),
        sa.PrimaryKeyConstraint("holder_id", name=op.f("pk_belief_groups")),
    )
    op.create_index("ix_belief_groups_rep_id", "belief_groups", ["rep_id"])
    with op.batch_alter_table("store_state") as batch:
        batch.add_column(sa.Column("groups_for", sa.Text(), nullable=True))
    _guards.guard_tables(backend, _TABLES)
    op.execute("DROP VIEW belief_settings")
    op.execute(_guards.settings_view(DEFAULTS))
    run_frozen(op.get_bind(), "0011_triggers", "create")


def downgrade() -> None:
    backend = op.get_bind().dialect.name
    run_frozen(op.get_bind(), "0011_triggers", "drop")
    op.execute("DROP VIEW belief_settings")
    op.execute(_guards.settings_view(_previous.DEFAULTS))
    _guards.unguard_tables(backend, _TABLES)
    with op.batch_alter_table("store_state") as batch:
        batch.drop_column("groups_for")
    op.drop_index("ix_belief_groups_rep_id", table_name="belief_groups")
    op.drop_table("belief_groups")
    run_frozen(op.get_bind(), "0010_triggers", "create")
