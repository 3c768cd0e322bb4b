"""One robot's writes at one time share an instant; two robots' runs still never do (issue
25, correcting 0014).

- ``store_state.beliefs_self``: the self agent whose run set the rules' clock
  (``store_state.beliefs_ns``).
- Triggers (frozen in ``0015_triggers.json``): a run at the clock's time whose robot set it
  shares that instant; any other run at or before the clock comes 1 ns after it (another
  robot's, or a late robot's run of another time). 0014 moved every such run 1 ns on: N
  writes of one robot at one time reached the holders at t, t + 1 ns, ..., t + N - 1 ns, and
  a later direct write to a holder at t was refused as out of time order. ``13_late`` also
  freezes the followers of a fact ended at the run's time (one robot's writes asserting and
  retracting it at one time).

Revision ID: 0015
Revises: 0014
Create Date: 2026-11-28
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from toaster.migrations.frozen_triggers import run_frozen

revision = "0015"
down_revision = "0014"
branch_labels = None
depends_on = None


def upgrade() -> None:
    run_frozen(op.get_bind(), "0014_triggers", "drop")
    with op.batch_alter_table("store_state") as batch:
        batch.add_column(sa.Column("beliefs_self", sa.Text(), nullable=True))
    run_frozen(op.get_bind(), "0015_triggers", "create")


def downgrade() -> None:
    run_frozen(op.get_bind(), "0015_triggers", "drop")
    with op.batch_alter_table("store_state") as batch:
        batch.drop_column("beliefs_self")
    run_frozen(op.get_bind(), "0014_triggers", "create")
