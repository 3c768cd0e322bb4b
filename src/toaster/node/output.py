"""What a live node publishes to: :class:`Output` (the ROS bridge's topics, a test's list)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import TYPE_CHECKING, Protocol

from toaster.model import Fact

if TYPE_CHECKING:
    from toaster.world.state import World


class Output(Protocol):
    """Something that publishes each tick's facts (ROS topics, a test's list, ...), once the
    tick is stored (while :meth:`LiveNode.run` runs: handed to the writer thread). It may also
    have ``publish_facts(t_ns, facts, world)``, called as soon as the producers computed the
    tick, before it is stored: the ROS bridge sends its fact lists then, so that they do not
    wait for the database (docs/live.md, "Latency")."""

    def publish(self, t_ns: int, facts: Mapping[str, list[Fact]], world: World) -> None: ...


__all__ = ["Output"]
