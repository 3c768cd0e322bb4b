"""What a ROS 1 bridge publishes each tick (:class:`TickOutput`, a node output): the fact
lists, and at 1/VIEW_EVERY of the ticks /tf, the markers, the area and entity lists and the
database tables; and the node's status lines. Fact lists and /tf are written as arrays
(:mod:`toaster.ros1.wire`)."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

import numpy as np

from toaster.model import Fact
from toaster.outputs import markers
from toaster.ros1 import messages, wire
from toaster.world.geometry import rpy_to_quats
from toaster.world.state import World

#: /tf, markers, area and entity lists go out every VIEW_EVERY ticks (10 Hz at 30 Hz): they
#: are for eyes and RViz, and at 30 Hz they doubled a tick and the node read its own /tf back
VIEW_EVERY = 3
PDG_LISTS = {
    "human": ("/pdg/humanList", "HumanListStamped", "humanList"),
    "robot": ("/pdg/robotList", "RobotListStamped", "robotList"),
    "object": ("/pdg/objectList", "ObjectListStamped", "objectList"),
}


class TickOutput:
    """Publishes one tick: fact lists, TF, markers, areas and entity lists; and the node's
    status lines (``bridge``: the :class:`~toaster.ros1.bridge.Bridge` whose publishers it
    uses)."""

    def __init__(self, bridge: Any) -> None:
        self.bridge = bridge
        self.ticks = 0
        self.writer = wire.FactListWriter()
        self._sent = -1  # the tick whose fact lists went out (publish_facts)
        self._frames: tuple[World | None, int, wire.Pieces, np.ndarray] = (
            None,
            -1,
            wire.Pieces(),
            np.zeros(0, np.int64),
        )

    def status(self, line: str) -> None:
        from std_msgs.msg import String  # type: ignore[import-not-found]

        self.bridge.status_pub.publish(String(data=line))

    def publish_facts(self, t_ns: int, facts: Mapping[str, list[Fact]], world: World) -> None:
        """The fact lists, as soon as the producers computed them (before the write)."""
        for producer, pub in self.bridge.fact_pubs.items():
            if pub.get_num_connections():  # written as arrays (wire.py), genpy's bytes
                pub.publish(wire.fact_list_message(self.writer, facts, producer, t_ns))
        self._sent = t_ns

    def publish(self, t_ns: int, facts: Mapping[str, list[Fact]], world: World) -> None:
        """The rest of a stored tick (and its fact lists if they have not gone out)."""
        b = self.bridge
        for line in b.warnings.drain():
            b.node.warn(line)
        reg = b.registry
        if self._sent != t_ns:
            self.publish_facts(t_ns, facts, world)
        b.areas_out.answer(t_ns, world)  # print_area's lists, asked from service threads
        self.ticks += 1
        if (self.ticks - 1) % VIEW_EVERY:  # fact lists every tick; views at 1/VIEW_EVERY
            return
        b.tables_out.publish()
        if b.tf_pub is not None:
            b.tf_pub.publish(self._tf(t_ns, world))
        b.areas_out.publish(t_ns, world)
        self._markers(t_ns, facts, world, b.node.areas.areas)
        if any(p.get_num_connections() for p in b.list_pubs.values()):
            lists = markers.entity_list_fields(world, t_ns)
            header = {"frame_id": "/map", "stamp": t_ns}
            for kind, (_, type_name, field) in PDG_LISTS.items():
                b.list_pubs[kind].publish(
                    messages.to_msg(reg.msg(type_name), {"header": header, field: lists[kind]}, reg)
                )

    def _tf(self, t_ns: int, world: World) -> Any:
        """Every live entity's frame (:func:`markers.transforms`), written as arrays."""
        rows = markers.live_rows(world)
        names, piece = self._frame_names(world)
        data = wire.tf_bytes(
            "map", names, piece[rows], world.pos[rows], rpy_to_quats(world.rpy[rows]), t_ns
        )
        return wire.as_message(data)

    def _frame_names(self, world: World) -> tuple[wire.Pieces, np.ndarray]:
        """Every row's TF frame name (:func:`markers.frame_of`), kept until entities
        change."""
        cached, version, names, piece = self._frames
        if cached is not world or version != world.version:
            names = wire.Pieces()
            piece = np.fromiter(
                (names.add(markers.frame_of(world, r)) for r in range(world.n)),
                np.int64,
                world.n,
            )
            self._frames = (world, world.version, names, piece)
        return names, piece

    def _markers(
        self,
        t_ns: int,
        facts: Mapping[str, list[Fact]],
        world: World,
        areas: Mapping[str, Any],
    ) -> None:
        from visualization_msgs.msg import MarkerArray  # type: ignore[import-not-found]

        pubs = self.bridge.marker_pubs
        wanted = {t for t, p in pubs.items() if p.get_num_connections()}
        if not wanted:
            return
        arrays: dict[str, list[dict[str, Any]]] = {}
        if wanted & set(markers.TOPICS.values()):
            arrays |= markers.entity_markers(world, t_ns)
        if markers.AREAS_TOPIC in wanted:
            occupied = {
                f.target_id
                for f in facts.get("area_manager", [])
                if f.property in ("IsInArea", "IsInRoom", "IsAt")
            }
            arrays[markers.AREAS_TOPIC] = markers.area_markers(world, areas, occupied, t_ns)
        if markers.MOTION_TOPIC in wanted:
            arrays[markers.MOTION_TOPIC] = markers.motion_markers(
                world, facts.get("agent_monitor", []), t_ns
            )
        for topic in wanted:
            pubs[topic].publish(messages.to_msg(MarkerArray, {"markers": arrays[topic]}))
