"""toaster: situation assessment for human-robot interaction over a temporal SQL fact store.

``toaster.connect(url)`` opens a database; the rest reads and writes through it. Names load on
first use (:mod:`toaster._lazy`): ``import toaster`` imports neither SQLAlchemy nor numpy.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from toaster._lazy import exports as _exports

if TYPE_CHECKING:  # what the lazy names below are, for type checkers
    from toaster import beliefs as beliefs
    from toaster import errors as errors
    from toaster import queries as queries
    from toaster.app.session import connect as connect
    from toaster.beliefs.api import BeliefDiff as BeliefDiff
    from toaster.beliefs.api import belief_history as belief_history
    from toaster.beliefs.api import belief_value as belief_value
    from toaster.beliefs.api import false_beliefs as false_beliefs
    from toaster.beliefs.tell import tell as tell
    from toaster.db import Database as Database
    from toaster.db import Store as Store
    from toaster.errors import ToasterError as ToasterError
    from toaster.model import Agent as Agent
    from toaster.model import Entity as Entity
    from toaster.model import EventRow as EventRow
    from toaster.model import Fact as Fact
    from toaster.model import FactRow as FactRow
    from toaster.model import OntologyRow as OntologyRow
    from toaster.model import PropertyRow as PropertyRow

__version__ = "0.1.0"

_HOMES = {
    "connect": "toaster.app.session",
    "Database": "toaster.db",
    "Store": "toaster.db",
    "Fact": "toaster.model",
    "FactRow": "toaster.model",
    "EventRow": "toaster.model",
    "Entity": "toaster.model",
    "Agent": "toaster.model",
    "OntologyRow": "toaster.model",
    "PropertyRow": "toaster.model",
    "ToasterError": "toaster.errors",
    "errors": "toaster.errors",
    "queries": "toaster.queries",
    "beliefs": "toaster.beliefs",
    "false_beliefs": "toaster.beliefs.api",
    "belief_value": "toaster.beliefs.api",
    "belief_history": "toaster.beliefs.api",
    "BeliefDiff": "toaster.beliefs.api",
    "tell": "toaster.beliefs.tell",
}
__all__ = sorted(_HOMES)

if not TYPE_CHECKING:  # hidden from type checkers, so that a misspelt name stays an error
    __getattr__, __dir__ = _exports(__name__, _HOMES)
