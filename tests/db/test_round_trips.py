"""A PostgreSQL tick of the library costs a fixed few round trips, whatever it writes (issue 28).

The store sends a write's statements in batches (psycopg's pipeline mode): the transaction's
BEGIN with its header (cache epoch, the rules' clock) in one round trip, the reads its diff
needs in another, the writes and the belief run in a third, then COMMIT. Round trips are counted on the real psycopg
connection from libpq's trace of the messages it sends, never timed. Batching changes nothing
of what is written: the same ticks written batched and checked one answer at a time (inside a
caller's transaction the store checks each answer before it sends on) store the same rows, on
both backends.
"""

from __future__ import annotations

import os
from collections.abc import Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa

import toaster
from tests.beliefs import test_write_surface as surface
from toaster.beliefs import api
from toaster.db.engine import dbapi, make_engine

BACKENDS = surface.BACKENDS
fresh_urls = surface.fresh_urls  # a factory of fresh databases of the test's backend

F = toaster.Fact
S = 1_000_000_000
HUMANS = ("ANNE", "BOB")
#: BEGIN with the header (cache epoch, rules' clock), the reads, the writes with the belief
#: run, COMMIT. Before batching: 18 for the same tick, one per statement.
STEADY_TICK_ROUND_TRIPS = 4


def tick(i: int) -> list[tuple[str, list[toaster.Fact]]]:
    """Two sources' snapshots at tick ``i``: every tick a thing appears (a new key) and the one
    before ends, the door opens or closes (a change), a distance moves beyond its tolerance (a
    refresh), and on even ticks the ball comes back on the table (a known key, its last end
    read)."""
    rooms = [F(who, "IsInRoom", "ROOM") for who in (*HUMANS, "CUP", "BALL", "DOOR", f"THING{i}")]
    things = [
        F("DOOR", "IsOpen", value_text="true" if i % 2 else "false"),
        F("CUP", "Distance", "ROBOT", value_num=1.0 + 0.1 * i),
        *([F("BALL", "IsOn", "TABLE")] if i % 2 == 0 else []),
    ]
    return [("rooms", rooms), ("things", things)]


def setup(db: toaster.Database) -> toaster.Store:
    store = db.store()
    store.add_entity("ROBOT", "robot", is_self=True, t_ns=0)
    for who in HUMANS:
        store.add_entity(who, "human", t_ns=0)
    return store


def round_trips(trace: str) -> int:
    """Times the client waited for the server, from libpq's trace: each simple query and each
    Sync (a statement outside a pipeline, or the end of a batch), and each Flush that asks a
    pipeline's results early (the one right after a Sync belongs to it)."""
    sent = [line.split("\t")[2] for line in trace.splitlines() if line.startswith("F\t")]
    waits = 0
    for n, message in enumerate(sent):
        if message in ("Query", "Sync") or (message == "Flush" and sent[n - 1] != "Sync"):
            waits += 1
    return waits


@contextmanager
def traced(db: toaster.Database, path: Path) -> Iterator[None]:
    """libpq's trace of the store's connection into ``path`` (its messages, no timestamps)."""
    from psycopg import pq

    raw: Any = dbapi(db.connection)
    fd = os.open(path, os.O_WRONLY | os.O_CREAT | os.O_TRUNC)
    raw.pgconn.trace(fd)
    raw.pgconn.set_trace_flags(pq.Trace.SUPPRESS_TIMESTAMPS | pq.Trace.REGRESS_MODE)
    try:
        yield
    finally:
        raw.pgconn.untrace()
        os.close(fd)


@pytest.mark.backend("postgresql")
def test_a_steady_tick_takes_four_round_trips(db: toaster.Database, tmp_path: Path) -> None:
    store = setup(db)
    for i in range(8):  # past psycopg's preparing of each statement (its 5th execution)
        store.sync_many("ROBOT", (i + 1) * S, tick(i))
    for i in range(8, 11):
        with traced(db, tmp_path / "trace"):
            results = store.sync_many("ROBOT", (i + 1) * S, tick(i))
        trace = (tmp_path / "trace").read_text()
        rooms, things = results
        assert (rooms.appeared, rooms.ended, things.changed, things.refreshed) == (1, 1, 1, 1)
        assert things.appeared + things.ended == 1  # the ball, back or gone
        assert round_trips(trace) <= STEADY_TICK_ROUND_TRIPS, trace
    # the belief run reached the holders: Anne believes the door closed, as it is now
    door = {(b.property, b.value_text) for b in api.beliefs(db, "ANNE", subject="DOOR")}
    assert ("IsOpen", "false") in door


_SAMPLES = (
    "SELECT k.agent_id, k.subject_id, k.property, k.target_id, s.until_ns, s.value_num, "
    "s.confidence, s.observability FROM fact_samples s JOIN facts f ON f.id = s.fact_id "
    "JOIN fact_keys k ON k.id = f.key_id"
)


def _samples(url: str) -> list[tuple[Any, ...]]:
    engine = make_engine(url)
    try:
        with engine.connect() as conn:
            return sorted(tuple(row) for row in conn.execute(sa.text(_SAMPLES)))
    finally:
        engine.dispose()


@pytest.mark.parametrize("fresh_urls", BACKENDS, indirect=True)
def test_batched_ticks_store_what_checked_ticks_store(fresh_urls: Any) -> None:
    batched, checked = fresh_urls(), fresh_urls()
    for url, inside in ((batched, False), (checked, True)):
        with toaster.connect(url) as db:
            store = setup(db)
            for i in range(12):
                if inside:  # a caller's transaction: each answer checked before sending on
                    with store.transaction():
                        store.sync_many("ROBOT", (i + 1) * S, tick(i))
                else:
                    store.sync_many("ROBOT", (i + 1) * S, tick(i))
    expected, got = surface.snapshot(checked), surface.snapshot(batched)
    assert any(row[0] == "ANNE" for row in got["history"]), "no belief written"
    for name in expected:
        assert got[name] == expected[name], name
    assert _samples(batched) == _samples(checked) != []


@pytest.mark.parametrize("fresh_urls", BACKENDS, indirect=True)
def test_two_sources_stating_one_new_fact_in_one_tick(fresh_urls: Any) -> None:
    """The second source reads the fact the first one opens in the same tick (its reads wait
    for the first one's writes): one interval, one event."""
    with toaster.connect(fresh_urls()) as db:
        store = setup(db)
        cup = F("CUP", "IsOn", "TABLE")
        first, second = store.sync_many("ROBOT", S, [("a", [cup]), ("b", [cup])])
        assert (first.appeared, second.appeared, second.unchanged) == (1, 0, 0)
        assert len(toaster.queries.history(db, "ROBOT", subject="CUP")) == 1
        assert [e.kind for e in toaster.queries.events(db, "ROBOT", subject="CUP")] == ["appeared"]


@pytest.mark.parametrize("fresh_urls", BACKENDS, indirect=True)
def test_a_fact_another_writer_ended_ends_without_a_second_event(fresh_urls: Any) -> None:
    """Another process's store ends a fact this store's source holds (no cache epoch moves):
    the source's next snapshot without it finds nothing to close, and writes no event (the
    batched write finds out after the fact and writes the tick again, checking first)."""
    url = fresh_urls()
    cup = F("CUP", "IsOn", "TABLE")
    with toaster.connect(url) as db, toaster.connect(url) as other:
        store = setup(db)
        store.sync_snapshot("mine", "ROBOT", 1 * S, [cup, F("BALL", "IsOn", "TABLE")])
        theirs = other.store()
        theirs.sync_snapshot("theirs", "ROBOT", 2 * S, [cup])  # the same fact: adopted
        theirs.sync_snapshot("theirs", "ROBOT", 3 * S, [])  # and ended
        result = store.sync_snapshot("mine", "ROBOT", 4 * S, [F("BALL", "IsOn", "TABLE")])
        assert (result.ended, result.unchanged) == (0, 1)
        kinds = [(e.kind, e.stamp_ns) for e in toaster.queries.events(db, "ROBOT", subject="CUP")]
        assert kinds == [("appeared", 1 * S), ("ended", 3 * S)]


@pytest.mark.backend("postgresql")
def test_a_tick_waiting_for_the_rules_clock_fails_in_one_line(
    db_url: str, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The header of a snapshot's transaction locks the rules' clock: a session holding it
    longer than the lock timeout makes the tick fail in one line, rolled back."""
    from toaster.errors import DatabaseLockedError

    monkeypatch.setenv("TOASTER_LOCK_TIMEOUT", "0.5")
    holder = make_engine(db_url)
    with toaster.connect(db_url) as db, holder.connect() as other:
        store = setup(db)
        store.sync_many("ROBOT", S, tick(0))
        other.begin()
        other.exec_driver_sql("SELECT * FROM store_state FOR UPDATE")
        with pytest.raises(DatabaseLockedError, match=r"locked by another session"):
            store.sync_many("ROBOT", 2 * S, tick(1))
        other.rollback()
        assert [r.appeared for r in store.sync_many("ROBOT", 2 * S, tick(1))] == [1, 0]
    holder.dispose()


def test_ticks_inside_and_after_a_callers_database_transaction(db: toaster.Database) -> None:
    """A write inside ``db.transaction()`` joins it (the store begins nothing of its own), and
    the writes after it are transactions as before: a failing one leaves nothing."""
    store = setup(db)
    with db.transaction():
        store.sync_many("ROBOT", S, tick(0))
    store.sync_many("ROBOT", 2 * S, tick(1))
    with pytest.raises(toaster.errors.InvalidInputError), store.transaction():
        store.sync_many("ROBOT", 3 * S, tick(2))
        store.add_entity("", "object")  # refused: the tick above is rolled back with it
    assert store.sync_many("ROBOT", 3 * S, tick(2))[0].appeared == 1
    assert {e.stamp_ns for e in toaster.queries.events(db, "ROBOT")} == {S, 2 * S, 3 * S}


@pytest.mark.backend("postgresql")
def test_ticks_store_again_when_the_server_comes_back(db_url: str) -> None:
    """A tick that cannot reach the server (or connect to it) fails and leaves the store as
    it was: the ticks after the server came back are transactions of their own, stored with
    their events."""
    from tests.node.test_faults import Proxy

    proxy = Proxy()
    via_proxy = db_url.replace("127.0.0.1:5432", f"127.0.0.1:{proxy.port}")
    assert via_proxy != db_url
    try:
        with toaster.connect(via_proxy) as db:
            store = setup(db)
            store.sync_many("ROBOT", S, tick(0))
            proxy.down()
            for i in (1, 2):  # the first finds its connection reset, the second cannot connect
                with pytest.raises((sa.exc.OperationalError, toaster.errors.DatabaseOpenError)):
                    store.sync_many("ROBOT", (1 + i) * S, tick(i))
                db.reset_connection()  # as a live node does after a lost connection
            proxy.up()
            assert store.sync_many("ROBOT", 4 * S, tick(3))[0].appeared == 1
            store.add_entity("CAT", "animal", t_ns=4 * S)
        with toaster.connect(db_url) as db:
            stamps = {e.stamp_ns for e in toaster.queries.events(db, "ROBOT")}
            assert stamps == {S, 4 * S}
            assert [e.id for e in toaster.queries.entities(db, "CAT")] == ["CAT"]
    finally:
        proxy.down()
