"""The temporal fact store: schema, migrations and the write path."""

from toaster.db.database import Database, connect
from toaster.db.store import ChangeSet, Store, SyncResult

__all__ = ["ChangeSet", "Database", "Store", "SyncResult", "connect"]
