"""The composition root: :func:`connect` opens a database whose store runs the belief rule.

The database layer (:mod:`toaster.db`) knows no rule; this module is the one place that wires
the rules in. Every application path (the library's :func:`toaster.connect`, the command line,
the live node, ROS, benchmarks and tests) opens its database here, so that every writer keeps
the other agents' beliefs up to date.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from toaster.db.database import Database, open_database

if TYPE_CHECKING:
    from toaster.db.writer.changes import Rule
    from toaster.db.writer.store import RuleFactory, Store


def belief_rule(store: Store) -> Rule:
    """The belief rule for ``store`` (imported on first use: ``toaster --help`` stays fast)."""
    from toaster.rules.hook import BeliefRule

    return BeliefRule(store)


#: The rules every store opened by :func:`connect` runs, in order.
RULES: tuple[RuleFactory, ...] = (belief_rule,)


def connect(url: str | None = None, *, create: bool = True, check: bool = True) -> Database:
    """Open a toaster database; its :meth:`~toaster.db.Database.store` runs the belief rule.

    Args:
        url: ``sqlite:///file.db``, ``postgresql://host/db`` or a path ending in ``.db``;
            default ``$TOASTER_DB`` or ``sqlite:///toaster.db``.
        create: migrate a database that has no table yet (a new file or database) to head.
        check: raise :class:`~toaster.errors.SchemaOutdatedError` when an existing database is
            not at the code's revision (the message says to run ``toaster db upgrade``).
    """
    return open_database(url, create=create, check=check, rules=RULES)
