"""The bounds of one read-only statement, its result, and the errors both guards share."""

from __future__ import annotations

from collections.abc import Iterable, Iterator
from typing import TYPE_CHECKING, Any, NamedTuple

from toaster.errors import InvalidInputError, ToasterError

if TYPE_CHECKING:
    from sqlalchemy import Connection

DEFAULT_MAX_ROWS = 100_000
DEFAULT_MAX_BYTES = 32 * 2**20
DEFAULT_TIMEOUT_S = 60.0


class Limits(NamedTuple):
    """Bounds of one read-only statement (checked by :func:`limits`)."""

    max_rows: int
    max_bytes: int
    timeout_s: float


class ReadRows:
    """The rows of one read-only statement as they are fetched, each bound already checked
    (no row comes from a statement that is then refused): ``columns``, then at most
    ``max_rows`` rows; ``truncated`` is True once they are read if there were more."""

    def __init__(self, columns: list[str], rows: Iterable[tuple[Any, ...]], max_rows: int) -> None:
        self.columns = columns
        self.truncated = False
        self._rows = rows
        self._max_rows = max_rows

    def __iter__(self) -> Iterator[tuple[Any, ...]]:
        for count, row in enumerate(self._rows):
            if count == self._max_rows:
                self.truncated = True
                return
            yield row


def limits(max_rows: int, max_bytes: int, timeout_s: float) -> Limits:
    """The checked bounds (:class:`~toaster.errors.InvalidInputError` names a bad one)."""
    for name, value, low, high in (
        ("max_rows", max_rows, 1, 2**31 - 2),
        ("max_bytes", max_bytes, 1024, 2**62),
    ):
        if isinstance(value, bool) or not isinstance(value, int) or not low <= value <= high:
            msg = (
                f"{name}={value!r} is not a whole number from {low} to {high}: give e.g. "
                f"{name}=100000"
            )
            raise InvalidInputError(msg)
    if not (isinstance(timeout_s, int | float) and 0 < timeout_s < 1e7):
        msg = f"timeout_s={timeout_s!r} is not a number of seconds > 0: give e.g. timeout_s=60"
        raise InvalidInputError(msg)
    return Limits(max_rows, max_bytes, float(timeout_s))


def timeout_error(bounds: Limits) -> ToasterError:
    """The error of a statement that ran past ``timeout_s``."""
    return ToasterError(
        f"SQL error: the statement ran longer than {bounds.timeout_s:g} s "
        "(read-only SQL's bound): narrow it (WHERE, LIMIT) or raise --timeout"
    )


def too_big_error(bounds: Limits, value: str | None = None) -> ToasterError:
    """The error of a result past ``max_bytes``, or of one ``value`` (what makes it)."""
    if value is not None:
        return ToasterError(
            f"SQL error: {value} is larger than {bounds.max_bytes} bytes "
            "(--max-bytes): make it smaller, or raise --max-bytes"
        )
    return ToasterError(
        f"SQL error: the result is larger than {bounds.max_bytes} bytes "
        "(--max-bytes): select fewer rows or columns, or raise --max-bytes"
    )


def require_own_transaction(conn: Connection) -> None:
    """Refuse to run inside the caller's transaction (the statement's must be rolled back)."""
    if conn.in_transaction():
        msg = (
            "read-only SQL runs in a transaction of its own: call execute() outside "
            "store.transaction() / db.transaction()"
        )
        raise ToasterError(msg)


def first_line(exc: BaseException) -> str:
    """The first line of an exception's message (its type's name when it has none)."""
    return (str(exc).strip().splitlines() or [type(exc).__name__])[0]
