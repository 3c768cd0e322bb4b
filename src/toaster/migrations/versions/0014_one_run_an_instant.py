"""Each belief run is an instant of its own: several robots and SQL writers keep every
invariant (issue 25).

Triggers only (frozen in ``0014_triggers.json``): a run moves the rules' clock
(``store_state.beliefs_ns``) to its time or, when the clock is already there or past it, 1 ns
after it. Two runs at one instant (robots ticking at the same time, a late writer's run at the
clock's time) took the same holder key in and out at that instant: zero-length intervals,
an ``appeared`` and an ``ended`` each, that ``toaster db check`` reported.

Revision ID: 0014
Revises: 0013
Create Date: 2026-11-27
"""

from __future__ import annotations

from alembic import op

from toaster.migrations.frozen_triggers import swap_frozen

revision = "0014"
down_revision = "0013"
branch_labels = None
depends_on = None


def upgrade() -> None:
    swap_frozen(op.get_bind(), "0013_triggers", "0014_triggers")


def downgrade() -> None:
    swap_frozen(op.get_bind(), "0014_triggers", "0013_triggers")
