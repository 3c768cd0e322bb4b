"""A live node maintains its database beside its ticks, never between them, and keeps SQLite's
page cache small: a long run neither stalls nor grows."""

from __future__ import annotations

import threading
from pathlib import Path

import pytest
import sqlalchemy as sa

import toaster
from toaster.db.database import Database
from toaster.db.maintenance import Maintainer
from toaster.node import LiveNode
from toaster.node.live_node import LIVE_PAGE_CACHE_KIB

WAIT_S = 120.0


def _run_in_thread(node: LiveNode, ticks: int, maintain_every_s: float):
    errors: list[BaseException] = []

    def run() -> None:
        try:
            node.run(200.0, ticks=ticks, maintain_every_s=maintain_every_s)
        except BaseException as exc:  # reported to the test
            errors.append(exc)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread, errors


def _feed(node: LiveNode, stop: threading.Event) -> None:
    k = 0
    while not stop.wait(0.002):
        node.api.push("bob", (k % 50 * 0.1, 0.0, 0.0))
        node.api.push("cup", (2.0, 0.0, 0.8), kind="object")
        k += 1


@pytest.mark.slow
def test_ticks_go_on_while_maintenance_waits(pg_schema_url: str) -> None:
    """A VACUUM held up by another session's lock (a long ALTER, someone's own VACUUM) does not
    hold up the node: ticking between two maintenance runs, the node stopped for as long."""
    db = toaster.connect(pg_schema_url)
    blocker = toaster.connect(pg_schema_url)
    stop = threading.Event()
    try:
        node = LiveNode(db)
        with blocker.engine.connect() as conn:
            conn.exec_driver_sql("LOCK TABLE facts IN SHARE UPDATE EXCLUSIVE MODE")
            feeder = threading.Thread(target=_feed, args=(node, stop), daemon=True)
            feeder.start()
            thread, errors = _run_in_thread(node, 60, maintain_every_s=0.01)
            thread.join(WAIT_S)
            assert not thread.is_alive(), (
                f"the node made {node.stats.ticks} of 60 ticks "
                f"in {WAIT_S:.0f} s while a VACUUM waited for a lock"
            )
            assert not errors, errors
            # every tick stored, or written with the next one (the writer thread's coalescing)
            assert node.stats.ticks + node.stats.coalesced == 60 and node.stats.ticks > 0
            conn.rollback()
    finally:
        stop.set()
        blocker.close()
        db.close()


@pytest.mark.slow
def test_maintainer_runs_and_survives_failures(db_url: str) -> None:
    db = toaster.connect(db_url)
    try:
        store = db.store()
        store.add_entity("R", "robot", is_self=True, t_ns=0)
        for i in range(20):
            store.sync_snapshot(
                "am",
                "R",
                (i + 1) * 10**9,
                [
                    toaster.Fact("BOB", "Distance", f"O{j}", "far", 1.0 + i % 2, 0.9)
                    for j in range(i % 5)
                ],
            )
        maintainer = Maintainer(db, 3600.0)
        assert maintainer.run_once() and maintainer.runs == 1
        if db.dialect_name == "postgresql":
            with db.transaction() as conn:
                vacuumed = conn.execute(
                    sa.text(
                        "SELECT last_vacuum IS NOT NULL FROM pg_stat_user_tables "
                        "WHERE relname = 'facts' AND schemaname = current_schema()"
                    )
                ).scalar_one()
            assert vacuumed
        else:  # every frame of the WAL is in the database file
            raw = db.connection.connection.dbapi_connection
            busy, frames, done = raw.execute("PRAGMA wal_checkpoint(PASSIVE)").fetchone()
            assert busy == 0 and frames == done
        with pytest.raises(ValueError, match="positive"):
            Maintainer(db, 0)
    finally:
        db.close()


def test_a_failed_maintenance_is_reported_once(
    tmp_path: Path, caplog: pytest.LogCaptureFixture
) -> None:
    """Maintenance that cannot run (here: a database that cannot be opened) is logged once per
    kind of error and retried, never raised into the node."""
    gone = Database(sa.create_engine(f"sqlite:///{tmp_path / 'no' / 'such.db'}"), "gone")
    maintainer = Maintainer(gone, 3600.0)
    assert not maintainer.run_once() and not maintainer.run_once()
    assert maintainer.failures == 2 and maintainer.runs == 0
    reports = [r for r in caplog.records if "maintenance failed" in r.getMessage()]
    assert len(reports) == 1 and "\n" not in reports[0].getMessage()
    gone.close()


def test_the_node_bounds_sqlite_page_cache(tmp_path: Path) -> None:
    """SQLite's page cache is memory a node holds for as long as it runs: the node bounds it to
    ``LIVE_PAGE_CACHE_KIB``, on every connection it opens, a reconnection included."""
    db = toaster.connect(f"sqlite:///{tmp_path / 'node.db'}")
    try:
        LiveNode(db)

        def cache_kib() -> int:
            value = db.connection.exec_driver_sql("PRAGMA cache_size").scalar_one()
            db.connection.rollback()
            return -int(value)

        assert cache_kib() == LIVE_PAGE_CACHE_KIB
        db.connection.close()  # a lost connection, reopened on the next use
        assert cache_kib() == LIVE_PAGE_CACHE_KIB
        with db.engine.connect() as other:  # the engine's own default is untouched
            assert -int(other.exec_driver_sql("PRAGMA cache_size").scalar_one()) > 2000
    finally:
        db.close()
