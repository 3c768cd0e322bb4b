"""Older samples in blocks on PostgreSQL: ``fact_sample_blocks`` (issue 28).

A row of ``fact_samples`` costs PostgreSQL 100 bytes for 40 of numbers (a 24-byte tuple
header and a 4-byte line pointer in the heap and in the key index; SQLite's is one 34-byte
entry of a ``WITHOUT ROWID`` b-tree). Maintenance (``Database.maintain``, every minute of a
run) moves an open interval's older samples into rows of ``BLOCK`` samples, one array per
column, ~35 bytes a sample (docs/store.md "What an hour costs"). The table is created on both
backends (one declared schema) and guarded like ``fact_samples``; SQLite never fills it.

Upgrade keeps every row (the next maintenance packs them); downgrade moves the blocks' samples
back into rows.

Revision ID: 0025
Revises: 0023
Create Date: 2026-11-28
"""

from __future__ import annotations

import importlib
from typing import Any

import sqlalchemy as sa
from alembic import op

revision = "0025"
down_revision = "0023"
branch_labels = None
depends_on = None

_guard = importlib.import_module("toaster.migrations.versions.0006_belief_settings_guard")
_TABLE = ("fact_sample_blocks",)


def _array(of: sa.types.TypeEngine[Any]) -> sa.types.TypeEngine[Any]:
    return sa.ARRAY(of).with_variant(sa.Text(), "sqlite")


def upgrade() -> None:
    op.create_table(
        "fact_sample_blocks",
        sa.Column("fact_id", sa.BigInteger(), nullable=False),
        sa.Column("until_ns", sa.BigInteger(), nullable=False),
        sa.Column("untils_ns", _array(sa.BigInteger()), nullable=False),
        sa.Column("value_nums", _array(sa.Float()), nullable=False),
        sa.Column("confidences", _array(sa.Float()), nullable=False),
        sa.Column("observabilities", _array(sa.Float()), nullable=False),
        sa.PrimaryKeyConstraint("fact_id", "until_ns", name=op.f("pk_fact_sample_blocks")),
    )
    _guard.guard_tables(op.get_bind().dialect.name, _TABLE)


def downgrade() -> None:
    backend = op.get_bind().dialect.name
    _guard.unguard_tables(backend, _TABLE)
    if backend == "postgresql":  # SQLite's is empty
        op.execute("SELECT set_config('toaster.writer', 'rules', true)")  # fact_samples' guard
        op.execute(
            "INSERT INTO fact_samples (fact_id, until_ns, value_num, confidence, observability) "
            "SELECT b.fact_id, u.* FROM fact_sample_blocks b CROSS JOIN LATERAL unnest("
            "b.untils_ns, b.value_nums, b.confidences, b.observabilities) AS u "
            "ON CONFLICT DO NOTHING"
        )
    op.drop_table("fact_sample_blocks")
