"""toaster: situation assessment for human-robot interaction over a temporal SQL fact store."""

from toaster.db import Database, Store, connect
from toaster.model import Agent, Entity, EventRow, Fact, FactRow, OntologyRow, PropertyRow

__all__ = [
    "Agent",
    "Database",
    "Entity",
    "EventRow",
    "Fact",
    "FactRow",
    "OntologyRow",
    "PropertyRow",
    "Store",
    "connect",
]
__version__ = "0.1.0"
