"""Numeric samples inside intervals, and a leaner ``facts`` table on PostgreSQL.

``fact_samples`` keeps, per interval, the numbers (value, confidence, observability) it held
*until* each in-place refresh beyond the property's tolerance, so that as-of queries return a
past number within its tolerance (see docs/store.md, "Continuous values").

PostgreSQL only (the one backend with these knobs): autovacuum visits ``facts`` after 2 % of
its rows changed instead of 20 %: a robot closes and opens thousands of intervals an hour and
the dead versions of closed ones would otherwise pile up. (A fill factor of 85 was measured and
left out: it made the table larger without more HOT updates; docs/store.md.)

Revision ID: 0004
Revises: 0003
Create Date: 2026-11-23
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0004"
down_revision = "0003"
branch_labels = None
depends_on = None

_PG_FACTS_OPTIONS = "autovacuum_vacuum_scale_factor = 0.02, autovacuum_analyze_scale_factor = 0.02"
_PG_FACTS_RESET = "autovacuum_vacuum_scale_factor, autovacuum_analyze_scale_factor"


def upgrade() -> None:
    op.create_table(
        "fact_samples",
        sa.Column("fact_id", sa.BigInteger(), nullable=False),
        sa.Column("until_ns", sa.BigInteger(), nullable=False),
        sa.Column("value_num", sa.Float(), nullable=True),
        sa.Column("confidence", sa.Float(), nullable=False),
        sa.Column("observability", sa.Float(), nullable=False),
        sa.PrimaryKeyConstraint("fact_id", "until_ns", name=op.f("pk_fact_samples")),
        sqlite_with_rowid=False,
    )
    if op.get_bind().dialect.name == "postgresql":
        op.execute(f"ALTER TABLE facts SET ({_PG_FACTS_OPTIONS})")


def downgrade() -> None:
    if op.get_bind().dialect.name == "postgresql":
        op.execute(f"ALTER TABLE facts RESET ({_PG_FACTS_RESET})")
    op.drop_table("fact_samples")
