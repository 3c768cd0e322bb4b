"""Geometry producers (area_manager, agent_monitor, pdg facts) and the runner that ticks them."""

from toaster.producers.areas import AreaManager, multiple_relative_position, relative_position
from toaster.producers.diff import SnapshotDiff
from toaster.producers.monitor import AgentMonitor, pointing
from toaster.producers.perception import HandActors, PerceptionFacts
from toaster.producers.runner import Runner, Session, Stats, load_session
from toaster.world.areaspec import area_from_original, normalize_area
from toaster.world.config import DEFAULTS, make_config

__all__ = ["DEFAULTS", "AgentMonitor", "AreaManager", "HandActors", "PerceptionFacts", "Runner",
           "Session", "SnapshotDiff", "Stats", "area_from_original", "load_session", "make_config",
           "multiple_relative_position", "normalize_area", "pointing", "relative_position"]
