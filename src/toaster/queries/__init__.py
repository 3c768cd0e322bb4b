"""The read path: plain rows out of the temporal fact store.

>>> import toaster, toaster.queries as q                      # doctest: +SKIP
>>> db = toaster.connect("sqlite:///toaster.db")               # doctest: +SKIP
>>> q.fact_value(db, "PR2_ROBOT", "MUG", "IsOn", "TABLE", at=t)  # doctest: +SKIP
"""

from toaster.model import NumberedInterval
from toaster.queries.catalog import agents, descendants, entities, ontology, properties
from toaster.queries.events import events
from toaster.queries.facts import (
    SignalPoint,
    beliefs_at,
    current_facts,
    fact_value,
    history,
    memory,
    numbered_history,
    signal,
)
from toaster.queries.frames import to_dataframe
from toaster.queries.sql import SQLResult, are_in_table, execute, execute_stream
from toaster.queries.watch import watch

__all__ = [
    "NumberedInterval",
    "SQLResult",
    "SignalPoint",
    "agents",
    "are_in_table",
    "beliefs_at",
    "current_facts",
    "descendants",
    "entities",
    "events",
    "execute",
    "execute_stream",
    "fact_value",
    "history",
    "memory",
    "numbered_history",
    "ontology",
    "properties",
    "signal",
    "to_dataframe",
    "watch",
]
