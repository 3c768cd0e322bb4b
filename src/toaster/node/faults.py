"""What a live node does when part of a tick fails (used by :mod:`toaster.node.live_node`).

Every error inside a tick is contained: the tick's transaction is rolled back, the error is
classified (:func:`classify`), logged once (:class:`Faults`: one line, again at most once a
minute while it lasts, and once when it heals), and database faults are retried with a
backoff (:class:`Backoff`, 0.1 s doubling to 5 s) on a new connection. The world model stays
in memory meanwhile and the sources keep the newest pose per entity.

The time during which no tick was stored is recorded, once a tick is stored again, as one
event of the self agent (:class:`Gap`: property ``RecordingGap``, stamped at the last tick
stored before the outage, ``value_num`` its length in ns, ``value_text`` its length in
seconds and the first fault),
so that a reader can tell "nobody was watching" from "nothing changed". Open intervals are
not closed at the outage: the first tick stored after it writes the state then, so a fact
that ended during the gap ends at that tick.
"""

from __future__ import annotations

import functools
import sqlite3
import threading
import time
import traceback
from collections.abc import Callable
from dataclasses import dataclass, field
from typing import Any, TypeVar

from sqlalchemy.exc import DBAPIError, SQLAlchemyError

from toaster.errors import (
    ConcurrentWriteError,
    DatabaseLockedError,
    DatabaseOpenError,
    InvalidInputError,
    ToasterError,
    one_line,
)
from toaster.model import Fact
from toaster.timeutil import format_ns

#: The database connection is gone (a server restart, ``pg_terminate_backend``, a network
#: cut): the node drops it and connects again.
CONNECTION = "connection"
#: Another writer held a lock longer than ``TOASTER_LOCK_TIMEOUT`` or kept conflicting.
LOCKED = "locked"
#: Any other database error (disk I/O, a full disk, a statement the server cancelled).
DATABASE = "database"
#: A value the store refused (a :class:`~toaster.errors.ToasterError` that is no fault of the
#: database): the tick is lost, the next one is tried as usual.
REFUSED = "refused"
#: Any other exception: a bug. The tick is lost, the next one is tried as usual.
BUG = "bug"

#: The kinds retried with a backoff, and those after which the connection is replaced.
BACKOFF_KINDS = frozenset({CONNECTION, LOCKED, DATABASE})
RECONNECT_KINDS = frozenset({CONNECTION, DATABASE})

#: The property of the gap events (one per outage, of the self agent, about itself).
GAP_PROPERTY = "RecordingGap"
#: The source of the gap events.
GAP_SOURCE = "toaster.node"
#: Seconds between two log lines about one lasting fault.
REPEAT_LOG_S = 60.0

_LOCK_STATES = {"55P03", "40001", "40P01"}  # lock_not_available, serialization, deadlock
_GONE_STATES = {"57P01", "57P02", "57P03"}  # admin / crash shutdown, cannot connect now


def classify(exc: BaseException) -> str:
    """The kind of a tick's error: :data:`CONNECTION`, :data:`LOCKED`, :data:`DATABASE`,
    :data:`REFUSED` or :data:`BUG` (the driver's error is looked for under SQLAlchemy's and
    toaster's own)."""
    if isinstance(exc, DatabaseLockedError | ConcurrentWriteError):
        return LOCKED
    if isinstance(exc, InvalidInputError):  # a value refused, by toaster or the database
        return REFUSED
    if isinstance(exc, DBAPIError) and exc.connection_invalidated:
        return CONNECTION
    cause = _driver_error(exc)
    if isinstance(cause, sqlite3.Error):
        name = str(getattr(cause, "sqlite_errorname", ""))
        return LOCKED if name.startswith("SQLITE_BUSY") else DATABASE
    if cause is not None:  # psycopg's
        state = getattr(cause, "sqlstate", None) or ""
        if state in _LOCK_STATES:
            return LOCKED
        if state.startswith("08") or state in _GONE_STATES:
            return CONNECTION
        if not state and type(cause).__name__ in ("OperationalError", "InterfaceError"):
            return CONNECTION  # no answer from the server: a closed or broken connection
        return DATABASE
    if isinstance(exc, DatabaseOpenError):
        return CONNECTION
    if isinstance(exc, SQLAlchemyError):
        return DATABASE
    if isinstance(exc, ToasterError):
        return REFUSED
    return BUG


def _causes(exc: BaseException) -> list[BaseException]:
    """``exc``, the driver error SQLAlchemy wraps (``orig``) and its causes (``from``)."""
    seen: list[BaseException] = []
    todo: list[BaseException | None] = [exc]
    while todo and len(seen) < 8:
        item = todo.pop(0)
        if item is None or any(item is s for s in seen):
            continue
        seen.append(item)
        todo += [getattr(item, "orig", None), item.__cause__]
    return seen


def describe(exc: BaseException) -> str:
    """One line about ``exc``: the driver's message for a database error (not SQLAlchemy's
    wrapping, nor a "cannot connect" said of a connection lost midway), toaster's own message
    for its errors, and for a bug its type and where it was raised."""
    driver = _driver_error(exc)
    if driver is not None and not isinstance(exc, DatabaseLockedError | ConcurrentWriteError):
        exc = driver
    lines = str(exc).strip().splitlines()
    text = one_line(lines[0] if lines else "")[:300]
    if driver is not None or isinstance(exc, ToasterError | SQLAlchemyError):
        return text or type(exc).__name__
    frames = traceback.extract_tb(exc.__traceback__)
    where = f" at {frames[-1].filename.rsplit('/', 1)[-1]}:{frames[-1].lineno}" if frames else ""
    return f"{type(exc).__name__}: {text}{where}" if text else f"{type(exc).__name__}{where}"


def _driver_error(exc: BaseException) -> BaseException | None:
    for cause in _causes(exc):
        if isinstance(cause, sqlite3.Error) or type(cause).__module__.startswith("psycopg"):
            return cause
    return None


@dataclass
class Backoff:
    """Seconds to wait before the next attempt: 0 while healthy, then ``first_s`` doubling
    up to ``max_s``."""

    first_s: float = 0.1
    max_s: float = 5.0
    delay: float = 0.0

    def failed(self) -> float:
        self.delay = self.first_s if self.delay == 0 else min(self.max_s, self.delay * 2)
        return self.delay

    def reset(self) -> None:
        self.delay = 0.0


@dataclass(frozen=True)
class Gap:
    """Ticks not stored: the state was written at ``start_ns`` and next at ``end_ns``; what
    changed in between is stamped ``end_ns``."""

    start_ns: int
    end_ns: int
    reason: str

    def fact(self, self_id: str) -> Fact:
        """The event that records it (see the module's docstring)."""
        return Fact(
            self_id,
            GAP_PROPERTY,
            "",
            f"{(self.end_ns - self.start_ns) / 1e9:.3f} s not stored; {self.reason}"[:300],
            float(self.end_ns - self.start_ns),
        )


@dataclass
class _Trouble:
    """One lasting fault of a component (a producer, an output) or of the tick."""

    first: float
    logged: float
    count: int = 1


_F = TypeVar("_F", bound=Callable[..., Any])


def _locked(method: _F) -> _F:
    """Run under the instance's lock: a live node's tick and writer threads both report."""

    @functools.wraps(method)
    def run(self: Faults, *args: Any, **kwargs: Any) -> Any:
        with self._lock:
            return method(self, *args, **kwargs)

    return run  # type: ignore[return-value]


@dataclass
class Faults:
    """The fault state of one node: the current outage, its backoff, the gaps to record,
    the components that fail, and counts for the summary (thread-safe)."""

    warn: Callable[[str], None]
    backoff: Backoff = field(default_factory=Backoff)
    clock: Callable[[], float] = time.monotonic
    counts: dict[str, int] = field(default_factory=dict)  # failed ticks per kind
    gaps: int = 0  # outages healed
    gap_ns: int = 0  # their total length
    pending: list[Gap] = field(default_factory=list)  # healed, not yet recorded
    last_stored_ns: int | None = None
    _outage: tuple[int, str, str] | None = None  # (start_ns, kind, reason)
    _tick: _Trouble | None = None
    _parts: dict[str, _Trouble] = field(default_factory=dict)
    _lock: threading.RLock = field(default_factory=threading.RLock)

    @property
    def failing(self) -> bool:
        """True from a failed tick to the next stored one."""
        return self._outage is not None

    @property
    def delay(self) -> float:
        """Seconds to wait before the next attempt (0: tick at the usual pace)."""
        return self.backoff.delay

    @_locked
    def tick_failed(self, exc: BaseException, t_ns: int) -> str:
        """A tick at ``t_ns`` was not stored: note it, log it once; returns its kind."""
        kind = classify(exc)
        self.counts[kind] = self.counts.get(kind, 0) + 1
        reason = f"{kind}: {describe(exc)}"
        if kind in BACKOFF_KINDS:
            self.backoff.failed()
        else:
            self.backoff.reset()
        now = self.clock()
        if self._outage is None:
            start = self.last_stored_ns if self.last_stored_ns is not None else t_ns
            self._outage = (start, kind, reason)
            self._tick = _Trouble(now, now)
            retry = (
                f"retrying with a backoff up to {self.backoff.max_s:g} s"
                if kind in BACKOFF_KINDS
                else "next tick as usual"
            )
            self.warn(f"tick not stored ({reason}); {retry}, the world model is kept")
            return kind
        trouble = self._tick
        assert trouble is not None
        trouble.count += 1
        if now - trouble.logged >= REPEAT_LOG_S or kind != self._outage[1]:
            trouble.logged = now
            self._outage = (self._outage[0], kind, self._outage[2])
            self.warn(
                f"still no tick stored after {now - trouble.first:.0f} s "
                f"({trouble.count} attempts): {reason}"
            )
        return kind

    @_locked
    def tick_stored(self, t_ns: int) -> Gap | None:
        """A tick at ``t_ns`` was stored; the gap it ends, if any (also kept in
        :attr:`pending` until :meth:`recorded`)."""
        self.last_stored_ns = t_ns
        self.backoff.reset()
        if self._outage is None:
            return None
        start, _kind, reason = self._outage
        trouble = self._tick
        self._outage, self._tick = None, None
        gap = Gap(start, max(t_ns, start), reason)
        self.gaps += 1
        self.gap_ns += gap.end_ns - gap.start_ns
        self.pending.append(gap)
        del self.pending[:-100]  # a database that takes no gap event: keep the newest
        attempts = trouble.count if trouble is not None else 1
        self.warn(
            f"ticks stored again: {(gap.end_ns - gap.start_ns) / 1e9:.3f} s not "
            f"recorded ({attempts} failed attempts), kept as event {GAP_PROPERTY}"
        )
        return gap

    @_locked
    def recorded(self, gap: Gap) -> None:
        """``gap``'s event is stored."""
        self.pending.remove(gap)

    @_locked
    def part_failed(
        self,
        name: str,
        exc: BaseException,
        effect: str = "the others go on, its facts are left as they were until it works again",
    ) -> None:
        """A component (producer, output) failed in a tick that goes on without it: one
        line, again at most once a minute while it keeps failing."""
        now = self.clock()
        trouble = self._parts.get(name)
        if trouble is None:
            self._parts[name] = _Trouble(now, now)
            self.warn(f"{name} failed ({describe(exc)}); {effect}")
            return
        trouble.count += 1
        if now - trouble.logged >= REPEAT_LOG_S:
            trouble.logged = now
            self.warn(
                f"{name} still fails ({trouble.count} times in "
                f"{now - trouble.first:.0f} s): {describe(exc)}"
            )

    @_locked
    def part_worked(self, name: str) -> None:
        """A component that failed works again."""
        trouble = self._parts.pop(name, None)
        if trouble is not None:
            self.warn(f"{name} works again after {trouble.count} failures")

    @_locked
    def noted(self, what: str, exc: BaseException, effect: str) -> str:
        """An error beside a stored tick (maintenance, a gap's event): logged like a
        component's (:meth:`part_worked` when it works again); returns its kind."""
        self.part_failed(what, exc, effect)
        return classify(exc)

    @_locked
    def summary(self) -> str:
        """One line for the end of a run ('' when nothing failed)."""
        if not self.counts and not self._parts:
            return ""
        kinds = ", ".join(f"{n} {k}" for k, n in sorted(self.counts.items()))
        parts = f"; failing now: {', '.join(sorted(self._parts))}" if self._parts else ""
        open_gap = ""
        if self._outage is not None:
            since = format_ns(self._outage[0])
            open_gap = f"; nothing stored since {since} (that gap is not recorded)"
        recorded = self.gaps - len(self.pending)
        return (
            f"{sum(self.counts.values())} ticks not stored ({kinds or 'none'}); "
            f"{recorded} gaps recorded, {self.gap_ns / 1e9:.3f} s in all{open_gap}{parts}"
        )


__all__ = ["Backoff", "Faults", "Gap", "classify", "describe"]
