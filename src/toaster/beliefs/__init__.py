"""Perspective taking: every non-self agent's beliefs, maintained by rules in the database.

The user-facing names (docs/beliefs.md, "API") load on first use, so that the query layer can
import the rule's SQL (:mod:`toaster.rules.sqltext`) without loading this API, which reads
through it. ``toaster.beliefs.tell`` is the module; its function is :func:`toaster.tell`.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from toaster._lazy import exports as _exports

if TYPE_CHECKING:  # what the lazy names below are, for type checkers
    from toaster.beliefs.api import BeliefDiff as BeliefDiff
    from toaster.beliefs.api import belief_history as belief_history
    from toaster.beliefs.api import belief_value as belief_value
    from toaster.beliefs.api import beliefs as beliefs
    from toaster.beliefs.api import configure as configure
    from toaster.beliefs.api import false_beliefs as false_beliefs
    from toaster.beliefs.api import holders as holders
    from toaster.beliefs.api import reset as reset
    from toaster.beliefs.api import self_agent as self_agent
    from toaster.beliefs.scenario import Scenario as Scenario
    from toaster.beliefs.scenario import replay as replay
    from toaster.beliefs.scenario import replay_and_check as replay_and_check

_API, _SCENARIO = "toaster.beliefs.api", "toaster.beliefs.scenario"
_HOMES = {
    "beliefs": _API,
    "belief_value": _API,
    "false_beliefs": _API,
    "belief_history": _API,
    "holders": _API,
    "self_agent": _API,
    "configure": _API,
    "reset": _API,
    "BeliefDiff": _API,
    "Scenario": _SCENARIO,
    "replay": _SCENARIO,
    "replay_and_check": _SCENARIO,
}
__all__ = sorted(_HOMES)

if not TYPE_CHECKING:  # hidden from type checkers, so that a misspelt name stays an error
    __getattr__, __dir__ = _exports(__name__, _HOMES)
