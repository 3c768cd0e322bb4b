"""The control plane of a running node: a change counter and one-shot commands.

``store_state.control_version`` is bumped in the same transaction as every change a running
node (``toaster serve``) must apply: areas, monitored agents and joints, streams, held objects
and new commands. The node compares it once per tick (PostgreSQL also sends
``NOTIFY toaster_control``). ``control_commands`` keeps one-shot requests (set an entity's
pose, pointing, relative positions) and the node's answers.

PostgreSQL only: a statement trigger on ``events`` sends ``NOTIFY toaster_events`` so that
subscribers (:func:`toaster.queries.watch`) wake when any writer commits events (one
notification per transaction: PostgreSQL folds identical ones).

Revision ID: 0005
Revises: 0004
Create Date: 2026-11-23
"""

from __future__ import annotations

import sqlalchemy as sa
from alembic import op

revision = "0005"
down_revision = "0004"
branch_labels = None
depends_on = None


def upgrade() -> None:
    with op.batch_alter_table("store_state") as batch:
        batch.add_column(
            sa.Column(
                "control_version", sa.BigInteger(), server_default=sa.text("0"), nullable=False
            )
        )
    row_id = sa.BigInteger().with_variant(sa.Integer(), "sqlite")
    op.create_table(
        "control_commands",
        sa.Column("id", row_id, autoincrement=True, nullable=False),
        sa.Column("kind", sa.Text(), nullable=False),
        sa.Column("args_json", sa.Text(), nullable=False),
        sa.Column("created_ns", sa.BigInteger(), nullable=False),
        sa.Column("state", sa.Text(), server_default=sa.text("'pending'"), nullable=False),
        sa.Column("answer_json", sa.Text(), nullable=True),
        sa.Column("done_ns", sa.BigInteger(), nullable=True),
        sa.CheckConstraint(
            "state IN ('pending', 'done', 'failed')", name=op.f("ck_control_commands_state_known")
        ),
        sa.PrimaryKeyConstraint("id", name=op.f("pk_control_commands")),
    )
    op.create_index("ix_control_commands_pending", "control_commands", ["state", "id"])
    if op.get_bind().dialect.name == "postgresql":
        op.execute(
            "CREATE FUNCTION toaster_notify_events() RETURNS trigger LANGUAGE plpgsql "
            "AS $$ BEGIN PERFORM pg_notify('toaster_events', ''); RETURN NULL; END $$"
        )
        op.execute(
            "CREATE TRIGGER events_notify AFTER INSERT ON events FOR EACH STATEMENT "
            "EXECUTE FUNCTION toaster_notify_events()"
        )


def downgrade() -> None:
    if op.get_bind().dialect.name == "postgresql":
        op.execute("DROP TRIGGER events_notify ON events")
        op.execute("DROP FUNCTION toaster_notify_events()")
    op.drop_index("ix_control_commands_pending", table_name="control_commands")
    op.drop_table("control_commands")
    with op.batch_alter_table("store_state") as batch:
        batch.drop_column("control_version")
