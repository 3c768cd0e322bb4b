"""ROS 1 and ROS 2 bags as a replayable source (the ``rosbag`` extra: the rosbags library).

``read_bag(path)`` reads a ROS 1 ``.bag``, a ROS 2 bag directory (``metadata.yaml`` with
``.db3`` or ``.mcap`` files), or one ``.mcap`` / ``.db3`` file, through the same message mapping
as the live ROS bridge (:mod:`toaster.world.rosmsg`):

* ``/tf`` and ``/tf_static`` (``tf2_msgs/TFMessage``): the frames of the frame map (``tf_map``,
  as ``toaster serve --tf-map``), and ROS4HRI ``body_<id>`` / ``face_<id>`` frames, composed up
  to ``map``;
* ``geometry_msgs/PoseStamped`` topics named in ``pose_topics`` ({topic: (id, kind)});
* the original's ``toaster_msgs/HumanListStamped`` / ``RobotListStamped`` /
  ``ObjectListStamped`` on any topic (pdg, toaster_simu), joints included, with the
  original's camelCase field names or ROS 2 snake_case ones;
* ``toaster_msgs/AreaList`` (``/area_manager/areaList``): the last one gives the areas, so
  toaster's own recordings replay with their areas;
* toaster's own recordings' ``/toaster/run`` and ``/toaster/world``
  (:mod:`toaster.world.recorded`): when a bag has both, it replays the recorded world
  exactly (a :class:`~toaster.world.recorded.WorldReplay`) and the other topics are not read.

Poses are replayed by their stamps (the header's, else the bag's receive time), deterministically:
the same bag gives the same facts at any speed. Messages that cannot be used are counted and
reported in one line per kind of problem (``problems``), never raised halfway through a run;
the whole bag is read and validated before the first tick.
"""

from __future__ import annotations

from collections import Counter
from collections.abc import Mapping
from pathlib import Path
from typing import Any

import numpy as np

from toaster.errors import FileFormatError
from toaster.extras import require
from toaster.model import MAX_COORD, check_id, shown
from toaster.timeutil import MAX_NS, MAX_RATE_HZ, MIN_RATE_HZ
from toaster.world.recorded import RUN_TYPE, WORLD_TYPE, RunInfo, WorldReplay, recorded_types
from toaster.world.state import World

TF_TYPES = ("tf2_msgs/msg/TFMessage",)
POSE_TYPE = "geometry_msgs/msg/PoseStamped"
LIST_TYPES = tuple(f"toaster_msgs/msg/{k}ListStamped" for k in ("Human", "Robot", "Object"))
AREA_TYPE = "toaster_msgs/msg/AreaList"
MSG_DIR = Path(__file__).resolve().parent.parent / "ros1" / "msgs"
#: Topics every toaster recording has (a bag with them is one of toaster's own)
TOASTER_TOPICS = ("/toaster/entities", "/toaster/facts")


def is_bag(path: Path) -> bool:
    """Whether ``path`` looks like a bag toaster can replay."""
    return path.suffix.lower() in (".bag", ".mcap", ".db3") or (
        path.is_dir() and (path / "metadata.yaml").exists()
    )


def toaster_types() -> dict[str, Any]:
    """The shipped toaster_msgs / hri_msgs definitions as rosbags types."""
    from rosbags.typesys import get_types_from_msg

    types: dict[str, Any] = {}
    for msg in sorted(MSG_DIR.glob("*/msg/*.msg")):
        name = f"{msg.parent.parent.name}/msg/{msg.stem}"
        types.update(get_types_from_msg(msg.read_text(), name))
    return types


def typestore() -> Any:
    """A rosbags typestore with ROS 2 standard types and toaster's own."""
    from rosbags.typesys import Stores, get_typestore

    store = get_typestore(Stores.LATEST)
    store.register(toaster_types() | recorded_types())
    return store


class BagSource:
    """Poses of a bag in stamp order; ``advance`` applies those stamped up to the tick."""

    def __init__(
        self,
        name: str,
        times: np.ndarray,
        updates: list[Any],
        problems: Counter[str],
        areas: dict[str, dict[str, Any]] | None = None,
    ) -> None:
        from toaster.world.geometry import check_quat, quats_to_rpy

        self.name = name
        self.areas = dict(areas or {})  # the last AreaList of the bag (toaster's recordings)
        self.problems = problems
        quats, good = [], []
        for i, update in enumerate(updates):
            try:
                check_id(update.entity_id, "entity id")
                if update.owner_id:
                    check_id(update.owner_id, "owner id")
                q = check_quat(update.quat)
            except ValueError as exc:  # InvalidInputError is one
                problems[f"{shown(update.entity_id)}: {exc}"] += 1
                continue
            if not np.isfinite(update.position).all():
                problems[f"{update.entity_id}: non-finite pose ignored"] += 1
            elif np.abs(update.position).max() > MAX_COORD:
                problems[f"{update.entity_id}: pose beyond ±{MAX_COORD:g} m ignored"] += 1
            elif not 0 <= int(times[i]) <= MAX_NS:
                problems[f"{update.entity_id}: stamp {int(times[i])} ns out of range ignored"] += 1
            else:
                quats.append(q)
                good.append(i)
        keep = np.array(good, np.int64)
        order = np.argsort(times[keep], kind="stable")
        self.times = times[keep][order]
        self.updates = [updates[good[i]] for i in order]
        self.pos = np.array([u.position for u in self.updates], float).reshape(-1, 3)
        self.rpy = quats_to_rpy(quats)[order]
        self._next = 0
        self.start_ns = int(self.times[0]) if len(self.times) else 0
        self.end_ns = int(self.times[-1]) if len(self.times) else 0
        self.kinds = {u.entity_id: u.kind for u in self.updates if u.kind != "joint"}
        self.sample_hz = _sample_hz(self.times, self.updates)
        self.toaster = False  # a toaster recording (one without /toaster/world: older)

    def sample_times(self) -> np.ndarray:
        """Every distinct time a pose was perceived at."""
        return np.unique(self.times)

    def setup(self, world: World) -> None:
        """Register every entity of the bag (agents before their joints); not perceived, so
        not live, until its first pose."""
        seen: set[str] = set()
        for update in sorted(self.updates, key=lambda u: u.kind == "joint"):
            if update.entity_id in seen:
                continue
            seen.add(update.entity_id)
            world.add_entity(
                update.entity_id,
                update.kind,
                owner_id=update.owner_id if update.kind == "joint" else "",
                name=update.joint or update.entity_id,
            )

    def advance(self, world: World, t_ns: int) -> None:
        """Apply the poses stamped at or before ``t_ns`` not applied yet."""
        end = int(np.searchsorted(self.times, t_ns, side="right"))
        if end <= self._next:
            return
        lo, self._next = self._next, end
        rows = world.rows_of([u.entity_id for u in self.updates[lo:end]])
        world.observe(self.name, rows, self.times[lo:end], self.pos[lo:end], self.rpy[lo:end])


def _sample_hz(times: np.ndarray, updates: list[Any]) -> float | None:
    """The median rate at which one entity is seen (ticks at it by default)."""
    if len(times) < 2:
        return None
    ids = np.array([u.entity_id for u in updates], dtype=object)
    steps = []
    for entity_id in np.unique(ids)[:50]:
        t = np.unique(times[ids == entity_id])  # objects not seen again repeat their stamp
        if len(t) > 1:
            steps.append(np.median(np.diff(t)))
    step = float(np.median(steps)) if steps else 0.0
    return min(max(1e9 / step, MIN_RATE_HZ), MAX_RATE_HZ) if step > 0 else None


def read_bag(
    path: str | Path,
    *,
    tf_map: str | Path | Mapping[str, Any] | None = None,
    pose_topics: Mapping[str, tuple[str, str]] | None = None,
) -> BagSource | WorldReplay:
    """Read a bag's poses (see the module's doc); one-line errors for unreadable bags."""
    require("rosbag", "reading bags")
    from rosbags.highlevel import AnyReader

    from toaster.world import rosmsg as mapping

    path = Path(path)
    targets = mapping.read_frame_map(tf_map)
    topics = dict(pose_topics or {})
    tree = mapping.TfTree()
    times: list[int] = []
    updates: list[Any] = []
    problems: Counter[str] = Counter()
    areas: dict[str, dict[str, Any]] = {}

    def keep(found: list[Any], received_ns: int) -> None:
        for update in found:
            times.append(update.t_ns if update.t_ns else received_ns)
            updates.append(update)

    run: list[tuple[int, Any]] = []
    states: list[tuple[int, Any]] = []
    try:
        with AnyReader([path], default_typestore=typestore()) as reader:
            topics_seen = {c.topic for c in reader.connections}
            recorded = {c.msgtype for c in reader.connections} >= {RUN_TYPE, WORLD_TYPE}
            poses = () if recorded else (*TF_TYPES, *LIST_TYPES, AREA_TYPE)
            wanted = [
                c
                for c in reader.connections
                if c.msgtype in poses
                or (recorded and c.msgtype in (RUN_TYPE, WORLD_TYPE))
                or (c.msgtype == POSE_TYPE and c.topic in topics and not recorded)
            ]
            for topic in set(topics) - topics_seen:
                problems[f"topic {topic} is not in the bag"] += 1
            for conn, received_ns, raw in reader.messages(connections=wanted):
                msg: Any = reader.deserialize(raw, conn.msgtype)
                try:
                    if conn.msgtype in (RUN_TYPE, WORLD_TYPE):
                        stamp = mapping.stamp_ns(msg.header.stamp)
                        (run if conn.msgtype == RUN_TYPE else states).append((stamp, msg))
                    elif conn.msgtype in TF_TYPES:
                        changed, _ = tree.update(msg)
                        for frame in changed:
                            hri = mapping.hri_target(frame)
                            if hri is not None and frame not in targets:
                                targets[frame] = hri
                        found, lost = mapping.tf_updates(tree, targets, changed)
                        for frame in lost:
                            problems[f"frame {frame} does not reach map"] += 1
                        keep(found, received_ns)
                    elif conn.msgtype == AREA_TYPE:
                        areas = dict(
                            mapping.area_from_msg(a) for a in mapping.field(msg, "areaList", ())
                        )
                    elif conn.msgtype in LIST_TYPES:
                        found, bad = mapping.list_updates(msg)
                        for line in bad:
                            problems[line] += 1
                        keep(found, received_ns)
                    else:
                        entity, kind = topics[conn.topic]
                        keep(
                            [mapping.pose_stamped_update(msg, entity, kind, tree=tree)], received_ns
                        )
                except ValueError as exc:
                    problems[f"{conn.topic}: {exc}"] += 1
    except (OSError, KeyError) as exc:
        msg = f"cannot read bag {str(path)!r}: {exc}"
        raise FileFormatError(msg) from None
    except Exception as exc:  # rosbags' own errors (bad index, unknown storage, ...)
        if type(exc).__module__.startswith("rosbags"):
            msg = f"cannot read bag {str(path)!r}: {str(exc).splitlines()[0]}"
            raise FileFormatError(msg) from None
        raise
    if run:
        try:
            return WorldReplay(path.name, RunInfo.from_msg(run[0][1], run[0][0]), states)
        except (ValueError, TypeError) as exc:  # json's errors are ValueErrors
            msg = (
                f"cannot replay {path.name!r}: its /toaster/run and /toaster/world do not "
                f"fit ({exc}); record the run again"
            )
            raise FileFormatError(msg) from None
    if not updates:
        msg = (
            f"bag {path.name!r} holds no pose toaster can use: give --tf-map for its /tf "
            "frames or --pose-topic TOPIC=ID for PoseStamped topics"
        )
        raise FileFormatError(msg)
    source = BagSource(path.name, np.array(times, np.int64), updates, problems, areas)
    source.toaster = bool(set(TOASTER_TOPICS) & topics_seen)
    return source
