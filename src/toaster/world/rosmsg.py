"""Pure mapping between ROS messages and toaster values (no rospy import).

Everything here is duck-typed on message attributes, so a ROS 2 transport or a bag reader can
reuse it: stamps with ``secs``/``nsecs`` (ROS 1) or ``sec``/``nanosec`` (ROS 2), ``/tf``
transforms through a frame map and a small transform tree, ``PoseStamped`` per entity, the
original's HumanListStamped / RobotListStamped / ObjectListStamped (pdg, toaster_simu),
ROS4HRI (REP-155) ``body_<id>`` / ``face_<id>`` frames, and facts and areas as the fields of
toaster_msgs/Fact and toaster_msgs/Area (plain dicts; the transport builds the messages).
"""

from __future__ import annotations

import json
import math
import re
import threading
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, NamedTuple

import numpy as np

from toaster.errors import InvalidInputError
from toaster.model import check_agent_id, check_id, shown
from toaster.world.factmsg import fact_fields as fact_fields  # the bridge's, recordings'
from toaster.world.factmsg import fact_from_msg as fact_from_msg
from toaster.world.geometry import (
    IDENTITY,
    Quat,
    Vec,
    check_quat,
    compose_poses,
    quat_mul,
    rotate,
)
from toaster.world.geometry import rpy_to_quat as rpy_to_quat  # its old home

FIXED_FRAME = "map"
ENTITY_KINDS = ("human", "robot", "object", "joint")


class PoseUpdate(NamedTuple):
    """One pose for a LiveSource push: world position, quaternion (x, y, z, w), stamp (None:
    now); joints carry their agent (``owner_id``) and skeleton name (``joint``)."""

    entity_id: str
    kind: str
    position: Vec
    quat: Quat
    t_ns: int | None
    owner_id: str = ""
    joint: str = ""


class FrameTarget(NamedTuple):
    """What a TF frame is: an entity, or a joint of an agent."""

    entity_id: str
    kind: str
    owner_id: str = ""
    joint: str = ""


# -- stamps and small maths ---------------------------------------------------------------------
def field(msg: Any, name: str, default: Any = None) -> Any:
    """A message field by its original (camelCase) name or its ROS 2 snake_case one
    (``humanList`` / ``human_list``, ``insideEntities_`` / ``inside_entities``)."""
    if hasattr(msg, name):
        return getattr(msg, name)
    snake = re.sub(r"(?<!^)(?=[A-Z])", "_", name).lower().strip("_")
    return getattr(msg, snake, default)


def stamp_ns(stamp: Any) -> int:
    """ns since the epoch of a ROS 1 (secs/nsecs) or ROS 2 (sec/nanosec) stamp, or an int."""
    if stamp is None:
        return 0
    if isinstance(stamp, int):
        return stamp
    if hasattr(stamp, "secs"):
        return int(stamp.secs) * 1_000_000_000 + int(stamp.nsecs)
    return int(stamp.sec) * 1_000_000_000 + int(stamp.nanosec)


def vec(p: Any) -> Vec:
    """(x, y, z) of a Point / Vector3; ValueError when not finite."""
    out = (float(p.x), float(p.y), float(p.z))
    if not all(math.isfinite(c) for c in out):
        msg = f"position {list(out)} must be finite numbers (metres)"
        raise ValueError(msg)
    return out


def quat(q: Any) -> Quat:
    """(x, y, z, w) of a Quaternion; an all-zero quaternion (a message default) is identity."""
    out = (float(q.x), float(q.y), float(q.z), float(q.w))
    if out == (0.0, 0.0, 0.0, 0.0):
        return IDENTITY
    return check_quat(out)


def strip_frame(frame: str) -> str:
    """A frame id without its leading slash (tf2 drops it too)."""
    return frame.lstrip("/")


# -- frame map ----------------------------------------------------------------------------------
def read_frame_map(source: str | Path | Mapping[str, Any] | None) -> dict[str, FrameTarget]:
    """Frame -> target from a YAML/JSON file or a mapping ``{frame: {id, kind, owner?, joint?}}``
    (also accepted under a top-level ``frames:`` key). A joint needs ``owner`` (its agent);
    its id is ``<owner>/<joint>`` and ``joint`` defaults to ``id``."""
    if source is None:
        return {}
    if isinstance(source, str | Path):
        path = Path(source)
        try:
            text = path.read_text()
        except OSError as exc:
            msg = f"cannot read the frame map {str(path)!r}: {exc.strerror}"
            raise InvalidInputError(msg) from None
        data = _parse_map_text(text, path)
    else:
        data = source
    if isinstance(data, Mapping) and isinstance(data.get("frames"), Mapping):
        data = data["frames"]
    if not isinstance(data, Mapping):
        msg = "the frame map must be a mapping {frame: {id, kind, owner?, joint?}}"
        raise InvalidInputError(msg)
    return {
        strip_frame(str(frame)): frame_target(str(frame), entry) for frame, entry in data.items()
    }


def _parse_map_text(text: str, path: Path) -> Any:
    import yaml

    try:
        return json.loads(text) if path.suffix == ".json" else yaml.safe_load(text)
    except (ValueError, yaml.YAMLError) as exc:
        first = str(exc).splitlines()[0]
        msg = f"the frame map {str(path)!r} is not valid YAML/JSON: {first}"
        raise InvalidInputError(msg) from None


def frame_target(frame: str, entry: Any) -> FrameTarget:
    """One frame-map entry (a mapping, or a bare entity id meaning an object)."""
    if isinstance(entry, FrameTarget):
        return entry
    if isinstance(entry, str):
        entry = {"id": entry}
    if not isinstance(entry, Mapping):
        msg = f"frame {frame!r}: give {{id, kind, owner?, joint?}}, not {entry!r}"
        raise InvalidInputError(msg)
    kind = str(entry.get("kind", "object")).lower()
    if kind not in ENTITY_KINDS:
        msg = f"frame {frame!r}: unknown kind {kind!r} (use {', '.join(ENTITY_KINDS)})"
        raise InvalidInputError(msg)
    owner = str(entry.get("owner", "") or "")
    if kind == "joint":
        joint = str(entry.get("joint") or entry.get("id") or "")
        if not owner or not joint:
            msg = f"frame {frame!r}: a joint needs owner (its agent) and joint (or id)"
            raise InvalidInputError(msg)
        check_agent_id(owner, f"frame {frame!r}: owner")
        return FrameTarget(
            check_id(f"{owner}/{joint}", f"frame {frame!r}: joint id"), "joint", owner, joint
        )
    entity_id = str(entry.get("id") or "")
    if not entity_id:
        msg = f"frame {frame!r}: missing id"
        raise InvalidInputError(msg)
    check = check_agent_id if kind in ("human", "robot") else check_id
    return FrameTarget(check(entity_id, f"frame {frame!r}: {kind} id"), kind)


def hri_target(frame: str) -> FrameTarget | None:
    """ROS4HRI frames: ``body_<id>`` is human ``<id>``, ``face_<id>`` its ``head`` joint."""
    if frame.startswith("body_") and len(frame) > 5:
        return FrameTarget(frame[5:], "human")
    if frame.startswith("face_") and len(frame) > 5:
        human = frame[5:]
        return FrameTarget(f"{human}/head", "joint", human, "head")
    return None


def tracked_ids(msg: Any) -> set[str]:
    """The ids of an hri_msgs/IdsList."""
    return {str(i) for i in msg.ids}


# -- transform tree -----------------------------------------------------------------------------
class TfTree:
    """The newest transform per child frame; poses composed up to the fixed frame.

    Thread-safe (``/tf`` and ``/tf_static`` arrive on different threads).
    """

    MAX_DEPTH = 64
    #: frames kept at most: a publisher inventing new frame names cannot make it grow further
    MAX_FRAMES = 10_000

    def __init__(self, fixed_frame: str = FIXED_FRAME) -> None:
        self.fixed = strip_frame(fixed_frame)
        self._edges: dict[str, tuple[str, Vec, Quat, int]] = {}
        self._lock = threading.Lock()

    def update(self, msg: Any) -> tuple[set[str], list[str]]:
        """Store the transforms of a TFMessage; return (children set, one line per bad one)."""
        changed: set[str] = set()
        bad: list[str] = []
        with self._lock:
            for tr in msg.transforms:
                child = strip_frame(tr.child_frame_id)
                parent = strip_frame(tr.header.frame_id)
                try:
                    check_id(child, "child frame")
                    check_id(parent, "parent frame")
                    t, q = vec(tr.transform.translation), quat(tr.transform.rotation)
                except ValueError as exc:  # InvalidInputError is one
                    bad.append(f"transform {shown(parent)} -> {shown(child)} ignored: {exc}")
                    continue
                if child == parent:
                    bad.append(
                        f"transform {shown(parent)} -> {shown(child)} ignored: not a tree edge"
                    )
                    continue
                if child not in self._edges and len(self._edges) >= self.MAX_FRAMES:
                    bad.append(
                        f"transform {shown(parent)} -> {shown(child)} ignored: "
                        f"{self.MAX_FRAMES} frames are known already"
                    )
                    continue
                self._edges[child] = (parent, t, q, stamp_ns(tr.header.stamp))
                changed.add(child)
        return changed, bad

    def chain(self, frame: str) -> list[str]:
        """Frames from ``frame`` up to its root (``frame`` first)."""
        out, current = [frame], frame
        with self._lock:
            while current in self._edges and len(out) <= self.MAX_DEPTH:
                current = self._edges[current][0]
                out.append(current)
        return out

    def lookup(self, frame: str) -> tuple[Vec, Quat, int | None] | None:
        """Pose of ``frame`` in the fixed frame and its newest stamp (None when all stamps
        are 0, as static transforms); None when no chain of transforms reaches the fixed
        frame."""
        return self.lookup_many([frame])[0]

    def lookup_many(self, frames: list[str]) -> list[tuple[Vec, Quat, int | None] | None]:
        """:meth:`lookup` of many frames, composed together (one rotation batch per level)."""
        chains: list[list[tuple[str, Vec, Quat, int]] | None] = []
        with self._lock:
            for frame in frames:
                current = strip_frame(frame)
                edges: list[tuple[str, Vec, Quat, int]] = []
                while current != self.fixed and len(edges) < self.MAX_DEPTH:
                    edge = self._edges.get(current)
                    if edge is None:
                        break
                    edges.append(edge)
                    current = edge[0]
                chains.append(edges if current == self.fixed else None)
        found = [c for c in chains if c is not None]
        depth = max((len(c) for c in found), default=0)
        # level k holds each chain's k-th transform from the frame up, identity past its end
        lt = np.zeros((depth, len(found), 3))
        lq = np.tile(np.asarray(IDENTITY), (depth, len(found), 1))
        for i, chain in enumerate(found):
            for k, (_, et, eq, _) in enumerate(chain):
                lt[k, i], lq[k, i] = et, eq
        t, q = np.zeros((len(found), 3)), np.tile(np.asarray(IDENTITY), (len(found), 1))
        for k in range(depth):
            t, q = compose_poses(lt[k], lq[k], t, q)
        out: list[tuple[Vec, Quat, int | None] | None] = []
        i = 0
        for edges_up in chains:
            if edges_up is None:
                out.append(None)
                continue
            x, y, z = t[i].tolist()
            qx, qy, qz, qw = q[i].tolist()
            newest = max((e[3] for e in edges_up), default=0)
            out.append(((x, y, z), (qx, qy, qz, qw), newest or None))
            i += 1
        return out

    def frames(self) -> list[str]:
        """Every child frame known."""
        with self._lock:
            return list(self._edges)

    def frozen(self) -> TfTree:
        """A copy that later messages do not change: poses composed from it all come from
        the same messages."""
        copy = TfTree()
        copy.fixed = self.fixed
        with self._lock:
            copy._edges = dict(self._edges)
        return copy


def tf_updates(
    tree: TfTree, targets: Mapping[str, FrameTarget], changed: Iterable[str]
) -> tuple[list[PoseUpdate], list[str]]:
    """Poses of the mapped frames whose chain contains a changed frame, and the mapped frames
    that do not reach the fixed frame, all composed from the tree as it was when called (a
    message arriving meanwhile on rospy's thread is not half seen: one human's body from it
    and its head from the one before, for one tick)."""
    tree = tree.frozen()
    changed = set(changed)
    updates: list[PoseUpdate] = []
    lost: list[str] = []
    wanted = [frame for frame in targets if changed.intersection(tree.chain(frame))]
    for frame, found in zip(wanted, tree.lookup_many(wanted), strict=True):
        target = targets[frame]
        if found is None:
            lost.append(frame)
            continue
        position, q, t_ns = found
        updates.append(
            PoseUpdate(
                target.entity_id, target.kind, position, q, t_ns, target.owner_id, target.joint
            )
        )
    return updates, lost


def pose_stamped_update(
    msg: Any,
    entity_id: str,
    kind: str = "object",
    *,
    tree: TfTree | None = None,
    fixed_frame: str = FIXED_FRAME,
) -> PoseUpdate:
    """A PoseStamped as the entity's world pose; a frame other than the fixed one is composed
    through ``tree``. ValueError for non-finite numbers or a frame that does not reach it."""
    position, q = vec(msg.pose.position), quat(msg.pose.orientation)
    frame = strip_frame(msg.header.frame_id)
    t_ns = stamp_ns(msg.header.stamp) or None
    if frame and frame != strip_frame(fixed_frame):
        found = tree.lookup(frame) if tree is not None else None
        if found is None:
            msg_text = f"frame {frame!r} does not reach {fixed_frame!r} through /tf"
            raise ValueError(msg_text)
        ft, fq, _ = found
        r = rotate(fq, position)
        position, q = (ft[0] + r[0], ft[1] + r[1], ft[2] + r[2]), quat_mul(fq, q)
    return PoseUpdate(entity_id, kind, position, q, t_ns)


# -- the original's entity lists ----------------------------------------------------------------
def _entity_update(
    entity: Any,
    kind: str,
    header_ns: int,
    owner: str = "",
    joint: str = "",
    entity_id: str | None = None,
) -> PoseUpdate:
    t_ns = int(entity.time) or header_ns or None
    return PoseUpdate(
        entity_id or str(entity.id),
        kind,
        vec(entity.pose.position),
        quat(entity.pose.orientation),
        t_ns,
        owner,
        joint,
    )


def agent_updates(agent: Any, kind: str, header_ns: int) -> list[PoseUpdate]:
    """An Agent (meAgent of a Human / Robot) and its skeleton joints."""
    me = field(agent, "meEntity")
    agent_id = str(me.id)
    out = [_entity_update(me, kind, header_ns)]
    names = list(field(agent, "skeletonNames", ()))
    for i, joint in enumerate(field(agent, "skeletonJoint", ())):
        me_joint = field(joint, "meEntity")
        name = names[i] if i < len(names) and names[i] else str(me_joint.name or me_joint.id)
        out.append(
            _entity_update(me_joint, "joint", header_ns, agent_id, name, f"{agent_id}/{name}")
        )
    return out


def list_updates(msg: Any) -> tuple[list[PoseUpdate], list[str]]:
    """Poses of a HumanListStamped, RobotListStamped or ObjectListStamped (one bad entity
    is skipped with a line saying why)."""
    header_ns = stamp_ns(msg.header.stamp)
    updates: list[PoseUpdate] = []
    bad: list[str] = []
    items: list[tuple[str, Any]] = (
        [("human", field(h, "meAgent")) for h in field(msg, "humanList", ())]
        + [("robot", field(r, "meAgent")) for r in field(msg, "robotList", ())]
        + [("object", o) for o in field(msg, "objectList", ())]
    )
    for kind, item in items:
        try:
            if kind == "object":
                updates.append(_entity_update(field(item, "meEntity"), "object", header_ns))
            else:
                updates.extend(agent_updates(item, kind, header_ns))
        except ValueError as exc:
            entity = field(item, "meEntity")
            bad.append(f"{kind} {shown(entity.id)} ignored: {exc}")
    return updates, bad


# -- areas (facts: toaster.world.factmsg) ------------------------------------------------------
def area_from_msg(msg: Any) -> tuple[str, dict[str, Any]]:
    """(name, spec) of a toaster_msgs/Area, as the original read it: zmin = zmax = 0 and a
    circle's height 0 mean no vertical band; factType interaction / density."""
    from toaster.world.areaspec import area_from_original, normalize_area

    f = field
    record = {
        "name": str(msg.name),
        "myOwner": str(f(msg, "myOwner")),
        "areaType": str(f(msg, "areaType")),
        "factType": str(f(msg, "factType")),
        "entityType": str(f(msg, "entityType")),
        "isCircle": bool(f(msg, "isCircle")),
        "ray": float(msg.ray),
        "center": {"x": float(msg.center.x), "y": float(msg.center.y)},
        "poly": [[float(p.x), float(p.y)] for p in msg.poly.points],
        "zmin": float(msg.zmin),
        "zmax": float(msg.zmax),
    }
    name, spec = area_from_original(record)
    extra: dict[str, Any] = {
        "enter_hysteresis": float(f(msg, "enterHysteresis")),
        "leave_hysteresis": float(f(msg, "leaveHysteresis")),
    }
    if f(msg, "isCircle") and float(msg.height) > 0:
        extra |= {
            "center": [float(msg.center.x), float(msg.center.y), float(msg.center.z)],
            "height": float(msg.height),
        }
    return name, normalize_area(name, {**spec, **extra})


def area_fields(
    area_id: str, spec: Mapping[str, Any], number: int, inside: Iterable[str] = ()
) -> dict[str, Any]:
    """toaster_msgs/Area fields (nested dicts) of a stored area spec."""
    circle = spec.get("shape") == "circle"
    center = [*spec.get("center", [0.0, 0.0]), 0.0][:3]
    z_min, z_max = spec.get("z_min"), spec.get("z_max")
    facts = list(spec.get("facts") or [])
    return {
        "id": number,
        "name": area_id,
        "myOwner": spec.get("owner", ""),
        "areaType": spec.get("area_type", ""),
        "factType": facts[0] if facts else "",
        "entityType": " ".join(spec.get("entity_types") or ["entities"]),
        "isCircle": circle,
        "center": {"x": center[0], "y": center[1], "z": center[2]},
        "ray": float(spec.get("radius") or 0.0),
        "height": float(spec.get("height") or 0.0),
        "poly": {"points": [{"x": p[0], "y": p[1], "z": 0.0} for p in spec.get("points", [])]},
        "zmin": float(z_min) if z_min is not None else 0.0,
        "zmax": float(z_max) if z_max is not None else 0.0,
        "enterHysteresis": float(spec.get("enter_hysteresis") or 0.0),
        "leaveHysteresis": float(spec.get("leave_hysteresis") or 0.0),
        "insideEntities_": sorted(inside),
        "upcomingEntities_": [],
        "leavingEntities_": [],
    }
