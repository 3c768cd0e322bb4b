"""The Foxglove server's publisher thread: what a live node's tick hands over (a snapshot of
the views, a read of beliefs and events, a health message) is built and sent here, off the
node's thread.

One slot per kind of job (:data:`KINDS`), latest wins: a job handed over while the previous
one of its kind still waits replaces it (``merge`` may fold the older into the newer), and
is counted in :attr:`Publisher.dropped` (on /toaster/health). The thread runs the jobs taken
together in the order of :data:`KINDS`. A job that fails is handed to ``failed`` (the node's
faults: logged once, then at most once a minute) and the thread goes on.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from typing import Any

#: the kinds of job, in the order the thread runs those it takes together
KINDS = ("views", "read", "health")


class Publisher:
    """The thread calling ``run(kind, job)`` for each job handed over (:meth:`submit`)."""

    def __init__(
        self,
        run: Callable[[str, Any], None],
        failed: Callable[[str, BaseException], None],
        worked: Callable[[str], None],
    ) -> None:
        self._run, self._failed, self._worked = run, failed, worked
        self._cond = threading.Condition()
        self._jobs: dict[str, Any] = {}
        self._closing = False
        self._busy = False  # running jobs taken
        self.dropped = 0  # jobs replaced before they ran
        self.thread = threading.Thread(target=self._loop, name="toaster-foxglove", daemon=True)
        self.thread.start()

    def submit(self, kind: str, job: Any, merge: Callable[[Any, Any], Any] | None = None) -> None:
        """Hand ``job`` over (never waits); it replaces the one of its ``kind`` still waiting
        (``merge(older, job)``: what runs instead)."""
        with self._cond:
            older = self._jobs.get(kind)
            if older is not None:
                self.dropped += 1
                if merge is not None:
                    job = merge(older, job)
            self._jobs[kind] = job
            self._cond.notify_all()

    def flush(self, timeout_s: float) -> bool:
        """Wait until the jobs handed over so far ran (at most ``timeout_s``); True if they
        did."""
        with self._cond:
            return self._cond.wait_for(lambda: not self._jobs and not self._busy, timeout_s)

    def _loop(self) -> None:
        while True:
            with self._cond:
                self._cond.wait_for(lambda: bool(self._jobs) or self._closing)
                if not self._jobs:
                    return
                jobs, self._jobs, self._busy = self._jobs, {}, True
            for kind in KINDS:
                if kind not in jobs:
                    continue
                try:
                    self._run(kind, jobs[kind])
                except Exception as exc:  # a job failing must not stop the thread
                    self._failed(kind, exc)
                else:
                    self._worked(kind)
            with self._cond:
                self._busy = False
                self._cond.notify_all()

    def close(self, timeout_s: float = 10.0) -> bool:
        """Run the jobs that wait and end the thread (at most ``timeout_s``); True if it
        ended."""
        with self._cond:
            self._closing = True
            self._cond.notify_all()
        self.thread.join(timeout_s)
        return not self.thread.is_alive()


__all__ = ["KINDS", "Publisher"]
