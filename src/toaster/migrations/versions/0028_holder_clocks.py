"""A rules' clock per holder: runs of robots whose people never meet do not wait for each other
(issue 28).

- ``holders.clock_ns``, ``holders.clock_self``: each holder's clock (the time of its last
  belief run, and the self agent whose run set it), taken over from ``store_state.beliefs_ns``
  and ``beliefs_self`` (every holder starts at the one clock's value; the columns go).
- Triggers (``frozen/0028``: the driver and the unit ``holders``): a run takes the clocks of
  the holders it may change (those its robot's facts name, the actors of its changes, the
  followers of its changed keys; PostgreSQL locks their rows, in the order of their ids,
  instead of the one clock row) and runs at the latest of them, as 0015 did with the one
  clock; a new nested holder starts at its run's time.
- With several self agents, runs keep no groups of holders and no perception (0011, 0023:
  both are one robot's, in ``store_state``, and each robot's run ended another's and wrote
  that row, which every run then waited for); registering a robot ends them already.

Revision ID: 0028
Revises: 0027
Create Date: 2026-11-28
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from toaster.migrations.frozen_triggers import swap_units

revision = "0028"
down_revision = "0027"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.add_column("holders", sa.Column("clock_ns", sa.BigInteger(), nullable=True))
    op.add_column("holders", sa.Column("clock_self", sa.Text(), nullable=True))
    op.execute(
        "UPDATE holders SET clock_ns = (SELECT beliefs_ns FROM store_state WHERE id = 1), "
        "clock_self = (SELECT beliefs_self FROM store_state WHERE id = 1)"
    )
    swap_units(op.get_bind(), "0027", "0028")
    # ALTER TABLE DROP COLUMN (SQLite 3.35+; a copy of store_state would fail on the
    # triggers that name it, a copy of holders delete its keys through the foreign keys)
    op.drop_column("store_state", "beliefs_self")
    op.drop_column("store_state", "beliefs_ns")


def downgrade() -> None:
    op.add_column("store_state", sa.Column("beliefs_ns", sa.BigInteger(), nullable=True))
    op.add_column("store_state", sa.Column("beliefs_self", sa.Text(), nullable=True))
    op.execute(  # the one clock: the latest holder's
        "UPDATE store_state SET beliefs_ns = (SELECT clock_ns FROM holders "
        "WHERE clock_ns IS NOT NULL ORDER BY clock_ns DESC LIMIT 1), beliefs_self = "
        "(SELECT clock_self FROM holders WHERE clock_ns IS NOT NULL ORDER BY clock_ns DESC "
        "LIMIT 1) WHERE id = 1"
    )
    swap_units(op.get_bind(), "0028", "0027")
    op.drop_column("holders", "clock_self")
    op.drop_column("holders", "clock_ns")
