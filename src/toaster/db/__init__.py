"""The temporal fact store: schema, migrations and the write path.

It imports nothing from the layers above it (beliefs, queries, the command line, the live
node, the world): :func:`toaster.connect` (:mod:`toaster.app.session`) gives its store the rules.
Its names load on first use (SQLAlchemy and Alembic are not imported by ``toaster --help``).
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from toaster._lazy import exports as _exports

if TYPE_CHECKING:
    from toaster.db.database import Database, open_database
    from toaster.db.writer.changes import ChangeSet, Rule, SyncResult
    from toaster.db.writer.store import RuleFactory, Store

_HOMES = {
    "Database": "toaster.db.database",
    "open_database": "toaster.db.database",
    "ChangeSet": "toaster.db.writer.changes",
    "Rule": "toaster.db.writer.changes",
    "RuleFactory": "toaster.db.writer.store",
    "Store": "toaster.db.writer.store",
    "SyncResult": "toaster.db.writer.changes",
}

__all__ = ["ChangeSet", "Database", "Rule", "RuleFactory", "Store", "SyncResult", "open_database"]

if not TYPE_CHECKING:  # hidden from type checkers, so that a misspelt name stays an error
    __getattr__, __dir__ = _exports(__name__, _HOMES)
