"""The rule's triggers with plans that do not grow with the database.

- ``40_refresh`` (seeing again) found a holder's beliefs about a target by scanning all the
  holder's keys per entity seen again (the keys' identity index matched the agent only), where
  a churn of agents over many objects spent much of its time (docs/beliefs.md); it now reads
  the target index, and the subject and target matches are separate branches (one OR condition before).
- ``10_focus`` read every key of the database per run (SQLite joined the scratch table to
  ``fact_keys`` the wrong way round) and ``58_frozen`` every followed period: both now start
  from the run's own rows.
- No schema change: the frozen copy of this revision's triggers replaces 0009's.

Revision ID: 0010
Revises: 0009
Create Date: 2026-11-24
"""

from __future__ import annotations

from alembic import op

from toaster.migrations.frozen_triggers import swap_frozen

revision = "0010"
down_revision = "0009"
branch_labels = None
depends_on = None


def upgrade() -> None:
    swap_frozen(op.get_bind(), "0009_triggers", "0010_triggers")


def downgrade() -> None:
    swap_frozen(op.get_bind(), "0010_triggers", "0009_triggers")
