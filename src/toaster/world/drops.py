"""Inputs dropped at the edge: counted per (topic, field), one warning line per key at most
every ``every_s`` seconds (thread-safe: rospy callbacks and service threads drop, the node's
thread drains the lines).

Keys are a topic (or service) and a field name, never a value, so the table stays as small as
the set of inputs however many distinct bad values arrive. Lines name the topic, the field
and the value, shortened and escaped by the check that refused it
(:func:`toaster.model.shown`, :func:`toaster.errors.one_line`).
"""

from __future__ import annotations

import threading
import time
from collections.abc import Callable

from toaster.errors import InvalidInputError, one_line

#: at most this many (topic, field) keys are counted apart; the rest count under "other"
MAX_KEYS = 1000


class Refused(InvalidInputError):
    """An input value refused at the edge; ``field`` names what was wrong in it."""

    def __init__(self, message: str, field: str = "request") -> None:
        super().__init__(message)
        self.field = field


def refuse_if(
    check: Callable[[object, str], object], value: object, field: str, what: str | None = None
) -> None:
    """Run one of the store's checks (``check(value, what)``); :class:`Refused` naming
    ``field`` when it fails."""
    try:
        check(value, what or field)
    except (InvalidInputError, ValueError, TypeError, OverflowError) as exc:
        raise Refused(str(exc), field) from None


class Drops:
    """Counts of dropped inputs and their rate-limited warning lines."""

    def __init__(self, every_s: float = 10.0) -> None:
        self.every_s = every_s
        self._counts: dict[tuple[str, str], int] = {}
        self._last: dict[tuple[str, str], float] = {}
        self._lines: list[str] = []
        self._lock = threading.Lock()

    def drop(self, topic: str, field: str, reason: str, verb: str = "dropped") -> None:
        """Count one input dropped from ``topic`` for ``field`` (``reason`` names the value);
        the line reads ``"<topic>: <reason> (<verb>: <field>, <n> so far)"``."""
        key = (topic, field)
        now = time.monotonic()
        with self._lock:
            if key not in self._counts and len(self._counts) >= MAX_KEYS:
                key = ("other", "other")
            count = self._counts[key] = self._counts.get(key, 0) + 1
            if now - self._last.get(key, -1e18) >= self.every_s:
                self._last[key] = now
                self._lines.append(
                    one_line(f"{key[0]}: {reason} ({verb}: {key[1]}, {count} so far)")
                )

    def counts(self) -> dict[str, int]:
        """``{"topic field": count}``, sorted."""
        with self._lock:
            return {f"{t} {f}": n for (t, f), n in sorted(self._counts.items())}

    @property
    def total(self) -> int:
        with self._lock:
            return sum(self._counts.values())

    def take_lines(self) -> list[str]:
        """The warning lines since the last call."""
        with self._lock:
            out, self._lines = self._lines, []
        return out

    def summary(self) -> str:
        """``"3 (/toaster_simu/objectList id 2, ...)"`` or ``"0"``."""
        counts = self.counts()
        if not counts:
            return "0"
        return f"{sum(counts.values())} ({', '.join(f'{k} {n}' for k, n in counts.items())})"
