"""Recordings of a run that ROS tools replay: a rosbag2 bag stored as MCAP (the ``rosbag`` extra).

Foxglove and Lichtblick open the ``.mcap`` file inside the bag directly; ``ros2 bag play`` and
RViz 2 take the bag directory, and ``toaster run BAG_DIR`` replays it as input. Topics (see
``docs/recordings.md``):

* ``/tf`` (``tf2_msgs/msg/TFMessage``): every entity under ``map`` with pdg's frame names
  (objects ``<id>``, agents ``<id>/base``, joints ``<agent>/<joint>``), full 3D poses;
* ``/pdg/humanList``, ``/pdg/robotList``, ``/pdg/objectList`` (``toaster_msgs``): the entities
  as pdg publishes them, joints as skeleton joints;
* ``/toaster/entities`` and ``/toaster/areas`` (``visualization_msgs/msg/MarkerArray``): shapes
  drawn by :mod:`toaster.ros1.markers` (real sizes, circles, owner-relative areas);
* ``/area_manager/areaList`` (``toaster_msgs/msg/AreaList``): the areas and who is inside;
* ``/<producer>/factList`` (``toaster_msgs/msg/FactList``): the self agent's facts of pdg,
  area_manager, agent_monitor and move3d_facts whenever they changed (from the store);
* ``/toaster/facts`` (``rcl_interfaces/msg/Log``): one line per belief change (an event).

Poses are not in the fact store: callers hand :func:`record` (or :class:`Recorder`) frames
``(t_ns, entities, areas)``: entities as :class:`EntityPose` (or its first six fields
``(id, kind, x, y, z, yaw)``), areas as ``(id, spec)`` or ``(id, [(x, y), ...])``.
"""

from __future__ import annotations

import heapq
import math
from collections.abc import Iterable, Iterator, Mapping, Sequence
from itertools import pairwise
from pathlib import Path
from typing import Any, NamedTuple

from toaster.errors import InvalidInputError, MissingDependencyError
from toaster.model import EventRow, Fact, FactRow
from toaster.recording_msgs import (
    EntityPose,
    FactTimeline,
    Messages,
    Scene,
    fit_metadata,
    metadata_version,
    toaster_types,
)
from toaster.ros1.markers import (  # noqa: F401  (re-exported marker constants)
    ADD,
    ARROW,
    CUBE,
    CYLINDER,
    DELETEALL,
    LINE_STRIP,
    SPHERE,
    SPHERE_LIST,
    TEXT,
)

__all__ = ["EntityPose", "Frame", "Recorder", "RecordingResult", "event_line", "read_frames",
           "record"]

ENTITIES_TOPIC, AREAS_TOPIC, FACTS_TOPIC = "/toaster/entities", "/toaster/areas", "/toaster/facts"
TF_TOPIC, AREA_LIST_TOPIC = "/tf", "/area_manager/areaList"
LIST_TOPICS = {"human": "/pdg/humanList", "robot": "/pdg/robotList", "object": "/pdg/objectList"}
MARKER_ARRAY, LOG = "visualization_msgs/msg/MarkerArray", "rcl_interfaces/msg/Log"
TF_MESSAGE, FACT_LIST = "tf2_msgs/msg/TFMessage", "toaster_msgs/msg/FactList"
AREA_LIST = "toaster_msgs/msg/AreaList"
LIST_TYPES = {k: f"toaster_msgs/msg/{k.title()}ListStamped" for k in LIST_TOPICS}
INFO = 20
KINDS = ("human", "robot", "object", "joint")


class AreaSpec(NamedTuple):
    """An area: its spec (``shape`` polygon or circle, ``points`` / ``center`` + ``radius``,
    ``owner`` for areas that move with an entity, as ``toaster area add``)."""

    id: str
    spec: dict[str, Any]


AreaOutline = AreaSpec  # the name of older releases


class Frame(NamedTuple):
    """The world at ``t_ns``: entity poses and areas (None: areas unchanged)."""

    t_ns: int
    entities: Sequence[EntityPose | Sequence[Any] | Mapping[str, Any]]
    areas: Sequence[AreaSpec | tuple[str, Any]] | None = None


class RecordingResult(NamedTuple):
    """What :func:`record` wrote: the bag directory, its MCAP file and message counts."""

    bag: Path
    mcap: Path
    frames: int
    facts: int
    fact_lists: int = 0


def _rosbags() -> tuple[Any, Any, Any]:
    try:
        from rosbags.rosbag2 import StoragePlugin, Writer
        from rosbags.typesys import Stores, get_typestore
    except ImportError:
        package = "rosbags"
        raise MissingDependencyError(package, "rosbag", "recording") from None
    return Writer, StoragePlugin, (Stores, get_typestore)


class Recorder:
    """Writes frames, fact lists and fact lines into a new bag directory ``path`` (use as a
    context manager).

    ``distro`` (humble, iron, jazzy, kilted) names the ROS 2 message definitions and the
    rosbag2 metadata version written (5, 8, 9, 9: what that distro's ``ros2 bag`` reads).
    ``toaster_names`` spells toaster_msgs' fields as ROS 2 requires (``ros2``, the default:
    decoded by Foxglove and rosidl tools) or as the original (``ros1``); ``toaster run`` reads
    both.
    """

    def __init__(self, path: str | Path, *, frame_id: str = "map", distro: str = "humble",
                 toaster_names: str = "ros2") -> None:
        writer_cls, plugin, (stores, get_typestore) = _rosbags()
        types = toaster_types(toaster_names)
        self.path = Path(path)
        if self.path.exists():
            msg = f"cannot record into {str(self.path)!r}: it exists; give a new directory name"
            raise InvalidInputError(msg)
        self.version, self.distro = metadata_version(distro), distro.lower()
        self.types = get_typestore(stores[f"ROS2_{self.distro.upper()}"])
        self.types.register(types)
        self._messages = Messages(self.types)
        self.frame_id = frame_id
        self.scene = Scene(frame_id)
        # rosbags writes versions 8 and 9; below 9 its QoS profiles are Humble's YAML strings
        self._writer = writer_cls(self.path, version=min(max(self.version, 8), 9),
                                  storage_plugin=plugin.MCAP)
        self._writer.version = self.version
        self._conns: dict[str, Any] = {}
        self.areas: dict[str, dict[str, Any]] = {}
        self._inside: dict[str, set[str]] = {}
        self._areas_changed = False
        self._owners: dict[str, tuple[float, ...]] = {}
        self.frames = self.facts = self.fact_lists = 0

    def __enter__(self) -> Recorder:
        self._writer.open()
        for topic, msgtype in ((TF_TOPIC, TF_MESSAGE), (ENTITIES_TOPIC, MARKER_ARRAY),
                               (AREAS_TOPIC, MARKER_ARRAY), (FACTS_TOPIC, LOG),
                               *((LIST_TOPICS[k], LIST_TYPES[k]) for k in LIST_TOPICS),
                               (AREA_LIST_TOPIC, AREA_LIST)):
            self._connect(topic, msgtype)
        return self

    def __exit__(self, *exc: object) -> None:
        self._writer.close()
        fit_metadata(self.path, self.version, self.distro)

    @property
    def mcap_path(self) -> Path:
        """The MCAP file inside the bag (open this one in Foxglove or Lichtblick)."""
        return next(self.path.glob("*.mcap"))

    # -- writing --------------------------------------------------------------------------
    def write_frame(self, t_ns: int, entities: Iterable[Any],
                    areas: Iterable[Any] | None = None) -> None:
        """Write /tf, pdg's lists and the markers at ``t_ns``; with ``areas``, replace the
        areas (redrawn whenever the owner of one moved, or who is inside changed)."""
        poses = entity_poses(entities)
        new_areas = None if areas is None else dict(area_spec(item) for item in areas)
        scene = self.scene
        scene.update(t_ns, poses)
        self._put(TF_TOPIC, t_ns, TF_MESSAGE, scene.transforms(t_ns))
        for kind, fields in scene.lists(t_ns).items():
            self._put(LIST_TOPICS[kind], t_ns, LIST_TYPES[kind], fields)
        self._put(ENTITIES_TOPIC, t_ns, MARKER_ARRAY, {"markers": scene.entity_markers(t_ns)})
        if new_areas is not None:
            self.areas, self._areas_changed = new_areas, True
        owners = scene.poses_of({spec.get("owner") or "" for spec in self.areas.values()} - {""})
        if self._areas_changed or owners != self._owners:
            self._owners = owners
            self._write_areas(t_ns)
        self.frames += 1

    def _write_areas(self, t_ns: int) -> None:
        """The markers; the area list too when areas or occupants changed (it holds
        owner-relative areas in their owner's frame)."""
        from toaster.ros1.mapping import area_fields

        occupied = {area for area, inside in self._inside.items() if inside}
        drawn = self.scene.area_markers(self.areas, occupied, t_ns)
        self._put(AREAS_TOPIC, t_ns, MARKER_ARRAY, {"markers": drawn})
        if self._areas_changed:
            listed = [area_fields(area_id, spec, k, self._inside.get(area_id, ()))
                      for k, (area_id, spec) in enumerate(sorted(self.areas.items()))]
            self._put(AREA_LIST_TOPIC, t_ns, AREA_LIST, {"areaList": listed})
        self._areas_changed = False

    def write_fact_list(self, t_ns: int, source: str, facts: Iterable[Fact | FactRow]) -> None:
        """Write the facts ``source`` holds at ``t_ns`` on ``/<source>/factList`` (FactRows
        keep their start as ``timeStart``)."""
        from toaster.ros1.mapping import fact_fields

        if not source.isidentifier():
            msg = f"cannot publish facts of {source!r}: a producer name is a ROS name (pdg)"
            raise InvalidInputError(msg)
        rows = list(facts)
        held = [row if isinstance(row, Fact) else row.to_fact() for row in rows]
        items = [fact_fields(fact, t_ns) | {"timeStart": getattr(row, "valid_from_ns", t_ns)}
                 for fact, row in zip(held, rows, strict=True)]
        topic = f"/{source}/factList"
        if topic not in self._conns:
            self._connect(topic, FACT_LIST)
        self._put(topic, t_ns, FACT_LIST, {"factList": items})
        self.fact_lists += 1
        if source == "area_manager":
            self._note_inside(held)

    def _note_inside(self, facts: list[Fact]) -> None:
        inside: dict[str, set[str]] = {}
        for fact in facts:
            if fact.target_id in self.areas:
                inside.setdefault(fact.target_id, set()).add(fact.subject_id)
        if inside != self._inside:
            self._inside, self._areas_changed = inside, True

    def write_fact_line(self, t_ns: int, text: str, *, name: str = "toaster",
                        level: int = INFO) -> None:
        """Write one line on the facts channel."""
        self._put(FACTS_TOPIC, t_ns, LOG, {"stamp": t_ns, "level": level, "name": name,
                                           "msg": text})
        self.facts += 1

    def write_event(self, event: EventRow) -> None:
        """Write one fact-store event as a line of the facts channel."""
        self.write_fact_line(event.stamp_ns, event_line(event), name=f"toaster.{event.agent_id}")

    def _connect(self, topic: str, msgtype: str) -> None:
        self._conns[topic] = self._writer.add_connection(topic, msgtype, typestore=self.types)

    def _put(self, topic: str, t_ns: int, msgtype: str, fields: Mapping[str, Any]) -> None:
        if t_ns < 0:
            msg = f"cannot record time {t_ns}: ROS times start at 0 (the Unix epoch)"
            raise InvalidInputError(msg)
        data = self.types.serialize_cdr(self._messages.build(msgtype, fields), msgtype)
        self._writer.write(self._conns[topic], t_ns, data)


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


# -- input checks -------------------------------------------------------------------------------
_POSE_HELP = "give (id, kind, x, y, z, yaw[, roll, pitch, size, owner, name, held_by, t_ns])"


def entity_poses(entities: Iterable[Any]) -> list[EntityPose]:
    """Checked poses of one frame; a joint's owner must be one of its humans or robots."""
    poses = [_entity(item) for item in entities]
    agents = {p.id for p in poses if p.kind in ("human", "robot")}
    for pose in poses:
        if pose.kind == "joint" and pose.owner not in agents:
            msg = (f"invalid entity pose {pose.id!r}: joint owner {pose.owner!r} is not a human "
                   "or robot of the same frame")
            raise InvalidInputError(msg)
    return poses


def _entity(item: Any) -> EntityPose:
    """An EntityPose from a tuple (positional fields) or a mapping (field names)."""
    fields = EntityPose._fields
    try:
        values = dict(item) if isinstance(item, Mapping) else dict(zip(fields, item, strict=False))
        if set(values) - set(fields) or (not isinstance(item, Mapping) and len(item) > len(fields)):
            raise ValueError
        kind = str(values["kind"]).lower()
        owner = str(values.get("owner") or "")
        x, y, z, yaw = (float(values[k]) for k in ("x", "y", "z", "yaw"))
        pose = EntityPose(
            str(values["id"]), kind if kind in KINDS else "object", x, y, z, yaw,
            float(values.get("roll") or 0.0), float(values.get("pitch") or 0.0),
            _size(values.get("size")), owner, str(values.get("name") or ""),
            str(values.get("held_by") or ""),
            None if values.get("t_ns") is None else int(values["t_ns"]))
    except (TypeError, ValueError, KeyError):
        msg = f"invalid entity pose {item!r}: {_POSE_HELP}"
        raise InvalidInputError(msg) from None
    if not all(math.isfinite(v) for v in (*pose[2:8], *(pose.size or ()))):
        msg = f"invalid entity pose {item!r}: coordinates and sizes must be finite"
        raise InvalidInputError(msg)
    if kind == "joint" and not pose.name:
        pose = pose._replace(name=pose.id.removeprefix(f"{owner}/"))
    return pose


def _size(value: Any) -> tuple[float, float, float] | None:
    if value is None:
        return None
    x, y, z = (float(v) for v in value)
    if min(x, y, z) <= 0:
        raise ValueError
    return (x, y, z)


def area_spec(item: Any) -> AreaSpec:
    """An area from ``(id, spec)`` (checked as ``toaster area add``) or ``(id, polygon)``."""
    from toaster.producers.areas import normalize_area

    try:
        area_id, shape = str(item[0]), item[1]
        points = [] if isinstance(shape, Mapping) else [[float(x), float(y)] for x, y in shape]
    except (TypeError, ValueError, IndexError, KeyError):
        msg = f"invalid area {item!r}: give (id, [(x, y), ...]) or (id, spec)"
        raise InvalidInputError(msg) from None
    if isinstance(shape, Mapping):
        return AreaSpec(area_id, normalize_area(area_id, shape))
    if len(points) < 3:
        msg = f"invalid area {area_id!r}: a polygon needs at least 3 points"
        raise InvalidInputError(msg)
    return AreaSpec(area_id, {"shape": "polygon", "points": points, "owner": ""})


def _frame(item: Frame | Sequence[Any]) -> Frame:
    """A checked frame (poses and areas parsed; a bad one fails before anything is written)."""
    frame = item if isinstance(item, Frame) else Frame(*item)
    if int(frame.t_ns) < 0:
        msg = f"cannot record time {frame.t_ns}: ROS times start at 0 (the Unix epoch)"
        raise InvalidInputError(msg)
    areas = None if frame.areas is None else [area_spec(a) for a in frame.areas]
    return Frame(int(frame.t_ns), entity_poses(frame.entities), areas)


# -- whole recordings ---------------------------------------------------------------------------
def record(path: str | Path, frames: Iterable[Frame | Sequence[Any]], *, db: Any = None,
           agent: str | Sequence[str] | None = None, since: int | None = None,
           until: int | None = None, frame_id: str = "map", distro: str = "humble",
           toaster_names: str = "ros2") -> RecordingResult:
    """Record ``frames`` (in time order) and, with ``db``, the self agent's fact lists and the
    events of ``agent`` (default: every agent) between ``since`` and ``until`` (default: the
    first and last frame). ``distro`` and ``toaster_names`` as :class:`Recorder`. Returns the
    bag directory and its MCAP file."""
    frame_list = [_frame(f) for f in frames]
    for before, after in pairwise(frame_list):
        if after.t_ns < before.t_ns:
            msg = (f"frames out of time order: {after.t_ns} comes after {before.t_ns}; "
                   "sort the frames by time")
            raise InvalidInputError(msg)
    if not frame_list and db is None:
        msg = "nothing to record: give at least one frame or a database"
        raise InvalidInputError(msg)
    metadata_version(distro)
    toaster_types(toaster_names)
    events: list[EventRow] = []
    timeline = FactTimeline([])
    if db is not None:
        from toaster.export import select_rows

        lo = since if since is not None else (frame_list[0].t_ns if frame_list else None)
        hi = until if until is not None else (frame_list[-1].t_ns if frame_list else None)
        events = select_rows(db, "events", agent=agent, since=lo, until=hi)  # type: ignore[assignment]
        timeline = FactTimeline.from_db(db, lo, hi)
    times = [f.t_ns for f in frame_list] or timeline.boundaries()
    with Recorder(path, frame_id=frame_id, distro=distro, toaster_names=toaster_names) as rec:
        for kind, item in _merged(frame_list, events, timeline.snapshots(times)):
            if kind == "facts":
                rec.write_fact_list(*item)
            elif kind == "frame":
                rec.write_frame(item.t_ns, item.entities, item.areas)
            else:
                rec.write_event(item)
    return RecordingResult(rec.path, rec.mcap_path, rec.frames, rec.facts, rec.fact_lists)


def _merged(frames: list[Frame], events: list[EventRow],
            snapshots: Iterable[tuple[int, str, list[Any]]]) -> Iterator[tuple[str, Any]]:
    """Fact lists, frames and events in time order (in that order at one time)."""
    keyed = [((s[0], 0, k, "facts", s) for k, s in enumerate(snapshots)),
             ((f.t_ns, 1, k, "frame", f) for k, f in enumerate(frames)),
             ((e.stamp_ns, 2, k, "event", e) for k, e in enumerate(events))]
    for *_, kind, item in heapq.merge(*keyed):
        yield kind, item


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
