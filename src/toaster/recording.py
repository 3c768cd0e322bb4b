"""Recordings of a run that ROS tools replay: a rosbag2 bag stored as MCAP (the ``rosbag`` extra).

Foxglove and Lichtblick open the ``.mcap`` file inside the bag directly; ``ros2 bag play`` and
RViz 2 take the bag directory. Topics:

* ``/toaster/entities`` (``visualization_msgs/msg/MarkerArray``): one body marker per entity
  (cylinder = human, cube = robot, sphere = object), a heading arrow for agents and the name as
  a text marker; each array starts with DELETEALL so that entities that left disappear.
* ``/toaster/areas`` (``MarkerArray``): each area's outline (a closed line strip) and its name.
* ``/toaster/facts`` (``rcl_interfaces/msg/Log``): one line per belief change (an event of the
  fact store): ``pr2: mug IsOn table appeared = true (confidence 1)``.

Poses are not in the fact store: callers hand :func:`record` (or :class:`Recorder`) frames
``(t_ns, entities, areas)``, entities as ``(id, kind, x, y, z, yaw)`` and areas as
``(id, [(x, y), ...])``, plus, optionally, the database whose events become the facts channel.
"""

from __future__ import annotations

import dataclasses
import heapq
import math
from collections.abc import Iterable, Iterator, Sequence
from itertools import pairwise
from pathlib import Path
from typing import Any, NamedTuple

from toaster.errors import InvalidInputError, MissingDependencyError
from toaster.model import EventRow

ENTITIES_TOPIC, AREAS_TOPIC, FACTS_TOPIC = "/toaster/entities", "/toaster/areas", "/toaster/facts"
MARKER_ARRAY, LOG = "visualization_msgs/msg/MarkerArray", "rcl_interfaces/msg/Log"
# visualization_msgs/Marker constants
ARROW, CUBE, SPHERE, CYLINDER, LINE_STRIP, TEXT = 0, 1, 2, 3, 4, 9
ADD, DELETEALL = 0, 3
INFO = 20
_BODIES = {"human": (CYLINDER, (0.45, 0.45, 1.7), (0.2, 0.45, 0.9)),
           "robot": (CUBE, (0.6, 0.6, 1.2), (0.95, 0.55, 0.1)),
           "object": (SPHERE, (0.15, 0.15, 0.15), (0.2, 0.7, 0.3))}
_OTHER = (CUBE, (0.2, 0.2, 0.2), (0.6, 0.6, 0.6))


class EntityPose(NamedTuple):
    """Where one entity is: position in metres, heading (yaw) in radians."""

    id: str
    kind: str
    x: float
    y: float
    z: float
    yaw: float


class AreaOutline(NamedTuple):
    """An area's footprint polygon (x, y) in metres."""

    id: str
    polygon: Sequence[tuple[float, float]]


class Frame(NamedTuple):
    """The world at ``t_ns``: entity poses and area outlines (None: areas unchanged)."""

    t_ns: int
    entities: Sequence[EntityPose | tuple[str, str, float, float, float, float]]
    areas: Sequence[AreaOutline | tuple[str, Sequence[tuple[float, float]]]] | None = None


class RecordingResult(NamedTuple):
    """What :func:`record` wrote: the bag directory, its MCAP file and message counts."""

    bag: Path
    mcap: Path
    frames: int
    facts: int


def _rosbags() -> tuple[Any, Any, Any]:
    try:
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        package = "rosbags"
        raise MissingDependencyError(package, "rosbag", "recording") from None
    return Writer, StoragePlugin, (Stores, get_typestore)


class Recorder:
    """Writes frames and fact lines into a new bag directory ``path`` (use as a context manager).

    ``distro`` names the ROS 2 message definitions used (``humble``, ``jazzy``...).
    """

    def __init__(self, path: str | Path, *, frame_id: str = "map", distro: str = "humble") -> None:
        writer_cls, plugin, (stores, get_typestore) = _rosbags()
        self.path = Path(path)
        if self.path.exists():
            msg = f"cannot record into {str(self.path)!r}: it exists; give a new directory name"
            raise InvalidInputError(msg)
        try:
            store = stores[f"ROS2_{distro.upper()}"]
        except KeyError:
            names = ", ".join(s.name[5:].lower() for s in stores if s.name.startswith("ROS2_"))
            msg = f"unknown ROS 2 distro {distro!r}: use one of {names}"
            raise InvalidInputError(msg) from None
        self.types = get_typestore(store)
        self.frame_id = frame_id
        self._writer = writer_cls(self.path, version=9, storage_plugin=plugin.MCAP)
        self._ids: dict[str, int] = {}
        self._last_t = -(2**63)
        self.frames = self.facts = 0

    def __enter__(self) -> Recorder:
        self._writer.open()
        add = self._writer.add_connection
        self._entities = add(ENTITIES_TOPIC, MARKER_ARRAY, typestore=self.types)
        self._areas = add(AREAS_TOPIC, MARKER_ARRAY, typestore=self.types)
        self._facts = add(FACTS_TOPIC, LOG, typestore=self.types)
        return self

    def __exit__(self, *exc: object) -> None:
        self._writer.close()

    @property
    def mcap_path(self) -> Path:
        """The MCAP file inside the bag (open this one in Foxglove or Lichtblick)."""
        return next(self.path.glob("*.mcap"))

    # -- writing --------------------------------------------------------------------------
    def write_frame(self, t_ns: int, entities: Iterable[Sequence[Any]],
                    areas: Iterable[Sequence[Any]] | None = None) -> None:
        """Write the entity markers at ``t_ns`` and, when given, the area outlines."""
        markers = [self._marker(t_ns, "entities", 0, action=DELETEALL)]
        for item in entities:
            pose = _entity(item)
            markers += self._entity_markers(t_ns, pose)
        self._write(self._entities, t_ns, self._array(markers), MARKER_ARRAY)
        if areas is not None:
            outline = [self._marker(t_ns, "areas", 0, action=DELETEALL)]
            for k, item in enumerate(areas):
                outline += self._area_markers(t_ns, k, _area(item))
            self._write(self._areas, t_ns, self._array(outline), MARKER_ARRAY)
        self.frames += 1

    def write_fact_line(self, t_ns: int, text: str, *, name: str = "toaster",
                        level: int = INFO) -> None:
        """Write one line on the facts channel."""
        t = self.types.types
        log = t[LOG](stamp=self._time(t_ns), level=level, name=name, msg=text, file="",
                     function="", line=0)
        self._write(self._facts, t_ns, log, LOG)
        self.facts += 1

    def write_event(self, event: EventRow) -> None:
        """Write one fact-store event as a line of the facts channel."""
        self.write_fact_line(event.stamp_ns, event_line(event), name=f"toaster.{event.agent_id}")

    def _write(self, conn: Any, t_ns: int, msg: Any, msgtype: str) -> None:
        if t_ns < 0:
            msg_ = f"cannot record time {t_ns}: ROS times start at 0 (the Unix epoch)"
            raise InvalidInputError(msg_)
        self._writer.write(conn, t_ns, self.types.serialize_cdr(msg, msgtype))

    # -- markers --------------------------------------------------------------------------
    def _time(self, t_ns: int) -> Any:
        return self.types.types["builtin_interfaces/msg/Time"](sec=t_ns // 1_000_000_000,
                                                               nanosec=t_ns % 1_000_000_000)

    def _array(self, markers: list[Any]) -> Any:
        return self.types.types[MARKER_ARRAY](markers=markers)

    def _marker(self, t_ns: int, ns: str, marker_id: int, *, kind: int = CUBE, action: int = ADD,
                xyz: Sequence[float] = (0, 0, 0), yaw: float = 0.0,
                scale: Sequence[float] = (1, 1, 1), rgba: Sequence[float] = (1, 1, 1, 1),
                text: str = "", points: Sequence[Sequence[float]] = ()) -> Any:
        t = self.types.types
        base = _default(self.types, "visualization_msgs/msg/Marker")
        point = t["geometry_msgs/msg/Point"]
        pose = t["geometry_msgs/msg/Pose"](
            position=point(x=float(xyz[0]), y=float(xyz[1]), z=float(xyz[2])),
            orientation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=math.sin(yaw / 2),
                                                          w=math.cos(yaw / 2)))
        return dataclasses.replace(
            base, header=t["std_msgs/msg/Header"](stamp=self._time(t_ns), frame_id=self.frame_id),
            ns=ns, id=marker_id, type=kind, action=action, pose=pose,
            scale=t["geometry_msgs/msg/Vector3"](x=float(scale[0]), y=float(scale[1]),
                                                 z=float(scale[2])),
            color=t["std_msgs/msg/ColorRGBA"](r=float(rgba[0]), g=float(rgba[1]),
                                              b=float(rgba[2]), a=float(rgba[3])),
            text=text, points=[point(x=float(p[0]), y=float(p[1]), z=float(p[2]))
                               for p in points])

    def _entity_markers(self, t_ns: int, pose: EntityPose) -> list[Any]:
        num = self._ids.setdefault(pose.id, len(self._ids))
        kind, scale, rgb = _BODIES.get(pose.kind, _OTHER)
        centre = (pose.x, pose.y, pose.z + (scale[2] / 2 if kind != SPHERE else 0.0))
        top = (pose.x, pose.y, pose.z + scale[2] + 0.25)
        out = [self._marker(t_ns, "entities", num, kind=kind, xyz=centre, yaw=pose.yaw,
                            scale=scale, rgba=(*rgb, 0.8)),
               self._marker(t_ns, "names", num, kind=TEXT, xyz=top, scale=(0, 0, 0.25),
                            text=pose.id)]
        if pose.kind in ("human", "robot"):
            out.append(self._marker(t_ns, "headings", num, kind=ARROW,
                                    xyz=(pose.x, pose.y, pose.z + 0.1), yaw=pose.yaw,
                                    scale=(0.7, 0.08, 0.08), rgba=(*rgb, 1.0)))
        return out

    def _area_markers(self, t_ns: int, num: int, area: AreaOutline) -> list[Any]:
        ring = [(float(x), float(y), 0.02) for x, y in area.polygon]
        centre = (sum(p[0] for p in ring) / len(ring), sum(p[1] for p in ring) / len(ring), 0.1)
        return [self._marker(t_ns, "areas", num, kind=LINE_STRIP, scale=(0.04, 0, 0),
                             rgba=(0.9, 0.9, 0.2, 1.0), points=[*ring, ring[0]]),
                self._marker(t_ns, "area_names", num, kind=TEXT, xyz=centre,
                             scale=(0, 0, 0.3), rgba=(0.9, 0.9, 0.2, 1.0), text=area.id)]


def event_line(event: EventRow) -> str:
    """One readable line for an event: ``pr2: mug IsOn table changed = shelf (confidence 1)``."""
    what = " ".join(p for p in (event.subject_id, event.property, event.target_id) if p)
    line = f"{event.agent_id}: {what} {event.kind}"
    if event.value_text is not None and event.kind != "ended":
        line += f" = {event.value_text}"
    if event.previous_text:
        line += f" (was {event.previous_text})"
    if event.confidence is not None and event.kind != "ended":
        line += f" (confidence {event.confidence:.3g})"
    return line


def _entity(item: Sequence[Any]) -> EntityPose:
    try:
        pose = EntityPose(str(item[0]), str(item[1]), *(float(v) for v in item[2:6]))
    except (TypeError, ValueError, IndexError):
        msg = f"invalid entity pose {item!r}: give (id, kind, x, y, z, yaw)"
        raise InvalidInputError(msg) from None
    if not all(math.isfinite(v) for v in pose[2:]):
        msg = f"invalid entity pose {item!r}: coordinates must be finite"
        raise InvalidInputError(msg)
    return pose


def _area(item: Sequence[Any]) -> AreaOutline:
    try:
        area = AreaOutline(str(item[0]), [(float(x), float(y)) for x, y in item[1]])
    except (TypeError, ValueError, IndexError):
        msg = f"invalid area {item!r}: give (id, [(x, y), ...])"
        raise InvalidInputError(msg) from None
    if len(area.polygon) < 3:
        msg = f"invalid area {area.id!r}: a polygon needs at least 3 points"
        raise InvalidInputError(msg)
    return area


_DEFAULTS: dict[tuple[int, str], Any] = {}


def _default(types: Any, name: str) -> Any:
    """A message of type ``name`` with every field at its zero value (any ROS 2 distro)."""
    import numpy as np

    key = (id(types), name)
    if key not in _DEFAULTS:
        fields = {field: _zero(types, node.name, spec, np)
                  for field, (node, spec) in types.fielddefs[name][1]}
        _DEFAULTS[key] = types.types[name](**fields)
    return _DEFAULTS[key]


def _zero(types: Any, node: str, spec: Any, np: Any) -> Any:
    if node == "NAME":
        return _default(types, spec)
    if node == "BASE":
        base = spec[0]
        return "" if base == "string" else False if base == "bool" else (
            0.0 if base.startswith("float") else 0)
    (inner, inner_spec), count = spec  # SEQUENCE or ARRAY
    if inner.name == "BASE" and inner_spec[0] not in ("string",):
        dtype = {"bool": bool, "float32": np.float32, "float64": np.float64}.get(
            inner_spec[0], getattr(np, inner_spec[0].replace("byte", "uint8").replace(
                "char", "uint8"), np.uint8))
        return np.zeros(count if node == "ARRAY" else 0, dtype=dtype)
    return [_zero(types, inner.name, inner_spec, np) for _ in range(count if node == "ARRAY"
                                                                    else 0)]


def record(path: str | Path, frames: Iterable[Frame | Sequence[Any]], *, db: Any = None,
           agent: str | Sequence[str] | None = None, since: int | None = None,
           until: int | None = None, frame_id: str = "map",
           distro: str = "humble") -> RecordingResult:
    """Record ``frames`` (in time order) and, with ``db``, its events as the facts channel.

    Events are those of ``agent`` (default: every agent) between ``since`` and ``until``
    (default: the first and last frame). Returns the bag directory and its MCAP file.
    """
    frame_list = [f if isinstance(f, Frame) else Frame(*f) for f in frames]
    for before, after in pairwise(frame_list):
        if after.t_ns < before.t_ns:
            msg = (f"frames out of time order: {after.t_ns} comes after {before.t_ns}; "
                   "sort the frames by time")
            raise InvalidInputError(msg)
    if not frame_list and db is None:
        msg = "nothing to record: give at least one frame or a database"
        raise InvalidInputError(msg)
    events: list[EventRow] = []
    if db is not None:
        from toaster.export import select_rows

        lo = since if since is not None else (frame_list[0].t_ns if frame_list else None)
        hi = until if until is not None else (frame_list[-1].t_ns if frame_list else None)
        events = select_rows(db, "events", agent=agent, since=lo, until=hi)  # type: ignore[assignment]
    with Recorder(path, frame_id=frame_id, distro=distro) as rec:
        for item in _merged(frame_list, events):
            if isinstance(item, EventRow):
                rec.write_event(item)
            else:
                rec.write_frame(item.t_ns, item.entities, item.areas)
    return RecordingResult(rec.path, rec.mcap_path, rec.frames, rec.facts)


def _merged(frames: list[Frame], events: list[EventRow]) -> Iterator[Frame | EventRow]:
    keyed_frames = ((f.t_ns, 0, k, f) for k, f in enumerate(frames))
    keyed_events = ((e.stamp_ns, 1, k, e) for k, e in enumerate(events))
    for *_, item in heapq.merge(keyed_frames, keyed_events):
        yield item


def read_frames(path: str | Path) -> list[Frame]:
    """Frames from a JSON-lines file: ``{"t_ns", "entities", "areas"}`` per line."""
    import json

    from toaster.errors import FileFormatError

    frames = []
    with Path(path).open(encoding="utf-8") as handle:
        for number, line in enumerate(handle, 1):
            if not line.strip():
                continue
            try:
                item = json.loads(line)
                frames.append(Frame(int(item["t_ns"]), item.get("entities", []),
                                    item.get("areas")))
            except (ValueError, KeyError, TypeError) as exc:
                msg = (f"{Path(path).name} line {number}: not a frame ({exc}); write "
                       '{"t_ns": 0, "entities": [["pr2", "robot", 0, 0, 0, 0]]}')
                raise FileFormatError(msg) from None
    return frames
