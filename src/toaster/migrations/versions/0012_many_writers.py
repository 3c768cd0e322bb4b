"""Several robots and producers write one database (issue 14).

- ``store_state.beliefs_ns``: the rules' clock. A belief run first moves it to its time unless
  it is behind, then runs at the clock's time: producers with their own clocks never write a
  holder's row before one already written; on PostgreSQL the update's row lock serializes
  the runs of concurrent writers.
- ``store_state.agents_version``, bumped by a trigger on any write to ``agents``: every store
  re-reads its agents when another client registered or changed one.
- ``fact_inbox`` refuses an assert older than the key's last interval (a write inside a
  closed interval would overlap it).

Revision ID: 0012
Revises: 0011
Create Date: 2026-11-24
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from toaster.migrations.frozen_triggers import run_frozen

revision = "0012"
down_revision = "0011"
branch_labels = None
depends_on = None


def upgrade() -> None:
    run_frozen(op.get_bind(), "0011_triggers", "drop")
    with op.batch_alter_table("store_state") as batch:
        batch.add_column(sa.Column("beliefs_ns", sa.BigInteger(), nullable=True))
        batch.add_column(
            sa.Column(
                "agents_version", sa.BigInteger(), nullable=False, server_default=sa.text("0")
            )
        )
    run_frozen(op.get_bind(), "0012_triggers", "create")


def downgrade() -> None:
    run_frozen(op.get_bind(), "0012_triggers", "drop")
    with op.batch_alter_table("store_state") as batch:
        batch.drop_column("agents_version")
        batch.drop_column("beliefs_ns")
    run_frozen(op.get_bind(), "0011_triggers", "create")
