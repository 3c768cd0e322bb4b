"""Belief runs that stay cheap and exact when several robots share the holders (issue 14).

Triggers only (frozen in ``0013_triggers.json``): the holders' keys of a run are resolved in
a fixed join order on PostgreSQL (step 45_resolve); a holder that began following a fact after
a late robot's end of it gets its own row (step 13_late); a switch to another robot's key
reads the followed fact as it is at the run's time (step 55_switch).

Revision ID: 0013
Revises: 0012
Create Date: 2026-11-24
"""

from __future__ import annotations

from alembic import op

from toaster.migrations.frozen_triggers import swap_frozen

revision = "0013"
down_revision = "0012"
branch_labels = None
depends_on = None


def upgrade() -> None:
    swap_frozen(op.get_bind(), "0012_triggers", "0013_triggers")


def downgrade() -> None:
    swap_frozen(op.get_bind(), "0013_triggers", "0012_triggers")
