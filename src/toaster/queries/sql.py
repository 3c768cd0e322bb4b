"""Raw SQL for users (the original's execute SQL), read-only unless asked, and ARE_IN_TABLE."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager
from typing import TYPE_CHECKING, Any, NamedTuple

from sqlalchemy import text

from toaster.db import readonly
from toaster.errors import InvalidInputError, ToasterError
from toaster.model import Fact, check_list, shown

if TYPE_CHECKING:
    from toaster.db.database import Database


class SQLResult(NamedTuple):
    """Column names and rows of a statement (``rowcount`` for writes); ``truncated`` when a
    read-only statement had more than ``max_rows`` rows (the first ``max_rows`` are kept)."""

    columns: list[str]
    rows: list[tuple[Any, ...]]
    rowcount: int
    truncated: bool = False


def execute(
    db: Database,
    sql: str,
    params: dict[str, Any] | list[Any] | None = None,
    *,
    write: bool = False,
    max_rows: int = readonly.DEFAULT_MAX_ROWS,
    max_bytes: int = readonly.DEFAULT_MAX_BYTES,
    timeout_s: float = readonly.DEFAULT_TIMEOUT_S,
) -> SQLResult:
    """Run one SQL statement, read-only unless ``write`` (docs/execute.md).

    Read-only: exactly one SELECT, WITH, VALUES, TABLE, EXPLAIN or SHOW (PRAGMA on SQLite)
    statement that cannot write, end its transaction, switch roles or act on the server
    (:mod:`toaster.db.readonly`); at most ``max_rows`` rows (more: ``truncated``), an error
    past ``max_bytes`` bytes of values or ``timeout_s`` seconds. Refusals are
    :class:`~toaster.errors.ReadOnlyError`.

    ``write``: any SQL, as the connecting role, without these bounds; it bumps the cache
    epoch, so that every store (this process's included) re-reads what its sources hold
    before its next write.

    Parameters use the driver's style (``?`` on SQLite, ``%s`` on PostgreSQL; or ``:name``
    with a dict on both).
    """
    if not write:
        with execute_stream(
            db, sql, params, max_rows=max_rows, max_bytes=max_bytes, timeout_s=timeout_s
        ) as stream:
            rows = list(stream)
        return SQLResult(stream.columns, rows, len(rows), stream.truncated)
    named = params if isinstance(params, dict) else None  # ``:name`` style, both backends
    try:
        with db.transaction(write=True) as conn:
            cur = db.cursor()
            if named is not None:
                result = conn.execute(text(sql), named)
                columns = list(result.keys()) if result.returns_rows else []
                rows = [tuple(r) for r in result] if result.returns_rows else []
                count = result.rowcount
            else:
                if params:
                    cur.execute(sql, params)
                else:  # no parameters: neither driver looks for placeholders
                    cur.execute(sql)
                columns = [d[0] for d in cur.description] if cur.description else []
                rows = [tuple(r) for r in cur.fetchall()] if cur.description else []
                count = cur.rowcount
            conn.execute(text("UPDATE store_state SET cache_epoch = cache_epoch + 1 WHERE id = 1"))
    except ToasterError:
        raise
    except Exception as exc:
        msg = f"SQL error: {_one_line(exc)}"
        raise ToasterError(msg) from None
    return SQLResult(columns, rows, count)


@contextmanager
def execute_stream(
    db: Database,
    sql: str,
    params: dict[str, Any] | list[Any] | None = None,
    *,
    max_rows: int = readonly.DEFAULT_MAX_ROWS,
    max_bytes: int = readonly.DEFAULT_MAX_BYTES,
    timeout_s: float = readonly.DEFAULT_TIMEOUT_S,
) -> Iterator[readonly.ReadRows]:
    """Run one read-only statement as :func:`execute` does, and give its rows as they are
    fetched: ``columns``, then the rows, ``truncated`` once they are read. Every bound is
    checked before the first row (a refused statement gives none); the caller holds one
    batch of rows at a time, so memory does not grow with the result.

    >>> with q.execute_stream(db, "SELECT * FROM events") as rows:  # doctest: +SKIP
    ...     for row in rows:
    ...         print(*row)
    """
    bounds = readonly.limits(max_rows, max_bytes, timeout_s)
    read = readonly.read_postgresql if db.dialect_name == "postgresql" else readonly.read_sqlite
    with read(db, sql, params, bounds) as rows:
        yield rows


def _one_line(exc: Exception) -> str:
    inner = getattr(exc, "orig", None) or exc
    lines = str(inner).strip().splitlines()
    return lines[0] if lines else type(inner).__name__


def are_in_table(db: Database, agent: str, facts: list[Fact]) -> list[bool]:
    """For each fact pattern, is it among ``agent``'s current facts? ``"NULL"`` subject or
    target is a wildcard; property type and value are ignored unless given (non-empty)."""
    from toaster.queries.facts import current_facts

    answers = []
    for fact in check_list(facts, "facts"):
        if not isinstance(fact, Fact):
            msg = f"invalid fact pattern {shown(fact)}: give toaster.Fact(subject, property, ...)"
            raise InvalidInputError(msg)
        filters: dict[str, Any] = {
            "subject": fact.subject_id,
            "property": fact.property,
            "target": fact.target_id or None,
        }
        if fact.target_id == "":
            filters["target"] = ""
        if fact.sub_property:
            filters["sub_property"] = fact.sub_property
        if fact.property_type:
            filters["property_type"] = fact.property_type
        answers.append(bool(current_facts(db, agent, limit=1, **filters)))
    return answers
