"""Beliefs computed only when perception changes (issue 28).

- ``belief_perceived(entity_id, holder_id, pconf)``: who perceives what, kept between runs for
  the self agent ``store_state.perceived_for`` from the run time ``store_state.perceived_ns``;
  a run whose changes hold no perception input (``rules.sqltext.PERCEPTION``) reuses it
  instead of computing it (steps 20_reuse, 21_remember).
- ``belief_settled(key_id, since_ns)``: self keys that every holder perceiving them follows,
  and no other: while the kept perception holds, their changes leave the run's change set
  (19_settled, 97_unsettle, 98_settle), refreshed numbers included.
- 85_refresh_rows keeps a holder's numbers as a sample before refreshing its interval in place.

Both tables are guarded like the rule's other tables. Every rule unit is dropped as 0019 froze
it and created as this revision froze it (``frozen/0023_units.json``); the downgrade does the
reverse.

Revision ID: 0023
Revises: 0022
Create Date: 2026-11-28
"""

from __future__ import annotations

import importlib

import sqlalchemy as sa
from alembic import op

from toaster.migrations.frozen_triggers import run_units

revision = "0023"
down_revision = "0022"
branch_labels = None
depends_on = None

_guards = importlib.import_module("toaster.migrations.versions.0006_belief_settings_guard")
_TABLES = ("belief_perceived", "belief_settled")


def upgrade() -> None:
    backend = op.get_bind().dialect.name
    run_units(op.get_bind(), "0019", "drop")
    op.create_table(
        "belief_perceived",
        sa.Column("entity_id", sa.Text(), nullable=False),
        sa.Column("holder_id", sa.Text(), nullable=False),
        sa.Column("pconf", sa.Float(), nullable=False),
        sa.PrimaryKeyConstraint("entity_id", "holder_id", name=op.f("pk_belief_perceived")),
    )
    op.create_table(
        "belief_settled",
        sa.Column("key_id", sa.BigInteger(), autoincrement=False, nullable=False),
        sa.Column("since_ns", sa.BigInteger(), nullable=False),
        sa.PrimaryKeyConstraint("key_id", name=op.f("pk_belief_settled")),
    )
    with op.batch_alter_table("store_state") as batch:
        batch.add_column(sa.Column("perceived_for", sa.Text(), nullable=True))
        batch.add_column(sa.Column("perceived_ns", sa.BigInteger(), nullable=True))
    _guards.guard_tables(backend, _TABLES)
    run_units(op.get_bind(), "0023", "create")


def downgrade() -> None:
    backend = op.get_bind().dialect.name
    run_units(op.get_bind(), "0023", "drop")
    _guards.unguard_tables(backend, _TABLES)
    with op.batch_alter_table("store_state") as batch:
        batch.drop_column("perceived_ns")
        batch.drop_column("perceived_for")
    op.drop_table("belief_settled")
    op.drop_table("belief_perceived")
    run_units(op.get_bind(), "0019", "create")
