"""The live node's writer thread (docs/live.md, "Latency"): a tick whose write waits does not
hold up the next ticks' fact lists; the ticks handed over meanwhile are written with the
newest one, in order, the last one too; a reader that flushes sees the ticks before it.

Real databases; the write is held up by a lock another connection holds (a long lock timeout:
the write waits, it does not fail). Counts and order only, never a wall-clock window.
"""

from __future__ import annotations

import contextlib
import itertools
import sqlite3
import threading
import time
from collections.abc import Iterator
from typing import Any

import pytest

import toaster
from tests.node.test_faults import gaps, wait_for
from tests.node.test_node import ROOM, stored
from toaster.db.engine import make_engine
from toaster.node import LiveNode
from toaster.queries import events

IN, OUT = (1.0, 0.0, 0.0), (20.0, 0.0, 0.0)


class Lists:
    """An output that keeps, per fact list sent, its tick and whether bob was in the room."""

    def __init__(self) -> None:
        self.sent: list[tuple[int, bool]] = []

    def publish_facts(self, t_ns: int, facts: Any, world: Any) -> None:
        inside = any(
            f.subject_id == "bob" and f.property == "IsInRoom"
            for f in facts.get("area_manager", [])
        )
        self.sent.append((t_ns, inside))

    def publish(self, t_ns: int, facts: Any, world: Any) -> None:
        """(the rest of a tick: nothing to keep)"""


class Node:
    """A node ticking in a thread at 30 Hz while bob steps in and out of the kitchen."""

    def __init__(self, node: LiveNode) -> None:
        self.node, self.stop, self.errors = node, threading.Event(), []
        self.feeding = True  # bob steps in and out; else he stays at ``at``
        self.at = IN
        self.lock = threading.Lock()
        self.feeder = threading.Thread(target=self._feed, daemon=True)
        self.runner = threading.Thread(target=self._run, daemon=True)

    def _feed(self) -> None:
        k = 0
        while not self.stop.is_set():
            with self.lock:
                if self.feeding:
                    self.at = IN if k % 2 else OUT
                    k += 1
                at = self.at
            self.node.api.push("bob", at, kind="human")
            self.node.api.push("cup", (3.0, 0.0, 0.8), kind="object")
            time.sleep(0.04)

    def _run(self) -> None:
        try:
            self.node.run(30.0, stop=self.stop)
        except BaseException as exc:  # the test reports it
            self.errors.append(exc)

    def __enter__(self) -> Node:
        self.feeder.start()
        self.runner.start()
        return self

    def __exit__(self, *exc: object) -> None:
        self.stop.set()
        self.runner.join(60)
        self.feeder.join(5)
        assert not self.runner.is_alive(), "the node did not stop"


@contextlib.contextmanager
def write_lock(url: str) -> Iterator[None]:
    """Another connection holds the lock a tick's write needs (SQLite: the write lock;
    PostgreSQL: the facts table against writes); reads go on."""
    if url.startswith("sqlite"):
        conn = sqlite3.connect(url.removeprefix("sqlite:///"), timeout=60, isolation_level=None)
        conn.execute("BEGIN IMMEDIATE")
        try:
            yield
        finally:
            conn.execute("ROLLBACK")
            conn.close()
        return
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            conn.exec_driver_sql("LOCK TABLE facts IN EXCLUSIVE MODE")
            try:
                yield
            finally:
                conn.rollback()
    finally:
        engine.dispose()


@pytest.mark.slow
def test_a_write_held_up_does_not_hold_up_the_next_fact_lists_and_every_tick_is_stored(
    db_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    monkeypatch.setenv("TOASTER_LOCK_TIMEOUT", "300")  # the held-up write waits, never fails
    lists = Lists()
    with toaster.connect(db_url) as db:
        db.store().put_area("kitchen", ROOM)
        node = LiveNode(db, outputs=[lists])
        with Node(node) as running:
            wait_for(lambda: node.stats.ticks >= 5 or running.errors, "the first ticks")
            with write_lock(db_url), toaster.connect(db_url) as other:
                changes = len(events(other, "toaster", subject="bob", property="IsInRoom"))
                sent = len(lists.sent)
                # the node goes on computing and sending fact lists while no write gets through
                wait_for(lambda: len(lists.sent) >= sent + 30, "30 fact lists while locked")
                assert len(events(other, "toaster", subject="bob", property="IsInRoom")) == changes
                assert node.stats.coalesced > 0  # ticks handed over meanwhile: the newest kept
                held = node.stats.ticks
            wait_for(lambda: node.stats.ticks >= held + 3, "ticks stored again")
        assert not running.errors, running.errors
        last_t, inside = lists.sent[-1]
        # the last tick computed is stored (the writer drained at the stop)
        assert (("bob", "kitchen") in stored(db, "IsInRoom")) == inside
        # the changes are stored in order, each at a tick the node computed
        ticks = {t for t, _ in lists.sent}
        rows = events(db, "toaster", subject="bob", property="IsInRoom")
        stamps = [r.stamp_ns for r in rows]
        assert len(stamps) >= 2 and stamps == sorted(stamps) and set(stamps) <= ticks
        assert stamps[-1] <= last_t
        kinds = [r.kind for r in rows]  # in, out, in, ...: each appearance ended before the next
        assert all(a != b for a, b in itertools.pairwise(kinds))
        assert gaps(db) == [] and node.faults.counts == {}  # held up is not an outage


def test_a_reader_that_flushes_sees_the_ticks_before_it(db_url: str) -> None:
    """Read-your-writes for another connection (the ROS services: DbPool flushes)."""
    lists = Lists()
    with toaster.connect(db_url) as db, toaster.connect(db_url) as other:
        db.store().put_area("kitchen", ROOM)
        node = LiveNode(db, outputs=[lists])
        with Node(node) as running:
            for place in (OUT, IN, OUT, IN):
                with running.lock:
                    running.feeding, running.at = False, place
                sent = len(lists.sent)
                wait_for(
                    lambda p=place, s=sent: any(  # type: ignore[misc]
                        inside == (p == IN) for _, inside in lists.sent[s:]
                    ),
                    "a fact list with bob's new place",
                )
                assert node.flush_writes(60.0)
                assert (("bob", "kitchen") in stored(other, "IsInRoom")) == (place == IN)
        assert not running.errors, running.errors


def test_a_replaced_tick_leaves_its_registrations_and_its_actors_to_the_next() -> None:
    """A tick replaced while it waited is written as the newer one's snapshot: the entities
    it registered and who moved what in it (the actor of a change first stored then) go with
    the newer tick; the newer tick's own actor wins for a thing both moved."""
    from toaster.node.writer import Pending
    from toaster.producers.batch import TickFacts

    older = Pending(
        1, {}, {"CUP": "ANNE", "BALL": "BOB"}, TickFacts({}), [("CUP", "object", "", "", None)]
    )
    newer = Pending(2, {}, {"BALL": "SALLY"}, TickFacts({}), [("BOX", "object", "", "", None)])
    written = older.merged(newer)
    assert written.t_ns == 2
    assert written.movers == {"CUP": "ANNE", "BALL": "SALLY"}
    assert [row[0] for row in written.register] == ["CUP", "BOX"]
