"""The belief rule's triggers installed per unit, so that a rule change replaces one step
(issue 26).

Triggers only: 0015's set (``0015_triggers.json``: one PostgreSQL function with every step,
one SQLite trigger per block) is dropped, and every unit of the manifest ``0016_units.json``
(``frozen/0016/<unit>.json``) is created: on PostgreSQL a plpgsql function
``toaster_step_<unit>`` per step, called by the run function in the same order under the same
conditions; on SQLite the same triggers as 0015's (three blocks renamed), each step's
statements inlined from its unit (see :mod:`toaster.migrations.frozen_triggers`). A later revision
swaps the units whose file changed (``swap_units``).

Revision ID: 0016
Revises: 0015
Create Date: 2026-11-28
"""

from __future__ import annotations

from alembic import op

from toaster.migrations.frozen_triggers import run_frozen, run_units

revision = "0016"
down_revision = "0015"
branch_labels = None
depends_on = None


def upgrade() -> None:
    run_frozen(op.get_bind(), "0015_triggers", "drop")
    run_units(op.get_bind(), "0016", "create")


def downgrade() -> None:
    run_units(op.get_bind(), "0016", "drop")
    run_frozen(op.get_bind(), "0015_triggers", "create")
