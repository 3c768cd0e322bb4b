"""What a live node publishes to: :class:`Output` (the ROS bridge's topics, a test's list)."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import TYPE_CHECKING, Any, Protocol

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


def publish_to(
    outputs: Sequence[Any],
    method: str,
    t_ns: int,
    facts: Mapping[str, list[Fact]],
    world: World,
    faults: Any,
) -> None:
    """Every output's ``method`` (``publish_facts`` or ``publish``; those that have it), for
    a live node and for a run that publishes (:mod:`toaster.app.published`). An output
    failing does not stop the others: ``faults`` (:class:`toaster.node.faults.Faults`) warns
    once, and again when it works."""
    for output in outputs:
        publish = getattr(output, method, None)
        if publish is None:
            continue
        name = f"output {type(output).__name__}"
        try:
            publish(t_ns, facts, world)
        except Exception as exc:  # an output failing must not stop the node
            faults.part_failed(name, exc, "the others go on")
        else:
            faults.part_worked(name)


__all__ = ["Output", "publish_to"]
