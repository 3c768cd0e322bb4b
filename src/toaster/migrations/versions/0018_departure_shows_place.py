"""Who sees a thing leave saw where it was: its other believed places end (the second-order
reference model's seed 12561713).

``40_refresh``: a holder that perceived the subject or the target of a departure before the
tick (the move's ``before`` phase) no longer believes the subject is wherever else it believed
it was, as a holder that sees it arrive already did (0009). A nested holder A>B perceives a
departure before the tick through the actor of the move without having perceived the thing at
the previous run (A, acting elsewhere, saw B see the key in the basket as B left): its stale
place (the box) ended only once it saw the thing again. Units swapped: ``40_refresh``.

Revision ID: 0018
Revises: 0017
Create Date: 2026-11-28
"""

from __future__ import annotations

from alembic import op

from toaster.migrations.frozen_triggers import swap_units

revision = "0018"
down_revision = "0017"
branch_labels = None
depends_on = None


def upgrade() -> None:
    swap_units(op.get_bind(), "0016", "0018")


def downgrade() -> None:
    swap_units(op.get_bind(), "0018", "0016")
