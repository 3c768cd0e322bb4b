"""A refresh (numbers moved beyond their tolerance, the same value) rewrites the open interval
in place and keeps the numbers it held as one ``fact_samples`` row. On PostgreSQL that update
must be HOT (heap-only: no new index entry, the old version pruned on its page without VACUUM):
no index of ``facts`` may cover a column a refresh writes (docs/store.md, "Continuous values")."""

from __future__ import annotations

import time

import pytest
import sqlalchemy as sa

import toaster
from tests.conftest import count
from toaster import Fact
from toaster.db.engine import make_engine

S = 1_000_000_000
REFRESHES = 20  # one row's versions fit its page: no pruning needed, whatever other sessions do


def _facts_counters(url: str, updates: int) -> tuple[int, int]:
    """(updates, HOT updates) of this schema's ``facts`` once the writer's statistics arrived
    (a backend sends them when it ends; wait for ``updates`` of them, at most 30 s)."""
    engine = make_engine(url)
    deadline = time.monotonic() + 30
    try:
        while True:
            with engine.connect() as conn:
                row = conn.execute(
                    sa.text(
                        "SELECT n_tup_upd, n_tup_hot_upd FROM pg_stat_user_tables "
                        "WHERE schemaname = current_schema() AND relname = 'facts'"
                    )
                ).one()
            if row[0] >= updates or time.monotonic() > deadline:
                return int(row[0]), int(row[1])
            time.sleep(0.1)
    finally:
        engine.dispose()


@pytest.mark.backend("postgresql")
def test_a_refresh_is_a_hot_update(db_url: str) -> None:
    db = toaster.connect(db_url)
    try:
        store = db.store()
        store.add_entity("R", "robot", is_self=True, t_ns=0)
        mug = Fact("BOB", "Distance", "MUG", "near", 1.0, 0.9)
        store.sync_snapshot("am", "R", 0, [mug])
        for i in range(1, REFRESHES + 1):  # 1.0, 2.0, 1.0...: beyond Distance's 0.05 each time
            result = store.sync_snapshot("am", "R", i * S, [mug._replace(value_num=1.0 + i % 2)])
            assert result.refreshed == 1
        assert count(db, "SELECT COUNT(*) FROM facts") == 1  # refreshed in place
        assert count(db, "SELECT COUNT(*) FROM fact_samples") == REFRESHES
    finally:
        db.close()  # its backend ends and sends its statistics
    assert _facts_counters(db_url, REFRESHES) == (REFRESHES, REFRESHES)
