"""The temporal fact store: schema, migrations and the write path.

It imports nothing from the layers above it (beliefs, queries, the command line, the live
node, the world): :func:`toaster.connect` (:mod:`toaster.session`) gives its store the rules.
Its names load on first use (SQLAlchemy and Alembic are not imported by ``toaster --help``).
"""

from __future__ import annotations

import importlib
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:
    from toaster.db.database import Database, open_database
    from toaster.db.store import ChangeSet, Rule, RuleFactory, Store, SyncResult

_HOMES = {"Database": "toaster.db.database", "open_database": "toaster.db.database",
          "ChangeSet": "toaster.db.store", "Rule": "toaster.db.store",
          "RuleFactory": "toaster.db.store", "Store": "toaster.db.store",
          "SyncResult": "toaster.db.store"}

__all__ = ["ChangeSet", "Database", "Rule", "RuleFactory", "Store", "SyncResult",
           "open_database"]


def __getattr__(name: str) -> Any:
    if name in _HOMES:
        return getattr(importlib.import_module(_HOMES[name]), name)
    msg = f"module 'toaster.db' has no attribute {name!r}"
    raise AttributeError(msg)


def __dir__() -> list[str]:
    return sorted([*globals(), *__all__])
