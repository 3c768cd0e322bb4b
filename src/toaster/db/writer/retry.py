"""Conflicts with concurrent writers: which errors a new attempt resolves, and how often.

The store (:meth:`~toaster.db.writer.base.WriterBase.retried`) rolls a conflicting write back
and runs it again with fresh caches.
"""

from __future__ import annotations

from sqlalchemy.exc import IntegrityError


class StaleCache(Exception):
    """Another writer opened an interval concurrently: forget what is remembered and retry."""


#: Attempts of a write that conflicts with concurrent writers (see WriterBase._retrying).
ATTEMPTS = 8
#: SQLSTATEs of conflicts that a new attempt resolves: serialization failure, deadlock,
#: unique violation (a key another writer inserted meanwhile).
_CONFLICTS = {"40001", "40P01", "23505"}


def is_conflict(exc: BaseException) -> bool:
    if isinstance(exc, StaleCache):
        return True
    orig = getattr(exc, "orig", exc)
    return getattr(orig, "sqlstate", None) in _CONFLICTS


def one_line(exc: BaseException) -> str:
    inner = getattr(exc, "orig", None) or exc
    lines = str(inner).strip().splitlines()
    return lines[0] if lines else type(inner).__name__


def is_integrity_error(exc: Exception) -> bool:
    if isinstance(exc, IntegrityError):
        return True
    name = type(exc).__name__
    return name in {"IntegrityError", "UniqueViolation"}


def on_facts(exc: BaseException) -> bool:
    """True for an integrity error that PostgreSQL reports on ``facts`` (an open interval
    another writer made meanwhile, or a key removed meanwhile)."""
    if not isinstance(exc, Exception) or not is_integrity_error(exc):
        return False
    return getattr(getattr(exc, "diag", None), "table_name", None) == "facts"
