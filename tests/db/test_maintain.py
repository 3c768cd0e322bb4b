"""Maintenance between ticks: PostgreSQL vacuums the hot tables, SQLite folds its WAL."""

from __future__ import annotations

from pathlib import Path

import pytest
import sqlalchemy as sa

import toaster
from toaster import Fact
from toaster.producers import Runner

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

S = 1_000_000_000


def _churn(store: toaster.Store) -> None:
    for i in range(30):
        store.sync_snapshot(
            "am",
            "R",
            i * S,
            [Fact("BOB", "Distance", f"O{j}", "far", 1.0 + i % 2, 0.9) for j in range(i % 7)],
        )


def test_maintain_reclaims_what_a_run_leaves(db: toaster.Database) -> None:
    store = db.store()
    store.add_entity("R", "robot", is_self=True, t_ns=0)
    _churn(store)
    with pytest.raises(RuntimeError, match="outside a transaction"), db.transaction():
        db.maintain()
    db.maintain()
    if db.dialect_name == "postgresql":
        with db.transaction() as conn:
            vacuumed = conn.execute(
                sa.text(
                    "SELECT last_vacuum IS NOT NULL FROM pg_stat_user_tables "
                    "WHERE relname = 'facts' AND schemaname = current_schema()"
                )
            ).scalar_one()
        assert vacuumed
    else:
        wal = Path(db.url.removeprefix("sqlite:///") + "-wal")
        assert not wal.exists() or wal.stat().st_size == 0
    assert len(toaster.queries.history(db, "R")) > 0  # nothing lost


def test_runner_maintains_on_its_own(db: toaster.Database) -> None:
    """`toaster run`'s loop maintains the database between ticks when its interval is due."""
    from toaster.world import World

    class Still:
        name = "still"

        def setup(self, world: World) -> None:
            world.add_entity("BOB", "human")

        def advance(self, world: World, t_ns: int) -> None:
            world.set_pose("BOB", (0.0, 0.0, 0.0), t_ns)

    store = db.store()
    store.add_entity("toaster", "robot", is_self=True, t_ns=0)
    runner = Runner(World(), [Still()], [], store=store)
    stats = runner.run(0, 3 * S, 1.0, maintain_every_s=0.0)
    assert stats.ticks == 4 and stats.seconds.get("maintain", 0) > 0
