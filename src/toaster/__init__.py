"""toaster: situation assessment for human-robot interaction over a temporal SQL fact store.

Names are imported lazily so that ``toaster --help`` does not pay for SQLAlchemy or numpy.
"""

from __future__ import annotations

from importlib import import_module
from typing import TYPE_CHECKING, Any

if TYPE_CHECKING:  # what the lazy names below are, for type checkers
    from toaster import errors as errors
    from toaster import queries as queries
    from toaster.db import Database as Database
    from toaster.db import Store as Store
    from toaster.model import Agent as Agent
    from toaster.model import Entity as Entity
    from toaster.model import EventRow as EventRow
    from toaster.model import Fact as Fact
    from toaster.model import FactRow as FactRow
    from toaster.model import OntologyRow as OntologyRow
    from toaster.model import PropertyRow as PropertyRow
    from toaster.session import connect as connect

__version__ = "0.1.0"

_EXPORTS = {
    "connect": "toaster.session", "Database": "toaster.db", "Store": "toaster.db",
    "Fact": "toaster.model", "FactRow": "toaster.model", "EventRow": "toaster.model",
    "Entity": "toaster.model", "Agent": "toaster.model", "OntologyRow": "toaster.model",
    "PropertyRow": "toaster.model", "errors": "toaster.errors", "queries": "toaster.queries",
}
__all__ = sorted(_EXPORTS)


def __getattr__(name: str) -> Any:
    module = _EXPORTS.get(name)
    if module is None:
        msg = f"module 'toaster' has no attribute {name!r}"
        raise AttributeError(msg)
    value = import_module(module)
    return value if module.endswith(name) else getattr(value, name)
