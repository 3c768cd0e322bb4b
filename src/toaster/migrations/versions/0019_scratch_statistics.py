"""The rule forgets statistics that say its scratch tables are empty (PostgreSQL).

Triggers only: the unit ``10_focus`` (``frozen/0019/10_focus.json``). A store's session
keeps its temporary scratch tables across commits (emptied by ``DELETE``, their pages kept),
so an ``ANALYZE`` of them in that session between two runs recorded 0 rows on N pages, and
the planner took every later run's rows for none (nested loops over thousands of rows;
docs/beliefs.md). A run that finds such statistics truncates the scratch tables that are
empty at its start and analyzes ``belief_changed``. SQLite's unit is unchanged (its driver is
created again, as for any swapped unit inlined into it).

Revision ID: 0019
Revises: 0018
Create Date: 2026-11-28
"""

from __future__ import annotations

from alembic import op

from toaster.migrations.frozen_triggers import swap_units

revision = "0019"
down_revision = "0018"
branch_labels = None
depends_on = None


def upgrade() -> None:
    swap_units(op.get_bind(), "0018", "0019")


def downgrade() -> None:
    swap_units(op.get_bind(), "0019", "0018")
