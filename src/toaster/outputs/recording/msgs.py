"""What a recording holds, as rosbags messages (helpers of :mod:`toaster.outputs.recording`).

* :class:`Messages` turns the plain field dicts of :mod:`toaster.outputs.markers` and
  :mod:`toaster.world.rosmsg` into messages of a rosbags typestore (missing fields at zero);
* :class:`Scene` keeps the recorded entities in a :class:`~toaster.world.state.World` (poses
  set, never simulated), so that the live bridge's code draws them: one definition of frame
  names, shapes, sizes and colours;
* :class:`FactTimeline` replays the store's intervals as complete snapshots over time: the
  producers' fact lists, each holder's beliefs.
"""

from __future__ import annotations

import functools
import heapq
import re
from collections.abc import Iterable, Iterator, Mapping, Sequence
from typing import TYPE_CHECKING, Any

import numpy as np

from toaster.model import Fact, FactRow, NumberedInterval
from toaster.outputs import markers
from toaster.producers.registry import NAMES as PRODUCERS
from toaster.world.rosmsg import strip_frame
from toaster.world.state import EntityPose, World

if TYPE_CHECKING:
    from rosbags.typesys.store import Typestore

    from toaster.db.database import Database

TIME = "builtin_interfaces/msg/Time"
_NP = {
    "bool": np.bool_,
    "float32": np.float32,
    "float64": np.float64,
    "byte": np.uint8,
    "char": np.uint8,
    "octet": np.uint8,
}


# -- dicts to messages --------------------------------------------------------------------------
def toaster_types(names: str = "ros1") -> dict[str, Any]:
    """toaster_msgs as rosbags types: the original's field names (``ros1``: ``humanList``, what
    ``toaster run`` reads back) or ROS 2 ones (``ros2``: ``human_list``, as rosidl and Foxglove
    require of ROS 2 interfaces; same CDR layout; checked by
    :func:`toaster.outputs.recording.formats.toaster_spelling`)."""
    from toaster.world.bags import toaster_types as shipped

    types = shipped()
    if names == "ros1":
        return types
    return {
        name: (consts, [(snake(field), spec) for field, spec in fields])
        for name, (consts, fields) in types.items()
    }


@functools.cache
def snake(name: str) -> str:
    """A ROS 2 field name for an original one: ``insideEntities_`` → ``inside_entities``."""
    return re.sub(r"(?<!^)(?=[A-Z])", "_", name).lower().strip("_")


class Messages:
    """Builds messages of a rosbags typestore from nested dicts: missing fields at zero, ints
    accepted for times (ns), original toaster_msgs field names filling ROS 2 ones."""

    def __init__(self, store: Typestore) -> None:
        self.store = store
        self._plans: dict[str, list[tuple[str, str, Any]]] = {}
        self._zeros: dict[str, Any] = {}

    def build(self, msgtype: str, value: Any) -> Any:
        """A ``msgtype`` message from ``value`` (a dict; a message passes through)."""
        if not isinstance(value, Mapping):
            if msgtype == TIME and isinstance(value, int | np.integer):
                return self.store.types[TIME](
                    sec=int(value) // 1_000_000_000, nanosec=int(value) % 1_000_000_000
                )
            return value
        plan = self._plan(msgtype)
        if msgtype.startswith("toaster_msgs/") and any(name not in value for name, *_ in plan):
            value = {snake(key): item for key, item in value.items()} | dict(value)
        fields = {
            name: (
                self._convert(node, spec, value[name]) if name in value else self._zero(node, spec)
            )
            for name, node, spec in plan
        }
        return self.store.types[msgtype](**fields)

    def _plan(self, msgtype: str) -> list[tuple[str, str, Any]]:
        if msgtype not in self._plans:
            self._plans[msgtype] = [
                (name, node.name, spec) for name, (node, spec) in self.store.fielddefs[msgtype][1]
            ]
        return self._plans[msgtype]

    def _convert(self, node: str, spec: Any, value: Any) -> Any:
        if node == "NAME":
            return self.build(spec, value)
        if node == "BASE":
            return _base(spec[0], value)
        (inner, inner_spec), _ = spec  # SEQUENCE or ARRAY
        if inner.name == "BASE" and inner_spec[0] != "string":
            return np.asarray(value, dtype=_dtype(inner_spec[0]))
        return [self._convert(inner.name, inner_spec, v) for v in value]

    def _zero(self, node: str, spec: Any) -> Any:
        """A field's zero value (messages built once and shared: they are only serialised)."""
        if node == "NAME":
            if spec not in self._zeros:
                self._zeros[spec] = self.build(spec, {})
            return self._zeros[spec]
        if node == "BASE":
            return _base(spec[0], "" if spec[0] == "string" else 0)
        (inner, inner_spec), count = spec
        size = count if node == "ARRAY" else 0
        if inner.name == "BASE" and inner_spec[0] != "string":
            return np.zeros(size, dtype=_dtype(inner_spec[0]))
        return [self._zero(inner.name, inner_spec) for _ in range(size)]


def _base(kind: str, value: Any) -> Any:
    if kind == "string":
        return str(value)
    if kind == "bool":
        return bool(value)
    return float(value) if kind.startswith("float") else int(value)


def _dtype(kind: str) -> Any:
    return _NP.get(kind) or getattr(np, kind, np.uint8)


# -- the recorded world -------------------------------------------------------------------------
class Scene:
    """The entities of the last frame as a World, drawn and listed by :mod:`markers`."""

    def __init__(self, frame_id: str = "map") -> None:
        self.world = World(history_capacity=1)
        self.frame_id = frame_id

    def update(self, t_ns: int, poses: Sequence[EntityPose]) -> None:
        """Make the world hold exactly ``poses`` (agents before joints; owners are checked by
        :func:`toaster.outputs.recording.entity_poses`)."""
        world = self.world
        world.active[: world.n] = False
        world.held_by[: world.n] = -1
        for pose in sorted(poses, key=lambda p: p.kind == "joint"):
            row = self._row(pose)
            world.pos[row] = (pose.x, pose.y, pose.z)
            world.rpy[row] = (pose.roll, pose.pitch, pose.yaw)
            world.size[row] = pose.size if pose.size is not None else np.nan
            world.t_ns[row] = pose.t_ns if pose.t_ns is not None else t_ns
        for pose in poses:
            if pose.held_by in world.index:
                world.held_by[world.index[pose.id]] = world.index[pose.held_by]

    def _row(self, pose: EntityPose) -> int:
        return self.world.add_entity(
            pose.id, pose.kind, owner_id=pose.owner, name=pose.name or pose.id
        )

    def poses_of(self, ids: Iterable[str]) -> dict[str, tuple[float, ...]]:
        """(x, y, z, yaw) of those of ``ids`` in the frame."""
        world = self.world
        rows = {i: world.index[i] for i in ids if i in world.index}
        return {
            i: (*world.pos[r].tolist(), float(world.rpy[r, 2]))
            for i, r in rows.items()
            if world.active[r]
        }

    def _header(self, item: dict[str, Any]) -> dict[str, Any]:
        item["header"] = {**item["header"], "frame_id": self.frame_id}
        return item

    def transforms(self, t_ns: int) -> dict[str, Any]:
        """tf2_msgs/TFMessage fields: every entity under the fixed frame, pdg's frame names
        without leading slashes, stamped with the frame's time."""
        return {
            "transforms": [
                {
                    "header": {"stamp": t_ns, "frame_id": self.frame_id},
                    "child_frame_id": strip_frame(child),
                    "transform": {
                        "translation": dict(zip("xyz", position, strict=True)),
                        "rotation": dict(zip("xyzw", quat, strict=True)),
                    },
                }
                for child, position, quat, _ in markers.transforms(self.world)
            ]
        }

    def lists(self, t_ns: int) -> dict[str, dict[str, Any]]:
        """HumanListStamped / RobotListStamped / ObjectListStamped fields by kind."""
        header = {"stamp": t_ns, "frame_id": self.frame_id}
        items = markers.entity_list_fields(self.world, t_ns)
        return {kind: {"header": header, f"{kind}List": items[kind]} for kind in items}

    def entity_markers(self, t_ns: int) -> dict[str, list[dict[str, Any]]]:
        """Bodies, heading arrows, joints and names by topic (objects, humans, robots), each
        array after a DELETEALL."""
        arrays = markers.entity_markers(self.world, t_ns)
        return {topic: [self._header(m) for m in array] for topic, array in arrays.items()}

    def area_markers(
        self, areas: Mapping[str, Mapping[str, Any]], occupied: set[str], t_ns: int
    ) -> list[dict[str, Any]]:
        """Polygons, discs and names; owner-relative areas where their owner is now."""
        return [self._header(m) for m in markers.area_markers(self.world, areas, occupied, t_ns)]

    def motion_markers(self, facts: Sequence[Fact], t_ns: int) -> list[dict[str, Any]]:
        """agent_monitor's motion and attention ``facts`` as arrows and lines."""
        return [self._header(m) for m in markers.motion_markers(self.world, facts, t_ns)]


# -- facts --------------------------------------------------------------------------------------
class FactTimeline:
    """Intervals grouped by a field (``source``: the self agent's producers; ``agent_id``: the
    holders), as the complete sets each group held over time, each fact with the number it
    had then (an interval's stored refreshes, :func:`toaster.queries.numbered_history`)."""

    def __init__(
        self,
        rows: Iterable[FactRow | NumberedInterval],
        key: str = "source",
        groups: Iterable[str] = (),
    ) -> None:
        self.by_source: dict[str, list[NumberedInterval]] = {group: [] for group in groups}
        for item in rows:
            interval = item if isinstance(item, NumberedInterval) else NumberedInterval(item, ())
            self.by_source.setdefault(getattr(interval.row, key), []).append(interval)

    @classmethod
    def from_db(cls, db: Database, since: int | None, until: int | None) -> FactTimeline:
        """The intervals of the store's self agent from the four producers in the window."""
        from toaster import queries

        selves = queries.agents(db, only_self=True)
        if not selves:
            return cls([])
        return cls(
            queries.numbered_history(
                db, selves[0].id, since=since, until=until, source=list(PRODUCERS)
            )
        )

    def boundaries(self) -> list[int]:
        """Every time a fact started or ended, or its number changed."""
        return sorted(
            {
                t
                for intervals in self.by_source.values()
                for row, numbers in intervals
                for t in (
                    row.valid_from_ns,
                    row.valid_to_ns,
                    *(number[0] for number in numbers),
                )
                if t is not None
            }
        )

    def snapshots(self, times: Sequence[int]) -> Iterator[tuple[int, str, list[FactRow]]]:
        """(t, group, facts held at t) at the first time and whenever a group's facts or their
        numbers changed (valid_from ≤ t < valid_to), in time order (groups in name order at one
        time)."""
        streams = [_changes(source, rows, times) for source, rows in sorted(self.by_source.items())]
        yield from heapq.merge(*streams, key=lambda item: item[0])


def _changes(
    source: str, intervals: list[NumberedInterval], times: Sequence[int]
) -> Iterator[tuple[int, str, list[FactRow]]]:
    starts = sorted(range(len(intervals)), key=lambda k: intervals[k].row.valid_from_ns)
    ends: list[tuple[int, int]] = []
    active: set[int] = set()
    last: tuple[tuple[int, FactRow], ...] | None = None
    i = 0
    for t in times:
        while i < len(starts) and intervals[starts[i]].row.valid_from_ns <= t:
            k = starts[i]
            active.add(k)
            end = intervals[k].row.valid_to_ns
            if end is not None:
                heapq.heappush(ends, (end, k))
            i += 1
        while ends and ends[0][0] <= t:
            active.discard(heapq.heappop(ends)[1])
        now = tuple((k, intervals[k].at(t)) for k in sorted(active))
        if last != now:
            last = now
            held = sorted(
                (row for _, row in now), key=lambda r: (r.subject_id, r.property, r.target_id)
            )
            yield t, source, held
