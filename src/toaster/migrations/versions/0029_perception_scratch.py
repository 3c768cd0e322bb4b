"""SQLite compiles the perception in two statements (issue 28).

A new scratch table ``belief_percepts(subject_id, property, target_id, confidence)``, empty
between runs: SQLite's steps 20_perceive and 96_regroup first keep the self agent's perception
facts there, then run their query over it (``frozen/0029``), instead of the common table
expression ``sf`` that SQLite resolved again at each of its references (with the settings each
reads): that made the two statements most of the compilation of a connection's first run (a
fresh database's story, docs/beliefs.md). The rows the rule writes are the same.
PostgreSQL's step functions are unchanged (its planner computes a CTE once); it gets the table
too (one schema for both), unused.

Revision ID: 0029
Revises: 0028
Create Date: 2026-11-28
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

from toaster.migrations.frozen_triggers import swap_units

revision = "0029"
down_revision = "0028"
branch_labels = None
depends_on = None


def upgrade() -> None:
    op.create_table(
        "belief_percepts",
        sa.Column("subject_id", sa.Text(), nullable=True),
        sa.Column("property", sa.Text(), nullable=True),
        sa.Column("target_id", sa.Text(), nullable=True),
        sa.Column("confidence", sa.Float(), nullable=True),
    )
    swap_units(op.get_bind(), "0028", "0029")


def downgrade() -> None:
    swap_units(op.get_bind(), "0029", "0028")
    op.drop_table("belief_percepts")
