"""toaster: situation assessment for human-robot interaction over a temporal SQL fact store.

Names are imported lazily so that ``toaster --help`` does not pay for SQLAlchemy or numpy.
"""

from __future__ import annotations

from importlib import import_module
from typing import Any

__version__ = "0.1.0"

_EXPORTS = {
    "connect": "toaster.db", "Database": "toaster.db", "Store": "toaster.db",
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
