"""SQLite runs the perception step's places as one trigger (issue 28).

Triggers only: the SQLite units ``20_perceive_*`` (``frozen/0027``) now enter the new unit
``20_perceive``, a trigger ``belief_step_20_perceive`` on ``belief_steps`` whose ``phase`` and
``everything`` are read from the entering row's name, instead of holding its statements.
SQLite compiles a trigger's program once per outer statement but inlined statements once per
place, and a connection's first rule run compiles the whole pipeline: 20_perceive's inlined
copies (five places since 0023) were most of a fresh database's first story (docs/beliefs.md).
The rows the rule writes are the same. PostgreSQL's step functions are unchanged (created again
as frozen).

Revision ID: 0027
Revises: 0025
Create Date: 2026-11-28
"""

from __future__ import annotations

from alembic import op

from toaster.migrations.frozen_triggers import swap_units

revision = "0027"
down_revision = "0025"
branch_labels = None
depends_on = None


def upgrade() -> None:
    swap_units(op.get_bind(), "0023", "0027")


def downgrade() -> None:
    swap_units(op.get_bind(), "0027", "0023")
