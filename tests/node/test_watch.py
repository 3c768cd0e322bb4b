"""Subscriptions: a watcher gets each matching event as another connection commits it."""

from __future__ import annotations

import threading
import time

import pytest

import toaster
from toaster.model import Fact
from toaster.queries import watch

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)


def test_a_watcher_gets_matching_events_committed_by_another_writer(db_url):
    got: list = []
    ready = threading.Event()

    def listen() -> None:
        with toaster.connect(db_url) as db:
            stream = watch(db, subject="B*", property="IsOn", timeout_s=5.0)
            ready.set()
            for row in stream:
                got.append((row.kind, row.subject_id, row.target_id, time.monotonic()))
                if len(got) == 2:
                    return

    with toaster.connect(db_url) as db:
        store = db.store()
        store.add_entity("R", "robot", is_self=True, t_ns=0)
        thread = threading.Thread(target=listen)
        # the watcher starts after this first fact: it is not delivered
        store.sync_snapshot("s", "R", 1, [Fact("BOOK", "IsOn", "TABLE")])
        thread.start()
        assert ready.wait(10)
        time.sleep(0.2)
        store.sync_snapshot(
            "s",
            "R",
            2,
            [
                Fact("BOOK", "IsOn", "TABLE"),
                Fact("CUP", "IsOn", "TABLE"),  # no match: C*
                Fact("BOX", "IsIn", "TABLE"),
            ],
        )  # no match: IsIn
        sent = time.monotonic()
        store.sync_snapshot("s", "R", 3, [Fact("BALL", "IsOn", "SHELF")])
        thread.join(10)
    assert [g[:3] for g in got] == [("ended", "BOOK", "TABLE"), ("appeared", "BALL", "SHELF")]
    assert got[0][3] - sent < 1.0  # pushed, not found by a later poll of minutes
