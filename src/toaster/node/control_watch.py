"""Whether a running node must read its control plane again: on PostgreSQL a thread LISTENs to
``NOTIFY toaster_control`` (sent with every control change, :mod:`toaster.node.control`) on a
connection of its own, so that a tick reads the control version only after a change (and at
least every ``max_age_s``). That read was the only database access before a tick's fact lists
go out, a round trip to a busy server each tick. SQLite has no notifications (and its read is
local): the node reads every tick, as without a watch.
"""

from __future__ import annotations

import threading
import time
from typing import TYPE_CHECKING

from toaster.db.catalog import CONTROL_CHANNEL

if TYPE_CHECKING:
    from toaster.db.database import Database

#: read the control version at least this often even without a notification (s)
MAX_AGE_S = 1.0


class ControlWatch:
    """A LISTEN thread and the flag it raises; :meth:`due` says when to read."""

    def __init__(self, db: Database, max_age_s: float | None = None) -> None:
        self.url = db.engine.url.set(drivername="postgresql").render_as_string(hide_password=False)
        self.max_age_s = MAX_AGE_S if max_age_s is None else max_age_s
        self.changed = threading.Event()
        self.changed.set()  # read at the first tick
        self.read_at = float("-inf")
        self.reads = 0  # how many times due() said to read
        self._stop = threading.Event()
        self._thread = threading.Thread(target=self._run, name="toaster-control-watch", daemon=True)

    @classmethod
    def of(cls, db: Database | None, max_age_s: float | None = None) -> ControlWatch | None:
        """A started watch for a PostgreSQL database (the dialect choice), else None."""
        if db is None or db.engine.dialect.name != "postgresql":
            return None
        watch = cls(db, max_age_s)
        watch._thread.start()
        return watch

    def due(self) -> bool:
        """Whether to read the control version now (a change was notified, the listener is
        down, or the last read is ``max_age_s`` old); the flag is cleared before the read, so
        that a change notified during it is read at the next tick."""
        now = time.monotonic()
        if self.changed.is_set() or now - self.read_at >= self.max_age_s:
            self.changed.clear()
            self.read_at = now
            self.reads += 1
            return True
        return False

    def _run(self) -> None:
        import psycopg

        while not self._stop.is_set():
            try:
                with psycopg.connect(self.url, autocommit=True, connect_timeout=10) as conn:
                    conn.execute(f"LISTEN {CONTROL_CHANNEL}")
                    self.changed.set()  # a change made before LISTEN is read too
                    while not self._stop.is_set():
                        for _ in conn.notifies(timeout=0.5, stop_after=1):
                            self.changed.set()
            except Exception:  # down: every tick reads (and meets the fault) until it is back
                self.changed.set()
                self._stop.wait(1.0)

    def stop(self) -> None:
        """Stop listening (the thread ends within half a second)."""
        self._stop.set()
        self._thread.join(5.0)
