"""Time in toaster is integer nanoseconds since the Unix epoch (UTC), everywhere.

`parse_time` accepts what a user types (``1700000000000000000``, ``2026-11-22T12:03:00Z``,
``now``, ``12.5s`` after the data's start, ``-5m`` before now) and `format_ns` shows a stored
time as a date; a :class:`TimeFrame` (the data's start and a display style) shows times as
elapsed seconds (``+12.500 s``) or dates, and reads them back (docs/time.md).
"""

from __future__ import annotations

import math
import re
import time
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from fractions import Fraction

from toaster.errors import InvalidInputError
from toaster.model import shown

NS_PER_S = 1_000_000_000
_UNITS = {
    "ns": 1,
    "us": 1_000,
    "µs": 1_000,
    "ms": 1_000_000,
    "s": NS_PER_S,
    "m": 60 * NS_PER_S,
    "min": 60 * NS_PER_S,
    "h": 3600 * NS_PER_S,
}
_DURATION = re.compile(r"^\s*([-+]?\d+(?:\.\d*)?|[-+]?\.\d+)\s*(ns|us|µs|ms|s|min|m|h)\s*$")
#: Times are signed 64-bit nanoseconds in the database, and never before the epoch.
MAX_NS = 2**63 - 1
_RANGE = "0 (1970-01-01T00:00:00Z) to 2^63-1 ns (2262-04-11T23:47:16Z)"
#: The slowest and fastest tick rates (ticks per second) a run may ask for: 0.1 ms to about
#: 11.6 days between ticks.
MIN_RATE_HZ, MAX_RATE_HZ = 1e-6, 10_000.0
_SECOND = timedelta(seconds=1)
_MAX_DIGITS = 30  # longer numbers are out of range anyway (and slow to convert)


def now_ns() -> int:
    """The wall clock, in nanoseconds since the epoch."""
    return time.time_ns()


def check_ns(value: object, what: str = "time") -> int:
    """Return ``value`` if it is a time the database can hold (an integer from 0 to 2^63-1
    ns), else raise a one-line error naming it and the range."""
    if not isinstance(value, int) or isinstance(value, bool):
        msg = f"invalid {what} {shown(value)}: times are integer nanoseconds"
        raise InvalidInputError(msg)
    if not 0 <= value <= MAX_NS:
        msg = f"{what} {_digits(value)} ns is out of range: times go from {_RANGE}"
        raise InvalidInputError(msg)
    return value


def check_optional_ns(value: object, what: str = "time") -> int | None:
    """``value`` if it is None (no time given) or a valid time (:func:`check_ns`)."""
    return None if value is None else check_ns(value, what)


def check_count(value: object, what: str) -> int | None:
    """``value`` if it is None (no bound) or a whole number from 0 to 2^63-1 (a row limit,
    an id), else a one-line error naming it."""
    if value is None:
        return None
    if not isinstance(value, int) or isinstance(value, bool) or not 0 <= value <= MAX_NS:
        msg = f"invalid {what} {shown(value)}: give a whole number from 0 to 2^63-1"
        raise InvalidInputError(msg)
    return value


def check_seconds(value: object, what: str) -> float:
    """``value`` as a number of seconds if it is a finite number >= 0 (a time-out, a polling
    period), else a one-line error naming it."""
    number = (
        float(value)
        if isinstance(value, int | float) and not isinstance(value, bool) and abs(value) < 1e300
        else math.nan
    )
    if not (math.isfinite(number) and number >= 0):
        msg = f"invalid {what} {shown(value)}: give a number of seconds >= 0"
        raise InvalidInputError(msg)
    return number


def _digits(value: int) -> str:
    """An integer for a message, cut when it is huge."""
    text = str(value) if abs(value) < 10**_MAX_DIGITS else f"{str(value)[:_MAX_DIGITS]}..."
    return text


def check_rate(value: object, what: str = "rate") -> float:
    """Return ``value`` as ticks per second if it is a number from MIN_RATE_HZ to
    MAX_RATE_HZ, else raise a one-line error naming it."""
    try:
        rate = (
            float(value)
            if isinstance(value, int | float | str) and not isinstance(value, bool)
            else math.nan
        )
    except (ValueError, OverflowError):
        rate = math.nan
    if not (math.isfinite(rate) and MIN_RATE_HZ <= rate <= MAX_RATE_HZ):
        msg = (
            f"{what} {shown(value)} must be a positive number of ticks per second, from "
            f"{MIN_RATE_HZ:g} to {MAX_RATE_HZ:g}"
        )
        raise InvalidInputError(msg)
    return rate


def _too_long(text: str, what: str) -> None:
    if len(text) > _MAX_DIGITS + 10:
        msg = f"invalid {what} {text[:30]!r}...: too long to be a {what}"
        raise InvalidInputError(msg)


def _duration_ns(text: str) -> int | None:
    """The nanoseconds of ``5s``, ``300ms`` or bare integer text (exact); None if neither."""
    _too_long(text, "duration")
    match = _DURATION.match(text)
    if match:
        number, unit = match.groups()
        return round(Fraction(number) * _UNITS[unit])
    stripped = text.strip()
    return int(stripped) if re.fullmatch(r"[-+]?\d+", stripped) else None


def parse_duration(text: str | int | float) -> int:
    """Parse a duration such as ``5s``, ``300ms`` or a bare integer of nanoseconds.

    Its magnitude is at most 2^63-1 ns (about 292 years); fractions are exact.
    """
    if isinstance(text, bool) or not isinstance(text, str | int | float):
        msg = f"invalid duration {text!r}: give nanoseconds or a number with a unit (5s, 300ms)"
        raise InvalidInputError(msg)
    if isinstance(text, float):
        msg = f"invalid duration {text!r}: floats are ambiguous, write '{text}s' or nanoseconds"
        raise InvalidInputError(msg)
    value = text if isinstance(text, int) else _duration_ns(text)
    if value is None:
        msg = (
            f"invalid duration {text!r}: give nanoseconds or a number with a unit (5s, 300ms, 2min)"
        )
        raise InvalidInputError(msg)
    if abs(value) > MAX_NS:
        msg = f"duration {text!r} is out of range: at most 2^63-1 ns (about 292 years)"
        raise InvalidInputError(msg)
    return value


def parse_time(text: str | int, *, start_ns: int | None = None) -> int:
    """Parse a point in time into nanoseconds since the epoch.

    Integers are nanoseconds; ``now`` is the wall clock; ISO 8601 dates are taken as UTC unless
    they carry an offset; a duration (``12.5s``, ``+3m``) is that long after ``start_ns`` (the
    data's start; None: the epoch); a negative one (``-5m``) is that long before now. The
    result must lie in 0 .. 2^63-1 ns (the database's range), else a one-line error names it.
    """
    if isinstance(text, int) and not isinstance(text, bool):
        return check_ns(text)
    if not isinstance(text, str):
        msg = f"invalid time {text!r}: give nanoseconds, an ISO date or a duration such as 12.5s"
        raise InvalidInputError(msg)
    _too_long(text, "time")
    stripped = text.strip()
    if stripped.lower() == "now":
        return now_ns()
    if re.fullmatch(r"[-+]?\d+", stripped):
        return check_ns(int(stripped), f"time {stripped!r} =")
    if _DURATION.match(stripped):
        offset = _duration_ns(stripped) or 0
        if stripped.startswith("-"):
            return check_ns(now_ns() + offset, f"time {stripped!r} =")  # before now
        return check_ns((start_ns or 0) + offset, f"time {stripped!r} =")
    return check_ns(_parse_iso(stripped), f"time {stripped!r} =")


def counts_from_start(text: str) -> bool:
    """Whether :func:`parse_time` reads ``text`` from the data's start (a positive duration
    such as ``12.5s``): only then does a caller need to know that start."""
    stripped = text.strip()
    return bool(_DURATION.match(stripped)) and not stripped.startswith("-")


def _parse_iso(text: str) -> int:
    frac_ns = 0
    body = text.replace("z", "Z")
    match = re.match(r"^(.*?T?\d{2}:\d{2}:\d{2})\.(\d{1,9})(.*)$", body)
    if match:
        head, digits, tail = match.groups()
        frac_ns = int(digits.ljust(9, "0"))
        body = head + tail
    body = body.replace("Z", "+00:00")
    try:
        moment = datetime.fromisoformat(body)
    except ValueError:
        msg = (
            f"invalid time {text!r}: give nanoseconds, 'now', an ISO date "
            "(2026-11-22T12:03:00Z) or a duration such as 12.5s"
        )
        raise InvalidInputError(msg) from None
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=UTC)
    epoch = datetime(1970, 1, 1, tzinfo=UTC)
    return (moment - epoch) // _SECOND * NS_PER_S + frac_ns


def format_ns(value: int | None) -> str:
    """Show a time readably: ISO 8601 UTC with as many fractional digits as it needs."""
    if value is None:
        return ""
    seconds, frac = divmod(value, NS_PER_S)
    try:
        stamp = datetime.fromtimestamp(seconds, tz=UTC).strftime("%Y-%m-%d %H:%M:%S")
    except (OverflowError, OSError, ValueError):  # outside datetime's years 1..9999
        return f"{value} ns"
    if frac:
        digits = f"{frac:09d}".rstrip("0")
        width = 3 if len(digits) <= 3 else 6 if len(digits) <= 6 else 9
        stamp += "." + digits.ljust(width, "0")
    return stamp + "Z"


def format_elapsed(value: int) -> str:
    """A signed duration in seconds, to the ms (or finer when it needs): ``+12.500 s``."""
    sign = "-" if value < 0 else "+"
    seconds, frac = divmod(abs(value), NS_PER_S)
    digits = f"{frac:09d}".rstrip("0")
    width = 3 if len(digits) <= 3 else 6 if len(digits) <= 6 else 9
    return f"{sign}{seconds}.{digits.ljust(width, '0')} s"


#: How times are shown: ``elapsed`` seconds since the data's start, ``date`` (UTC), or
#: ``auto`` (elapsed for data starting near the epoch, dates otherwise).
TIME_STYLES = ("auto", "elapsed", "date")
#: Data starting before this (1971-01-01) is simulated time: shown as elapsed seconds.
NEAR_EPOCH_NS = 365 * 86_400 * NS_PER_S


def start_from_first(first_ns: int) -> int:
    """The start of data whose first time is ``first_ns`` when nothing recorded one: the
    epoch for simulated time (before 1971, what typed durations count from), else itself."""
    return 0 if first_ns < NEAR_EPOCH_NS else first_ns


@dataclass(frozen=True)
class TimeFrame:
    """When a database's data starts, and how its times are shown and read.

    ``start_ns`` is the data's start (None: unknown, taken as the epoch); ``style`` one of
    :data:`TIME_STYLES`.
    """

    start_ns: int | None
    style: str = "auto"

    def __post_init__(self) -> None:
        if self.style not in TIME_STYLES:
            msg = f"invalid time style {self.style!r}: use one of {', '.join(TIME_STYLES)}"
            raise InvalidInputError(msg)

    @property
    def origin_ns(self) -> int:
        """What elapsed times count from: the data's start, else the epoch."""
        return self.start_ns or 0

    @property
    def elapsed(self) -> bool:
        """Times are shown as seconds since the start (auto: when the data starts before
        1971, i.e. simulated time; a real date otherwise)."""
        if self.style != "auto":
            return self.style == "elapsed"
        return self.start_ns is not None and self.start_ns < NEAR_EPOCH_NS

    def show(self, ns: int | None) -> str:
        """``+12.500 s`` since the start, or ``2026-11-22 12:03:00.500Z``; None gives ''."""
        if ns is None:
            return ""
        return format_elapsed(ns - self.origin_ns) if self.elapsed else format_ns(ns)

    def offset_s(self, ns: int) -> float:
        """Seconds since the start (a plot's axis value)."""
        return (ns - self.origin_ns) / NS_PER_S

    def axis_label(self) -> str:
        """The label of a time axis whose values are :meth:`offset_s`."""
        return "seconds since the data's start" if self.elapsed else "time (UTC)"

    def parse(self, text: str) -> int:
        """:func:`parse_time` with durations counted from this start."""
        return parse_time(text, start_ns=self.start_ns)
