"""A robot's runs take turns on its own clock (issue 28).

Triggers only: the pipeline (``frozen/0031``) also locks and moves the self agent's own
``holders`` row (``pipeline.MINE``). Since 0028 a run took the clocks of the holders its
robot's facts name only: a producer's first tick naming nobody (things in containers) moved
no clock, and another producer of the same robot whose run was at an earlier time then read,
at that time, a self fact that began later: a holder took it with an event no interval began
at (tests/db/test_many_writers.py, two producers per robot on PostgreSQL). The store reads the
self's clock as well when it stamps a snapshot a little behind it. On PostgreSQL a run locks its
robot's row alone first, then reads which holders are its own in the next statement: read in
the snapshot of a statement that then waited for the robot's previous run, they missed the
people that run's facts had just named, and their rows were written without their clocks.

Revision ID: 0031
Revises: 0030
Create Date: 2026-11-28
"""

from __future__ import annotations

from alembic import op

from toaster.migrations.frozen_triggers import swap_units

revision = "0031"
down_revision = "0030"
branch_labels = None
depends_on = None


def upgrade() -> None:
    swap_units(op.get_bind(), "0030", "0031")


def downgrade() -> None:
    swap_units(op.get_bind(), "0031", "0030")
