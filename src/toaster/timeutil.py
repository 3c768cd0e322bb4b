"""Time in toaster is integer nanoseconds since the Unix epoch (UTC), everywhere.

`parse_time` accepts what a user types (``1700000000000000000``, ``12.5s``, ``250ms``,
``2026-11-22T12:03:00Z``, ``now``) and `format_ns` shows a stored time readably.
"""

from __future__ import annotations

import re
import time
from datetime import UTC, datetime

from toaster.errors import InvalidInputError

NS_PER_S = 1_000_000_000
_UNITS = {"ns": 1, "us": 1_000, "µs": 1_000, "ms": 1_000_000, "s": NS_PER_S,
          "min": 60 * NS_PER_S, "h": 3600 * NS_PER_S}
_DURATION = re.compile(r"^\s*([-+]?\d+(?:\.\d*)?|[-+]?\.\d+)\s*(ns|us|µs|ms|s|min|h)\s*$")


def now_ns() -> int:
    """The wall clock, in nanoseconds since the epoch."""
    return time.time_ns()


def parse_duration(text: str | int | float) -> int:
    """Parse a duration such as ``5s``, ``300ms`` or a bare integer of nanoseconds."""
    if isinstance(text, bool):
        msg = f"invalid duration {text!r}: give nanoseconds or a number with a unit (5s, 300ms)"
        raise InvalidInputError(msg)
    if isinstance(text, int):
        return text
    if isinstance(text, float):
        msg = f"invalid duration {text!r}: floats are ambiguous, write '{text}s' or nanoseconds"
        raise InvalidInputError(msg)
    match = _DURATION.match(text)
    if match:
        number, unit = match.groups()
        return round(float(number) * _UNITS[unit]) if "." in number else int(number) * _UNITS[unit]
    stripped = text.strip()
    if re.fullmatch(r"[-+]?\d+", stripped):
        return int(stripped)
    msg = f"invalid duration {text!r}: give nanoseconds or a number with a unit (5s, 300ms, 2min)"
    raise InvalidInputError(msg)


def parse_time(text: str | int, *, base_ns: int = 0) -> int:
    """Parse a point in time into nanoseconds since the epoch.

    Integers are nanoseconds; ``now`` is the wall clock; ISO 8601 dates are taken as UTC unless
    they carry an offset; a duration (``12.5s``) is relative to ``base_ns``.
    """
    if isinstance(text, int) and not isinstance(text, bool):
        return text
    if not isinstance(text, str):
        msg = f"invalid time {text!r}: give nanoseconds, an ISO date or a duration such as 12.5s"
        raise InvalidInputError(msg)
    stripped = text.strip()
    if stripped.lower() == "now":
        return now_ns()
    if re.fullmatch(r"[-+]?\d+", stripped):
        return int(stripped)
    if _DURATION.match(stripped):
        return base_ns + parse_duration(stripped)
    return _parse_iso(stripped)


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
        msg = (f"invalid time {text!r}: give nanoseconds, 'now', an ISO date "
               "(2026-11-22T12:03:00Z) or a duration such as 12.5s")
        raise InvalidInputError(msg) from None
    if moment.tzinfo is None:
        moment = moment.replace(tzinfo=UTC)
    return int(moment.timestamp()) * NS_PER_S + frac_ns


def format_ns(value: int | None) -> str:
    """Show a time readably: ISO 8601 UTC with as many fractional digits as it needs."""
    if value is None:
        return ""
    seconds, frac = divmod(value, NS_PER_S)
    stamp = datetime.fromtimestamp(seconds, tz=UTC).strftime("%Y-%m-%d %H:%M:%S")
    if frac:
        digits = f"{frac:09d}".rstrip("0")
        width = 3 if len(digits) <= 3 else 6 if len(digits) <= 6 else 9
        stamp += "." + digits.ljust(width, "0")
    return stamp + "Z"
