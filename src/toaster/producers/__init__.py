"""Geometry producers (area_manager, agent_monitor, pdg facts) and the runner that ticks them.

Its names load on first use, so that :mod:`toaster.producers.registry` (the producers' names,
read by the ROS bridge and recordings) imports no numpy or shapely.
"""

from __future__ import annotations

from typing import TYPE_CHECKING

from toaster._lazy import exports as _exports

if TYPE_CHECKING:
    from toaster.producers.areas import (
        AreaManager,
        multiple_relative_position,
        relative_position,
    )
    from toaster.producers.diff import SnapshotDiff
    from toaster.producers.monitor import AgentMonitor, pointing
    from toaster.producers.perception import HandActors, PerceptionFacts
    from toaster.producers.runner import Runner, Session, Stats, load_session
    from toaster.world.areaspec import area_from_original, normalize_area
    from toaster.world.config import DEFAULTS, make_config

_HOMES = {
    "AreaManager": "toaster.producers.areas",
    "multiple_relative_position": "toaster.producers.areas",
    "relative_position": "toaster.producers.areas",
    "SnapshotDiff": "toaster.producers.diff",
    "AgentMonitor": "toaster.producers.monitor",
    "pointing": "toaster.producers.monitor",
    "HandActors": "toaster.producers.perception",
    "PerceptionFacts": "toaster.producers.perception",
    "Runner": "toaster.producers.runner",
    "Session": "toaster.producers.runner",
    "Stats": "toaster.producers.runner",
    "load_session": "toaster.producers.runner",
    "area_from_original": "toaster.world.areaspec",
    "normalize_area": "toaster.world.areaspec",
    "DEFAULTS": "toaster.world.config",
    "make_config": "toaster.world.config",
}

__all__ = [
    "DEFAULTS",
    "AgentMonitor",
    "AreaManager",
    "HandActors",
    "PerceptionFacts",
    "Runner",
    "Session",
    "SnapshotDiff",
    "Stats",
    "area_from_original",
    "load_session",
    "make_config",
    "multiple_relative_position",
    "normalize_area",
    "pointing",
    "relative_position",
]

if not TYPE_CHECKING:  # hidden from type checkers, so that a misspelt name stays an error
    __getattr__, __dir__ = _exports(__name__, _HOMES)
