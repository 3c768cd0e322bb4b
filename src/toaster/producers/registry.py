"""The one list of built-in producers: runs (:func:`~toaster.producers.runner.load_session`),
the live node, the ROS bridge's ``/<name>/factList`` topics and recordings all read it.

A new producer is a module of its own plus one row of :data:`BUILTINS` (its name is the
producer's ``name``, the topic it publishes on). The factories import their module when called,
so this module imports no producer (the runner imports it, and :class:`Producer`, without a
circle).
"""

from __future__ import annotations

from collections.abc import Callable, Mapping
from typing import TYPE_CHECKING, Any, Literal, NamedTuple, Protocol

if TYPE_CHECKING:
    from toaster.model import Fact
    from toaster.world.state import World

#: Area specs by id, as :func:`toaster.world.areaspec.normalize_area` checks them.
Areas = Mapping[str, Mapping[str, Any]]


class Producer(Protocol):
    """What the runner needs from a producer."""

    name: str

    def compute(self, world: World, t_ns: int) -> list[Fact]: ...


class Builtin(NamedTuple):
    """A built-in producer: its name, how to build it from thresholds and areas, and when a
    run wants it (``always``; ``spatial``: when the input asks for the spatial facts;
    ``live``: in a live node, ``toaster serve``)."""

    name: str
    factory: Callable[[Mapping[str, Any], Areas], Producer]
    wanted: Literal["always", "spatial", "live"]


def _pdg(config: Mapping[str, Any], areas: Areas) -> Producer:
    from toaster.producers.perception import PerceptionFacts

    return PerceptionFacts(config)


def _area_manager(config: Mapping[str, Any], areas: Areas) -> Producer:
    from toaster.producers.areas import AreaManager

    return AreaManager(areas, config)


def _agent_monitor(config: Mapping[str, Any], areas: Areas) -> Producer:
    from toaster.producers.monitor import AgentMonitor

    return AgentMonitor(config)


def _move3d_facts(config: Mapping[str, Any], areas: Areas) -> Producer:
    from toaster.producers.spatial import SpatialFacts

    return SpatialFacts(config)


def _pdg_seen(config: Mapping[str, Any], areas: Areas) -> Producer:
    from toaster.producers.seen import SeenFacts

    return SeenFacts(config)


#: In the order a tick computes them.
BUILTINS: tuple[Builtin, ...] = (
    Builtin("pdg", _pdg, "always"),
    Builtin("area_manager", _area_manager, "always"),
    Builtin("agent_monitor", _agent_monitor, "always"),
    Builtin("move3d_facts", _move3d_facts, "spatial"),
    Builtin("pdg_seen", _pdg_seen, "live"),
)
#: The producers' names, each a ``/<name>/factList`` topic of the bridge and of recordings.
NAMES: tuple[str, ...] = tuple(b.name for b in BUILTINS)


def builtin_producers(
    config: Mapping[str, Any], areas: Areas, *, spatial: bool, live: bool = False
) -> list[Producer]:
    """The built-in producers a run wants, built in :data:`BUILTINS` order; ``spatial`` adds
    those wanted only for the spatial facts, ``live`` those of a live node."""
    wanted = {"always"} | ({"spatial"} if spatial else set()) | ({"live"} if live else set())
    return [b.factory(config, areas) for b in BUILTINS if b.wanted in wanted]
