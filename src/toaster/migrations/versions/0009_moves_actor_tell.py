"""Beliefs where things happen: moves seen where they happen, the actor of a change, attention,
what is told.

- ``belief_changed.move`` (scratch): a location key that ended (``before``) or started
  (``after``) in the run, set by step 12_moves: a departure is seen by who perceived the
  subject before, an arrival by who perceives it after.
- ``belief_changed.actor_id`` and ``fact_inbox.actor_id``: the agent who made a change; it
  perceives its own change wherever it is.
- New settings with their defaults (the view ``belief_settings`` is replaced): ``attention``
  ``{}``, ``trust`` ``"everyone"``, ``distrust`` ``[]``.
- The rule's triggers: the frozen copy of this revision.

Revision ID: 0009
Revises: 0008
Create Date: 2026-11-24
"""

from __future__ import annotations

import importlib

import sqlalchemy as sa
from alembic import op

from toaster.migrations.frozen_triggers import run_frozen

revision = "0009"
down_revision = "0008"
branch_labels = None
depends_on = None

_settings = importlib.import_module("toaster.migrations.versions.0006_belief_settings_guard")
#: The defaults from this revision on (frozen: a change of default is a new revision).
DEFAULTS = {**_settings.DEFAULTS, "attention": {}, "trust": "everyone", "distrust": []}


def upgrade() -> None:
    with op.batch_alter_table("belief_changed") as batch:
        batch.add_column(sa.Column("move", sa.Text(), nullable=True))
        batch.add_column(sa.Column("actor_id", sa.Text(), nullable=True))
    run_frozen(op.get_bind(), "0008_triggers", "drop")  # they read fact_inbox
    with op.batch_alter_table("fact_inbox") as batch:
        batch.add_column(sa.Column("actor_id", sa.Text(), nullable=True))
    op.execute("DROP VIEW belief_settings")
    op.execute(_settings.settings_view(DEFAULTS))
    run_frozen(op.get_bind(), "0009_triggers", "create")


def downgrade() -> None:
    run_frozen(op.get_bind(), "0009_triggers", "drop")
    op.execute("DROP VIEW belief_settings")
    op.execute(_settings.settings_view(_settings.DEFAULTS))
    with op.batch_alter_table("fact_inbox") as batch:
        batch.drop_column("actor_id")
    with op.batch_alter_table("belief_changed") as batch:
        batch.drop_column("actor_id")
        batch.drop_column("move")
    run_frozen(op.get_bind(), "0008_triggers", "create")
