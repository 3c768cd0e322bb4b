"""An index of each agent's fact keys in the as-of query's order (issue 28).

``ix_fact_keys_agent_order (agent_id, subject_id, property, target_id, id)``: ``beliefs_at``
reads an agent's keys in its result's order, so SQLite merges the query's two halves (own
intervals, followed periods) instead of sorting them (docs/store.md "Benchmarks"). One entry
per key, not per interval: a recording's growth does not change.

Revision ID: 0022
Revises: 0019
Create Date: 2026-11-28
"""

from __future__ import annotations

from alembic import op

revision = "0022"
down_revision = "0019"
branch_labels = None
depends_on = None

_COLUMNS = ["agent_id", "subject_id", "property", "target_id", "id"]


def upgrade() -> None:
    op.create_index("ix_fact_keys_agent_order", "fact_keys", _COLUMNS)


def downgrade() -> None:
    op.drop_index("ix_fact_keys_agent_order", table_name="fact_keys")
