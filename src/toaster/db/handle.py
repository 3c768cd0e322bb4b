"""What the store needs of its database handle, as a Protocol.

:class:`~toaster.db.database.Database` is the one implementation; the store is typed against this
so that it does not import the handle that makes it (``Database.store()``).
"""

from __future__ import annotations

from contextlib import AbstractContextManager
from typing import TYPE_CHECKING, Protocol

if TYPE_CHECKING:
    from sqlalchemy import Connection

    from toaster.db.dialects.base import Backend, Cursor


class Handle(Protocol):
    """A database handle: one long-lived connection, transactions on demand, its backend."""

    backend: Backend

    @property
    def connection(self) -> Connection:
        """The long-lived connection (the one the transactions run on)."""

    def transaction(self, *, write: bool = False) -> AbstractContextManager[Connection]:
        """One transaction; nested calls join the open one. ``write`` takes the write lock
        up front (SQLite)."""

    def cursor(self) -> Cursor:
        """A raw DBAPI cursor on the long-lived connection (inside a transaction)."""

    def maintain(self) -> None:
        """Reclaim what long runs leave behind, outside any transaction."""

    def vacuum_scratch(self) -> bool:
        """Vacuum the session's scratch tables of the belief rule outside any transaction;
        False, doing nothing, inside one."""
