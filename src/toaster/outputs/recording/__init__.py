"""Recordings of a run that ROS tools replay (the ``rosbag`` extra): a rosbag2 folder holding an
MCAP file (ROS 2 distros) or a ROS 1 ``.bag`` file (``noetic``).

Foxglove and Lichtblick open the ``.mcap`` (or the ``.bag``) directly; ``ros2 bag play`` /
``rosbag play`` and RViz replay them, and ``toaster run BAG`` replays them as input. Topics
(see ``docs/recordings.md``):

* ``/tf`` (``tf2_msgs/TFMessage``): every entity under ``map`` with pdg's frame names
  (objects ``<id>``, agents ``<id>/base``, joints ``<agent>/<joint>``; each id one name token,
  :func:`toaster.quoting.ros_name`), full 3D poses;
* ``/pdg/humanList``, ``/pdg/robotList``, ``/pdg/objectList`` (``toaster_msgs``): the entities
  as pdg publishes them, joints as skeleton joints;
* ``/toaster_visualizer/marker_object``, ``marker_human``, ``marker_robot``, ``marker_area`` and
  ``marker_motion`` (``visualization_msgs/MarkerArray``): the live bridge's markers on the original
  toaster_visualizer's topics (:data:`toaster.outputs.markers.MARKER_TOPICS`), drawn by
  :mod:`toaster.outputs.markers` (real sizes, circles, owner-relative areas, agent_monitor's
  motion and attention facts);
* ``/area_manager/areaList`` (``toaster_msgs/AreaList``): the areas and who is inside;
* ``/<producer>/factList`` (``toaster_msgs/FactList``): the self agent's facts of pdg,
  area_manager, agent_monitor and move3d_facts whenever they changed (from the store);
* ``/toaster/beliefs/<holder>`` (``toaster_recording/Beliefs``): everything each agent (and
  nested holder) believes, whenever it changed (:mod:`toaster.outputs.recording.beliefs`);
* ``/toaster/facts`` (``Log``): one line per belief change (an event);
* ``/toaster/run`` and ``/toaster/world`` (``toaster_recording/Run``, ``World``): how the run
  was set up and the world its producers saw at every tick, so that ``toaster run`` on the
  recording reproduces the run's database (:mod:`toaster.world.recorded`).

Poses are not in the fact store: callers hand :func:`record` (or :class:`Recorder`) frames
``(t_ns, entities, areas)`` (:mod:`toaster.outputs.recording.input`).
"""

from __future__ import annotations

import heapq
from collections.abc import Iterable, Iterator, Mapping, Sequence
from pathlib import Path
from typing import TYPE_CHECKING, Any, NamedTuple

from toaster.errors import InvalidInputError
from toaster.model import EventRow, Fact, FactRow
from toaster.outputs.markers import (  # noqa: F401  (re-exported marker constants)
    ADD,
    AREAS_TOPIC,
    ARROW,
    CUBE,
    CYLINDER,
    DELETEALL,
    LINE_STRIP,
    MARKER_TOPICS,
    MOTION_TOPIC,
    SPHERE,
    SPHERE_LIST,
    TEXT,
)
from toaster.outputs.recording.beliefs import (
    BELIEFS_MSG,
    BELIEFS_TYPE,
    BeliefTimeline,
    chain,
    holder_topic,
)
from toaster.outputs.recording.formats import BagWriter, bag_format, toaster_spelling
from toaster.outputs.recording.input import (  # noqa: F401  (the input types, re-exported)
    AreaOutline,
    AreaSpec,
    Frame,
    area_spec,
    check_frames,
    entity_poses,
    read_frames,
)
from toaster.outputs.recording.msgs import EntityPose, FactTimeline, Messages, Scene, toaster_types
from toaster.quoting import ros_name
from toaster.world.recorded import (
    RUN_MSG,
    RUN_TOPIC,
    RUN_TYPE,
    WORLD_MSG,
    WORLD_TOPIC,
    WORLD_TYPE,
    RunInfo,
)

if TYPE_CHECKING:
    from toaster.db.database import Database

__all__ = [
    "EntityPose",
    "Frame",
    "Recorder",
    "RecordingResult",
    "event_line",
    "read_frames",
    "record",
]

FACTS_TOPIC = "/toaster/facts"
TF_TOPIC, AREA_LIST_TOPIC = "/tf", "/area_manager/areaList"
LIST_TOPICS = {"human": "/pdg/humanList", "robot": "/pdg/robotList", "object": "/pdg/objectList"}
MARKER_ARRAY = "visualization_msgs/msg/MarkerArray"
TF_MESSAGE, FACT_LIST = "tf2_msgs/msg/TFMessage", "toaster_msgs/msg/FactList"
AREA_LIST = "toaster_msgs/msg/AreaList"
LIST_TYPES = {k: f"toaster_msgs/msg/{k.title()}ListStamped" for k in LIST_TOPICS}


class RecordingResult(NamedTuple):
    """What :func:`record` wrote: the bag (folder or ``.bag``), the file a viewer opens (the
    ``.mcap`` inside, or the ``.bag``) and message counts."""

    bag: Path
    file: Path
    frames: int
    facts: int
    fact_lists: int = 0
    beliefs: int = 0

    @property
    def mcap(self) -> Path:
        """The file a viewer opens (the name of older releases)."""
        return self.file


#: The recording's own message definitions (package ``toaster_recording``) by type: what the
#: :class:`Recorder` registers after toaster_msgs, and what ``toaster ros1 env`` generates for
#: the ROS tools.
OWN_MESSAGES = {BELIEFS_TYPE: BELIEFS_MSG, RUN_TYPE: RUN_MSG, WORLD_TYPE: WORLD_MSG}


def own_types() -> dict[str, Any]:
    """:data:`OWN_MESSAGES` as rosbags types."""
    from rosbags.typesys import get_types_from_msg

    types: dict[str, Any] = {}
    for name, text in OWN_MESSAGES.items():
        types |= get_types_from_msg(text, name)
    return types


class Recorder:
    """Writes frames, fact lists, beliefs and fact lines into a new bag ``path`` (use as a
    context manager).

    ``distro`` (humble, iron, jazzy, kilted; noetic for a ROS 1 ``.bag``; default noetic when
    ``path`` ends in ``.bag``, else humble) names the message definitions and the container
    (:mod:`toaster.outputs.recording.formats`: a rosbag2 folder with the metadata version that
    distro writes). ``toaster_names`` spells toaster_msgs' fields as ROS 2 requires (``ros2``, the
    default of ROS 2 bags: decoded by Foxglove and rosidl tools) or as the original (``ros1``,
    the only spelling of ROS 1 bags); ``toaster run`` reads both.
    """

    def __init__(
        self,
        path: str | Path,
        *,
        frame_id: str = "map",
        distro: str | None = None,
        toaster_names: str | None = None,
    ) -> None:
        fmt = bag_format(path, distro)
        types = toaster_types(toaster_spelling(fmt, toaster_names))
        self.bag = BagWriter(path, fmt, types | own_types())
        self.path, self.distro, self.version = self.bag.path, fmt.distro, fmt.version
        self.types = self.bag.types
        self._messages = Messages(self.types)
        self.frame_id = frame_id
        self.scene = Scene(frame_id)
        self.areas: dict[str, dict[str, Any]] = {}
        self._inside: dict[str, set[str]] = {}
        self._areas_changed = False
        self._owners: dict[str, tuple[float, ...]] = {}
        self._motion: list[Fact] = []  # agent_monitor's facts now, drawn on marker_motion
        self.belief_topics: dict[str, str] = {}
        self.frames = self.facts = self.fact_lists = self.beliefs = 0

    def __enter__(self) -> Recorder:
        self.bag.open()
        for topic, msgtype in (
            (TF_TOPIC, TF_MESSAGE),
            *((topic, MARKER_ARRAY) for topic in MARKER_TOPICS),
            (FACTS_TOPIC, self.bag.log_type),
            *((LIST_TOPICS[k], LIST_TYPES[k]) for k in LIST_TOPICS),
            (AREA_LIST_TOPIC, AREA_LIST),
        ):
            # the areas are written only when they change: latched, as a late RViz needs them
            self.bag.connect(topic, msgtype, latched=topic in (AREAS_TOPIC, AREA_LIST_TOPIC))
        return self

    def __exit__(self, exc_type: object, *exc: object) -> None:
        self.bag.close(discard=exc_type is not None)

    @property
    def mcap_path(self) -> Path:
        """The file a viewer opens: the MCAP file inside the folder, or the ROS 1 ``.bag``."""
        return self.bag.file

    # -- writing --------------------------------------------------------------------------
    def write_frame(
        self, t_ns: int, entities: Iterable[Any], areas: Iterable[Any] | None = None
    ) -> None:
        """Write /tf, pdg's lists and the markers at ``t_ns``; with ``areas``, replace the
        areas (redrawn whenever the owner of one moved, or who is inside changed). The motion
        markers show agent_monitor's facts of the last :meth:`write_fact_list`."""
        poses = entity_poses(entities)
        new_areas = None if areas is None else dict(area_spec(item) for item in areas)
        scene = self.scene
        scene.update(t_ns, poses)
        self._put(TF_TOPIC, t_ns, TF_MESSAGE, scene.transforms(t_ns))
        for kind, fields in scene.lists(t_ns).items():
            self._put(LIST_TOPICS[kind], t_ns, LIST_TYPES[kind], fields)
        for topic, drawn in scene.entity_markers(t_ns).items():
            self._put(topic, t_ns, MARKER_ARRAY, {"markers": drawn})
        motion = scene.motion_markers(self._motion, t_ns)
        self._put(MOTION_TOPIC, t_ns, MARKER_ARRAY, {"markers": motion})
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
        from toaster.world.rosmsg import area_fields

        occupied = {area for area, inside in self._inside.items() if inside}
        drawn = self.scene.area_markers(self.areas, occupied, t_ns)
        self._put(AREAS_TOPIC, t_ns, MARKER_ARRAY, {"markers": drawn})
        if self._areas_changed:
            listed = [
                area_fields(area_id, spec, k, self._inside.get(area_id, ()))
                for k, (area_id, spec) in enumerate(sorted(self.areas.items()))
            ]
            self._put(AREA_LIST_TOPIC, t_ns, AREA_LIST, {"areaList": listed})
        self._areas_changed = False

    def write_fact_list(self, t_ns: int, source: str, facts: Iterable[Fact | FactRow]) -> None:
        """Write the facts ``source`` holds at ``t_ns`` on ``/<source>/factList`` (FactRows
        keep their start as ``timeStart``)."""
        if ros_name(source) != source:
            msg = f"cannot publish facts of {source!r}: a producer name is a ROS name (pdg)"
            raise InvalidInputError(msg)
        held, items = _fact_items(facts, t_ns)
        topic = f"/{source}/factList"
        if not self.bag.has(topic):
            self.bag.connect(topic, FACT_LIST)
        self._put(topic, t_ns, FACT_LIST, {"factList": items})
        self.fact_lists += 1
        if source == "area_manager":
            self._note_inside(held)
        elif source == "agent_monitor":
            self._motion = held

    def write_beliefs(
        self, t_ns: int, holder: str, facts: Iterable[Fact | FactRow], *, is_self: bool = False
    ) -> None:
        """Write everything ``holder`` (an agent, or a nested holder ``A>B``) believes at
        ``t_ns`` on its channel ``/toaster/beliefs/<holder>``."""
        topic = self.belief_topics.get(holder)
        if topic is None:
            topic = self.belief_topics[holder] = holder_topic(holder)
            self.bag.connect(topic, BELIEFS_TYPE)
        _, items = _fact_items(facts, t_ns)
        self._put(
            topic,
            t_ns,
            BELIEFS_TYPE,
            {
                "header": {"stamp": t_ns, "frame_id": self.frame_id},
                "holder": holder,
                "chain": chain(holder),
                "is_self": is_self,
                "facts": items,
            },
        )
        self.beliefs += 1

    def _note_inside(self, facts: list[Fact]) -> None:
        inside: dict[str, set[str]] = {}
        for fact in facts:
            if fact.target_id in self.areas:
                inside.setdefault(fact.target_id, set()).add(fact.subject_id)
        if inside != self._inside:
            self._inside, self._areas_changed = inside, True

    def write_run(self, info: RunInfo) -> None:
        """Write how the run was set up on ``/toaster/run`` (once, at its start)."""
        self.bag.connect(RUN_TOPIC, RUN_TYPE)
        self._put(RUN_TOPIC, info.start_ns, RUN_TYPE, info.fields())

    def write_world(self, t_ns: int, fields: Mapping[str, Any]) -> None:
        """Write the world the producers saw at ``t_ns`` on ``/toaster/world``
        (:func:`toaster.world.recorded.world_fields`)."""
        if not self.bag.has(WORLD_TOPIC):
            self.bag.connect(WORLD_TOPIC, WORLD_TYPE)
        self._put(WORLD_TOPIC, t_ns, WORLD_TYPE, fields)

    def write_fact_line(self, t_ns: int, text: str, *, name: str = "toaster") -> None:
        """Write one INFO line on the facts channel."""
        self._put(FACTS_TOPIC, t_ns, self.bag.log_type, self.bag.log_fields(t_ns, name, text))
        self.facts += 1

    def write_event(self, event: EventRow) -> None:
        """Write one fact-store event as a line of the facts channel."""
        self.write_fact_line(event.stamp_ns, event_line(event), name=f"toaster.{event.agent_id}")

    def _put(self, topic: str, t_ns: int, msgtype: str, fields: Mapping[str, Any]) -> None:
        self.bag.write(topic, t_ns, self._messages.build(msgtype, fields), msgtype)


def _fact_items(
    facts: Iterable[Fact | FactRow], t_ns: int
) -> tuple[list[Fact], list[dict[str, Any]]]:
    """The facts and their toaster_msgs/Fact fields at ``t_ns`` (a FactRow's start as
    ``timeStart``)."""
    from toaster.world.rosmsg import fact_fields

    rows = list(facts)
    held = [row if isinstance(row, Fact) else row.to_fact() for row in rows]
    items = [
        fact_fields(fact, t_ns) | {"timeStart": getattr(row, "valid_from_ns", t_ns)}
        for fact, row in zip(held, rows, strict=True)
    ]
    return held, items


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


# -- whole recordings ---------------------------------------------------------------------------
def record(
    path: str | Path,
    frames: Iterable[Frame | Sequence[Any]],
    *,
    db: Database | None = None,
    agent: str | Sequence[str] | None = None,
    since: int | None = None,
    until: int | None = None,
    frame_id: str = "map",
    distro: str | None = None,
    toaster_names: str | None = None,
    run: RunInfo | None = None,
    world: Iterable[tuple[int, Mapping[str, Any]]] = (),
    recorder: Any = None,
) -> RecordingResult:
    """Record ``frames`` (in time order) and, with ``db``, the self agent's fact lists, the
    beliefs and the events of ``agent`` (default: every agent and holder) between ``since``
    and ``until`` (default: the first and last frame). ``distro`` and ``toaster_names`` as
    :class:`Recorder`. ``run`` and ``world`` (``(t_ns, World fields)`` in time order) are what
    ``toaster run`` records so that the recording replays whole (:mod:`toaster.world.recorded`).
    ``recorder``: what writes it, called as :class:`Recorder` (default), e.g.
    :class:`toaster.outputs.foxglove.record.FoxgloveRecorder`. Returns the bag and the file to
    open."""
    frame_list = check_frames(frames)
    if not frame_list and db is None:
        msg = "nothing to record: give at least one frame or a database"
        raise InvalidInputError(msg)
    if recorder is None:
        recorder = Recorder
        toaster_spelling(bag_format(path, distro), toaster_names)
    events: list[EventRow] = []
    timeline, beliefs = FactTimeline([]), BeliefTimeline({}, [])
    lo = since if since is not None else (frame_list[0].t_ns if frame_list else None)
    hi = until if until is not None else (frame_list[-1].t_ns if frame_list else None)
    if db is not None:
        from toaster.outputs.export import select_rows

        events = select_rows(db, "events", agent=agent, since=lo, until=hi)  # type: ignore[assignment]
        timeline = FactTimeline.from_db(db, lo, hi)
        beliefs = BeliefTimeline.from_db(db, agent, lo, hi)
    # snapshots at every frame and every change in the window (a change between frames too)
    changes = {*timeline.boundaries(), *beliefs.boundaries()}
    times = sorted(
        {
            *(f.t_ns for f in frame_list),
            *(t for t in changes if (lo is None or t >= lo) and (hi is None or t <= hi)),
        }
    )
    with recorder(path, frame_id=frame_id, distro=distro, toaster_names=toaster_names) as rec:
        if run is not None:
            rec.write_run(run)
        for kind, item in _merged(
            frame_list, events, timeline.snapshots(times), beliefs.snapshots(times), world
        ):
            if kind == "facts":
                rec.write_fact_list(*item)
            elif kind == "beliefs":
                rec.write_beliefs(*item, is_self=beliefs.is_self[item[1]])
            elif kind == "frame":
                rec.write_frame(item.t_ns, item.entities, item.areas)
            elif kind == "world":
                rec.write_world(*item)
            else:
                rec.write_event(item)
    return RecordingResult(
        rec.path, rec.mcap_path, rec.frames, rec.facts, rec.fact_lists, rec.beliefs
    )


def _merged(
    frames: list[Frame],
    events: list[EventRow],
    snapshots: Iterable[tuple[int, str, list[Any]]],
    beliefs: Iterable[tuple[int, str, list[Any]]],
    world: Iterable[tuple[int, Mapping[str, Any]]] = (),
) -> Iterator[tuple[str, Any]]:
    """Fact lists, beliefs, frames, world states and events in time order (in that order at
    one time)."""
    keyed = [
        ((s[0], 0, k, "facts", s) for k, s in enumerate(snapshots)),
        ((b[0], 1, k, "beliefs", b) for k, b in enumerate(beliefs)),
        ((f.t_ns, 2, k, "frame", f) for k, f in enumerate(frames)),
        ((w[0], 3, k, "world", w) for k, w in enumerate(world)),
        ((e.stamp_ns, 4, k, "event", e) for k, e in enumerate(events)),
    ]
    for *_, kind, item in heapq.merge(*keyed):
        yield kind, item
