"""Backend-specific SQL lives here, one module per backend, behind one interface.

The store's hot path (key look-up, interval open/close/refresh, event append) is written once per
backend in bulk form: ``executemany`` on SQLite, one statement over ``unnest`` arrays on
PostgreSQL (round trips dominate there). Everything else uses SQLAlchemy Core and is shared.
"""

from __future__ import annotations

from toaster.db.dialects.base import (
    GUARD_MESSAGE,
    GUARDED_TABLES,
    LATEST_CLOCK,
    Backend,
    Key,
    insert_with_conflicts,
)

__all__ = [
    "GUARDED_TABLES",
    "GUARD_MESSAGE",
    "LATEST_CLOCK",
    "Backend",
    "Key",
    "backend_for",
    "insert_with_conflicts",
]


def backend_for(dialect_name: str) -> Backend:
    """The backend implementation for a SQLAlchemy dialect name."""
    if dialect_name == "sqlite":
        from toaster.db.dialects.sqlite import SQLiteBackend

        return SQLiteBackend()
    if dialect_name == "postgresql":
        from toaster.db.dialects.postgresql import PostgreSQLBackend

        return PostgreSQLBackend()
    msg = f"unsupported database backend {dialect_name!r}"
    raise ValueError(msg)
