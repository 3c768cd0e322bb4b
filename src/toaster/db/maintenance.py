"""Database maintenance on a thread of its own, beside a live writer.

Maintaining between two ticks stalls the writer for as long as maintenance takes: a
PostgreSQL VACUUM of the hot tables grows with them (docs/live.md) and SQLite's truncating
checkpoint waits for readers. A :class:`Maintainer` runs
:meth:`toaster.db.dialects.Backend.maintain` with ``beside_writer=True`` on a connection of
its own every ``every_s`` seconds: a VACUUM takes no lock that row writes wait for, and
SQLite's passive checkpoint copies what it can without blocking the writer.
"""

from __future__ import annotations

import logging
import threading
import time
from typing import TYPE_CHECKING

from toaster.errors import one_line

if TYPE_CHECKING:
    from toaster.db.database import Database

log = logging.getLogger("toaster.db")


class Maintainer:
    """Maintain ``db`` every ``every_s`` seconds on a thread and a connection of its own.

    A failure (a lost connection, a lock held too long) is logged once per kind of error
    and retried at the next turn; it never reaches the writer.
    """

    def __init__(self, db: Database, every_s: float) -> None:
        if every_s <= 0:
            msg = f"maintenance period {every_s} s must be positive"
            raise ValueError(msg)
        self.db = db
        self.every_s = every_s
        self.runs = 0
        self.failures = 0
        self.last_s = 0.0  # how long the last maintenance took
        self._stop = threading.Event()
        self._thread: threading.Thread | None = None
        self._reported: set[str] = set()

    def start(self) -> Maintainer:
        """Start the thread (once)."""
        if self._thread is None:
            self._thread = threading.Thread(
                target=self._loop, name="toaster-maintenance", daemon=True
            )
            self._thread.start()
        return self

    def stop(self, timeout_s: float = 30.0) -> None:
        """Stop the thread, letting a running maintenance finish."""
        self._stop.set()
        if self._thread is not None:
            self._thread.join(timeout_s)
            self._thread = None

    def __enter__(self) -> Maintainer:
        return self.start()

    def __exit__(self, *_exc: object) -> None:
        self.stop()

    def _loop(self) -> None:
        while not self._stop.wait(self.every_s):
            self.run_once()

    def run_once(self) -> bool:
        """Maintain once on a fresh pooled connection; False if it failed (logged)."""
        start = time.monotonic()
        try:
            with self.db.engine.connect() as conn:
                raw = self.db.raw_connection(conn)
                raw.rollback()  # the pool's ping may have left a transaction open
                self.db.backend.maintain(raw, beside_writer=True)
                conn.rollback()  # nothing of ours is left open in the pool
        except Exception as exc:  # whatever fails, the writer carries on
            self.failures += 1
            kind = type(exc).__name__
            if kind not in self._reported:
                self._reported.add(kind)
                log.warning(
                    "database maintenance failed (retried every %.0f s): %s",
                    self.every_s,
                    one_line(str(exc).splitlines()[0] if str(exc) else kind),
                )
            return False
        self.last_s = time.monotonic() - start
        self.runs += 1
        return True


__all__ = ["Maintainer"]
