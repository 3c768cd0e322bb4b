"""Raw SQL for users (the original's execute SQL), read-only unless asked, and ARE_IN_TABLE."""

from __future__ import annotations

from typing import Any, NamedTuple

from sqlalchemy import text

from toaster.errors import ReadOnlyError, ToasterError
from toaster.model import Fact

_READ_ONLY_MARKERS = ("readonly database", "read-only transaction", "query_only",
                      "attempt to write a readonly")


class SQLResult(NamedTuple):
    """Column names and rows of a statement (``rowcount`` for writes)."""

    columns: list[str]
    rows: list[tuple[Any, ...]]
    rowcount: int


def execute(db: Any, sql: str, params: dict[str, Any] | list[Any] | None = None, *,
            write: bool = False) -> SQLResult:
    """Run one SQL statement. Read-only unless ``write`` (enforced by the database itself:
    ``PRAGMA query_only`` on SQLite, ``SET TRANSACTION READ ONLY`` on PostgreSQL).

    Parameters use the driver's style (``?`` on SQLite, ``%s`` on PostgreSQL; or ``:name``
    with a dict on both). A write bumps the cache epoch, so that every store (this process's
    included) re-reads what its sources hold before its next write.
    """
    backend = db.backend
    named = params if isinstance(params, dict) else None  # ``:name`` style, both backends
    try:
        with db.transaction(write=write) as conn:
            cur = db.cursor()
            if not write:
                backend.set_read_only(cur)
            try:
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
            finally:
                if not write:
                    backend.clear_read_only(db.cursor())
            if write:
                conn.execute(text(
                    "UPDATE store_state SET cache_epoch = cache_epoch + 1 WHERE id = 1"))
    except ToasterError:
        raise
    except Exception as exc:
        message = _one_line(exc)
        if not write and any(marker in message.lower() for marker in _READ_ONLY_MARKERS):
            msg = (f"statement refused, the database is opened read-only: "
                   f"rerun with --write ({message})")
            raise ReadOnlyError(msg) from None
        msg = f"SQL error: {message}"
        raise ToasterError(msg) from None
    return SQLResult(columns, rows, count)


def _one_line(exc: Exception) -> str:
    inner = getattr(exc, "orig", None) or exc
    lines = str(inner).strip().splitlines()
    return lines[0] if lines else type(inner).__name__


def are_in_table(db: Any, agent: str, facts: list[Fact]) -> list[bool]:
    """For each fact pattern, is it among ``agent``'s current facts? ``"NULL"`` subject or
    target is a wildcard; property type and value are ignored unless given (non-empty)."""
    from toaster.queries.facts import current_facts

    answers = []
    for fact in facts:
        filters: dict[str, Any] = {"subject": fact.subject_id, "property": fact.property,
                                   "target": fact.target_id or None}
        if fact.target_id == "":
            filters["target"] = ""
        if fact.sub_property:
            filters["sub_property"] = fact.sub_property
        if fact.property_type:
            filters["property_type"] = fact.property_type
        answers.append(bool(current_facts(db, agent, limit=1, **filters)))
    return answers
