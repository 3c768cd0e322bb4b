"""What the ROS 2 bridge publishes each tick (:class:`Ros2Output`, a node output), as the ROS 1
bridge's :class:`~toaster.ros1.tickout.TickOutput`: the fact lists every tick (as soon as the
producers computed them; written as CDR bytes from the tick's arrays, :mod:`toaster.ros2.cdr`),
and at 1/VIEW_EVERY of the ticks /tf, the markers and the area list; the status line when the
node reports it. Messages are built only for matched readers."""

from __future__ import annotations

from collections.abc import Mapping
from typing import Any

from toaster.model import Fact
from toaster.outputs import markers
from toaster.producers.registry import NAMES as PRODUCERS
from toaster.ros1.dbcalls import AREA_KEY, AREA_SCOPE
from toaster.ros1.published import AreaOut
from toaster.ros1.tickout import VIEW_EVERY
from toaster.ros2.cdr import FactListCdr
from toaster.world.rosmsg import area_fields, strip_frame
from toaster.world.state import World

FACT_LIST = "toaster_msgs/msg/FactList"
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
TF_MESSAGE = "tf2_msgs/msg/TFMessage"
AREA_LIST = "toaster_msgs/msg/AreaList"
AREA_TOPIC = "/area_manager/areaList"


class Ros2Output:
    """Publishes one tick on the bridge's DDS writers."""

    def __init__(self, bridge: Any, *, publish_tf: bool = True, draw: bool = True) -> None:
        from toaster.ros1.bridge import STATUS_TOPIC

        self.bridge = bridge
        dds = self.dds = bridge.dds
        self.types = bridge.types
        self.ticks = 0
        self.writer = FactListCdr()
        self._sent = -1
        self.status_pub = dds.writer(STATUS_TOPIC, "std_msgs/msg/String", "latched", 1)
        self.fact_pubs = {p: dds.writer(f"/{p}/factList", FACT_LIST) for p in PRODUCERS}
        self.tf_pub = dds.writer("/tf", TF_MESSAGE, depth=100) if publish_tf else None
        self.marker_pubs = (
            {t: dds.writer(t, MARKER_ARRAY) for t in markers.MARKER_TOPICS} if draw else {}
        )
        self.area_pub = dds.writer(AREA_TOPIC, AREA_LIST, "latched", 1)
        self.areas_out = AreaOut(bridge.node, None, self.area_pub, self.area_numbers)
        self._area_numbers: tuple[frozenset[str], dict[str, int]] = (frozenset(), {})
        self._last_areas: Any = None

    def status(self, line: str) -> None:
        self.status_pub.write(self.types.build("std_msgs/msg/String", {"data": line}))

    def publish_facts(self, t_ns: int, facts: Mapping[str, list[Fact]], world: World) -> None:
        """The fact lists, as soon as the producers computed them (before the write)."""
        raw = getattr(facts, "raw", None)  # a tick's batches (TickFacts), not Fact tuples
        for producer, pub in self.fact_pubs.items():
            if self.dds.listened(pub):
                found = raw(producer) if raw is not None else facts.get(producer, None)
                self.dds.write_raw(pub, self.writer.write(found or [], t_ns))
        self._sent = t_ns

    def publish(self, t_ns: int, facts: Mapping[str, list[Fact]], world: World) -> None:
        """The rest of a stored tick (and its fact lists if they have not gone out)."""
        b = self.bridge
        for line in b.warnings.drain():
            b.node.warn(line)
        if self._sent != t_ns:
            self.publish_facts(t_ns, facts, world)
        self.areas_out.answer(t_ns, world)
        self.ticks += 1
        if (self.ticks - 1) % VIEW_EVERY:
            return
        if self.tf_pub is not None and self.dds.listened(self.tf_pub):
            self.tf_pub.write(self.types.build(TF_MESSAGE, _transforms(world, t_ns)))
        self._areas(t_ns, world)
        self._markers(t_ns, facts, world)

    def _areas(self, t_ns: int, world: World) -> None:
        """The area list while someone listens (transient local: sent again only when it
        changed, and to a reader that comes later at the next view tick)."""
        if not self.areas_out.on or not self.dds.listened(self.area_pub):
            self._last_areas = None
            return
        areas = self.bridge.node.areas.areas
        lists = self.areas_out.lists.lists(world, t_ns)
        numbers = self.area_numbers(frozenset(areas))
        fields = []
        for name, spec in sorted(areas.items()):
            found = lists.get(name)
            area = area_fields(name, spec, numbers.get(name, 0), found.inside if found else [])
            area["upcomingEntities_"] = found.upcoming if found else []
            area["leavingEntities_"] = found.leaving if found else []
            fields.append(area)
        if fields != self._last_areas:
            self._last_areas = fields
            self.area_pub.write(self.types.build(AREA_LIST, {"areaList": fields}))

    def area_numbers(self, names: frozenset[str]) -> dict[str, int]:
        """The original's numeric ids of the areas (re-read when the set of areas changes)."""
        node = self.bridge.node
        if names != self._area_numbers[0] and node.db is not None:
            from toaster.db import catalog

            with node.read_db.transaction() as conn:
                stored = catalog.get_setting(conn, AREA_SCOPE, AREA_KEY, {}) or {}
            self._area_numbers = (names, {k: int(v) for k, v in stored.items()})
        return self._area_numbers[1]

    def _markers(self, t_ns: int, facts: Mapping[str, list[Fact]], world: World) -> None:
        wanted = {t for t, p in self.marker_pubs.items() if self.dds.listened(p)}
        if not wanted:
            return
        arrays: dict[str, list[dict[str, Any]]] = {}
        if wanted & set(markers.TOPICS.values()):
            arrays |= markers.entity_markers(world, t_ns)
        if markers.AREAS_TOPIC in wanted:
            occupied = {
                f.target_id
                for f in facts.get("area_manager", None) or []
                if f.property in ("IsInArea", "IsInRoom", "IsAt")
            }
            areas = self.bridge.node.areas.areas
            arrays[markers.AREAS_TOPIC] = markers.area_markers(world, areas, occupied, t_ns)
        if markers.MOTION_TOPIC in wanted:
            agent = facts.get("agent_monitor", None) or []
            arrays[markers.MOTION_TOPIC] = markers.motion_markers(world, agent, t_ns)
        for topic in wanted:
            items = arrays.get(topic, [])
            self.marker_pubs[topic].write(self.types.build(MARKER_ARRAY, {"markers": items}))


def _transforms(world: World, t_ns: int) -> dict[str, Any]:
    """tf2_msgs/TFMessage fields: every live entity under "map" (frame names without a
    leading slash, as ROS 2's tf2 requires)."""
    return {
        "transforms": [
            {
                "header": {"stamp": t_ns, "frame_id": "map"},
                "child_frame_id": strip_frame(child),
                "transform": {
                    "translation": dict(zip("xyz", position, strict=True)),
                    "rotation": dict(zip("xyzw", quat, strict=True)),
                },
            }
            for child, position, quat, _ in markers.transforms(world)
        ]
    }
