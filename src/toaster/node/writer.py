"""A live node's writer thread: tick k is written while tick k+1 computes (docs/live.md,
"Latency").

At most one write runs and one waits. A tick handed over while one waits replaces it: a
tick's snapshots are states, so writing the newer one stores what the older would have, at
the newer stamp (like a lower rate; :meth:`Pending.merged` keeps the entities the older one
registered). The database connection of the node's store is used by this thread, and by the
node's thread only inside :meth:`TickWriter.idle` (which waits for the writes handed over so
far and holds the lock the writer writes under). After a failed write the thread waits for
the backoff (``delay``) before the next; :meth:`TickWriter.close` writes what waits (unless
told not to: during an outage) and ends the thread.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass, field
from typing import Any

from toaster.model import Fact
from toaster.producers.batch import FactBatch, TickFacts


@dataclass
class Pending:
    """One computed tick waiting for its write: its producers' snapshots, who moved what,
    and the entities to register first (``(id, kind, name, owner, agent)`` rows)."""

    t_ns: int
    out: Mapping[str, list[Fact] | FactBatch]
    movers: Mapping[str, str]
    facts: TickFacts
    register: list[tuple[str, str, str, str, bool | None]] = field(default_factory=list)

    def merged(self, newer: Pending) -> Pending:
        """``newer`` written in place of this one: the registrations of both, and who moved
        what in either (a thing moved in this tick is first written with ``newer``'s
        snapshot: its actor made that change)."""
        newer.register = self.register + newer.register
        newer.movers = {**self.movers, **newer.movers}
        return newer


class TickWriter:
    """The thread that calls ``write(pending)`` for each tick handed over (:meth:`submit`);
    ``write`` never raises (the node handles its faults); ``delay()`` is the backoff to wait
    after it (0: none)."""

    def __init__(self, write: Callable[[Pending], Any], delay: Callable[[], float]) -> None:
        self._write, self._delay = write, delay
        self.lock = threading.Lock()  # held while the connection is in use (idle() too)
        self._cond = threading.Condition()
        self._queued: tuple[int, Pending] | None = None  # (its number, the tick)
        self._busy = False
        self._begun = 0  # number of the last tick begun
        self._submitted = 0  # ... and of the last handed over
        self._through = 0  # every tick up to this number is through (written, failed, none)
        self._abandoned = 0  # the last tick begun and not computed
        self._closing = threading.Event()
        self._drain = True
        self.thread = threading.Thread(target=self._run, name="toaster-writer", daemon=True)
        self.thread.start()

    def begin(self) -> None:
        """A tick starts computing: from now on :meth:`flush` waits for its write too (its
        fact lists go out before it is handed over)."""
        with self._cond:
            self._begun += 1

    def abandon(self) -> None:
        """The tick begun was not computed: nothing to wait for."""
        with self._cond:
            self._abandoned = self._begun
            if self._queued is None and not self._busy:
                self._through = self._begun
            self._cond.notify_all()

    def submit(self, pending: Pending) -> bool:
        """Hand the tick begun over (never waits); True if it replaced one still waiting
        (whose number it takes over: a reader waiting for that one waits for this one)."""
        with self._cond:
            replaced = self._queued is not None
            if self._queued is not None:
                pending = self._queued[1].merged(pending)
            self._queued = (self._begun, pending)
            self._submitted = self._begun
            self._cond.notify_all()
        return replaced

    def flush(
        self, timeout_s: float, *, unless: Callable[[], bool] = lambda: False, begun: bool = True
    ) -> bool:
        """Wait until the ticks begun so far (``begun``; else those handed over) are through
        the writer (read-your-writes for another connection), at most ``timeout_s``, or until
        ``unless()`` (an outage: nothing is written then); True if they are."""
        with self._cond:
            target = self._begun if begun else self._submitted
            return self._cond.wait_for(
                lambda: self._through >= target or unless() or not self.thread.is_alive(),
                timeout_s,
            ) and (self._through >= target)

    @contextmanager
    def idle(
        self, timeout_s: float = 10.0, *, unless: Callable[[], bool] = lambda: False
    ) -> Iterator[None]:
        """Use the store's connection on this thread (the one that begins and hands over the
        ticks, maybe while it computes one): after the ticks handed over (see :meth:`flush`),
        with the writer kept out."""
        self.flush(timeout_s, unless=unless, begun=False)
        with self.lock:
            yield

    def close(self, *, drain: bool = True, timeout_s: float = 60.0) -> None:
        """Write the tick that waits (``drain``; else drop it) and end the thread."""
        with self._cond:
            self._drain = drain
            self._closing.set()
            self._cond.notify_all()
        self.thread.join(timeout_s)

    def _take(self) -> tuple[int, Pending] | None:
        with self._cond:
            while self._queued is None and not self._closing.is_set():
                self._cond.wait()
            queued, self._queued = self._queued, None
            if queued is not None and self._closing.is_set() and not self._drain:
                self._through = self._begun  # dropped: nobody waits for it
                self._cond.notify_all()
                return None
            self._busy = queued is not None
            return queued

    def _run(self) -> None:
        while True:
            queued = self._take()
            if queued is None:
                return
            number, pending = queued
            with self.lock:
                self._write(pending)
            with self._cond:
                self._busy = False
                self._through = max(self._through, number)
                if self._queued is None:  # a tick begun since and not computed
                    self._through = max(self._through, self._abandoned)
                self._cond.notify_all()
            delay = self._delay()
            if delay > 0:
                self._closing.wait(delay)  # a close cuts the backoff short


__all__ = ["Pending", "TickWriter"]
