"""Subscriptions: each committed event matching a pattern, pushed as it is committed.

``watch`` yields :class:`~toaster.model.EventRow` rows of ``event_log`` newer than the start
(or than ``after_id``) whose agent, subject, property and target match glob patterns (``*``,
``?``; ``None`` matches all). How a watcher learns that something was committed is the one
difference between the backends: PostgreSQL sends ``NOTIFY toaster_events`` from a statement
trigger on ``events`` (revision 0005: any writer, a SQL script included) and the watcher
LISTENs; on SQLite the watcher looks at ``PRAGMA data_version`` (which moves when another
connection commits) every ``poll_s``.
"""

from __future__ import annotations

import fnmatch
import threading
import time
from collections.abc import Iterator
from typing import TYPE_CHECKING

from sqlalchemy import text

from toaster.model import EventRow, check_text
from toaster.queries.events import EVENT_COLUMNS
from toaster.timeutil import check_count, check_seconds

if TYPE_CHECKING:
    from toaster.db.database import Database

EVENTS_CHANNEL = "toaster_events"


class _Listen:
    """PostgreSQL: wait for ``NOTIFY toaster_events`` on a connection of its own."""

    def __init__(self, db: Database) -> None:
        import psycopg

        self.conn = psycopg.connect(
            db.engine.url.set(drivername="postgresql").render_as_string(hide_password=False),
            autocommit=True,
        )
        self.conn.execute(f"LISTEN {EVENTS_CHANNEL}")

    def wait(self, timeout_s: float) -> None:
        for _ in self.conn.notifies(timeout=timeout_s, stop_after=1):
            break

    def close(self) -> None:
        self.conn.close()


class _DataVersion:
    """SQLite: poll ``PRAGMA data_version``, which moves when another connection commits."""

    def __init__(self, db: Database, poll_s: float) -> None:
        self.raw = db.engine.raw_connection()
        self.poll_s = poll_s
        self.seen = self._version()

    def _version(self) -> int:
        cur = self.raw.cursor()
        cur.execute("PRAGMA data_version")
        row = cur.fetchone()
        assert row is not None  # the pragma always answers one row
        return int(row[0])

    def wait(self, timeout_s: float) -> None:
        deadline = time.monotonic() + timeout_s
        while time.monotonic() < deadline:
            version = self._version()
            if version != self.seen:
                self.seen = version
                return
            time.sleep(min(self.poll_s, max(0.0, deadline - time.monotonic())))

    def close(self) -> None:
        self.raw.close()


def _matches(row: EventRow, patterns: dict[str, str | None]) -> bool:
    return all(
        pattern is None or fnmatch.fnmatchcase(getattr(row, field) or "", pattern)
        for field, pattern in patterns.items()
    )


def watch(
    db: Database,
    *,
    agent: str | None = None,
    subject: str | None = None,
    property: str | None = None,
    target: str | None = None,
    after_id: int | None = None,
    poll_s: float = 0.02,
    timeout_s: float | None = None,
    stop: threading.Event | None = None,
) -> Iterator[EventRow]:
    """Events committed from now on (or after event ``after_id``) that match the patterns,
    oldest first, as they are committed; stops after ``timeout_s`` without a match (None: never)
    or within half a second of ``stop`` being set.
    """
    patterns = {
        field: None if value is None else check_text(value, f"{field} pattern")
        for field, value in (
            ("agent_id", agent),
            ("subject_id", subject),
            ("property", property),
            ("target_id", target),
        )
    }
    after_id = check_count(after_id, "after_id")
    poll_s = check_seconds(poll_s, "poll_s")
    timeout_s = None if timeout_s is None else check_seconds(timeout_s, "timeout_s")
    with db.transaction() as conn:
        last = (
            after_id
            if after_id is not None
            else int(conn.execute(text("SELECT COALESCE(MAX(id), 0) FROM events")).scalar_one())
        )
    waker: _Listen | _DataVersion = (
        _Listen(db) if db.dialect_name == "postgresql" else _DataVersion(db, poll_s)
    )
    sql = text(f"SELECT {EVENT_COLUMNS} FROM event_log WHERE id > :last ORDER BY id, agent_id")
    quiet_since = time.monotonic()
    try:
        while stop is None or not stop.is_set():
            with db.transaction() as conn:
                rows = [EventRow(*r) for r in conn.execute(sql, {"last": last})]
            if rows:
                last = max(r.id for r in rows)
            matched = [r for r in rows if _matches(r, patterns)]
            yield from matched
            if matched:
                quiet_since = time.monotonic()
            left = None if timeout_s is None else timeout_s - (time.monotonic() - quiet_since)
            if left is not None and left <= 0:
                return
            waker.wait(0.5 if left is None else min(0.5, left))
    finally:
        waker.close()
