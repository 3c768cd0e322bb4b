"""The inbox checks the ids an SQL client writes as the library checks them.

Triggers only: the unit ``inbox`` (``frozen/0030``) refuses, for an assert or an event, a
subject, property, target, sub-property or owner id made only of spaces (``str.isspace``'s),
holding NUL or over ``MAX_ID_BYTES`` bytes of UTF-8 (``model.check_id``), naming the field;
it checked only that subject and property were not empty.

Revision ID: 0030
Revises: 0029
Create Date: 2026-11-28
"""

from __future__ import annotations

from alembic import op

from toaster.migrations.frozen_triggers import swap_units

revision = "0030"
down_revision = "0029"
branch_labels = None
depends_on = None


def upgrade() -> None:
    swap_units(op.get_bind(), "0029", "0030")


def downgrade() -> None:
    swap_units(op.get_bind(), "0030", "0029")
