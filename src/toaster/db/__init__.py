"""The temporal fact store: schema, migrations and the write path.

It imports nothing from the layers above it (beliefs, queries, the command line, the live
node, the world): :func:`toaster.connect` (:mod:`toaster.session`) gives its store the rules.
"""

from toaster.db.database import Database, open_database
from toaster.db.store import ChangeSet, Rule, RuleFactory, Store, SyncResult

__all__ = ["ChangeSet", "Database", "Rule", "RuleFactory", "Store", "SyncResult",
           "open_database"]
