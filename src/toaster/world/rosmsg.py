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
from collections.abc import Iterable, Mapping
from pathlib import Path
from typing import Any, NamedTuple

from toaster.errors import InvalidInputError
from toaster.model import check_agent_id, check_id, shown
from toaster.world.factmsg import fact_fields as fact_fields  # the bridge's, recordings'
from toaster.world.factmsg import fact_from_msg as fact_from_msg
from toaster.world.geometry import IDENTITY, Quat, Vec, check_quat, quat_mul, rotate
from toaster.world.geometry import rpy_to_quat as rpy_to_quat  # its old home
from toaster.world.tftree import FIXED_FRAME as FIXED_FRAME
from toaster.world.tftree import TfTree as TfTree
from toaster.world.tftree import stamp_ns as stamp_ns
from toaster.world.tftree import strip_frame as strip_frame

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


# -- transform tree (toaster.world.tftree) ------------------------------------------------------
def tf_updates(
    tree: TfTree, targets: Mapping[str, FrameTarget], changed: Iterable[str]
) -> tuple[list[PoseUpdate], list[str]]:
    """Poses of the mapped frames whose chain contains a changed frame, and the mapped frames
    that do not reach the fixed frame, all composed from the tree as it was when called (a
    message arriving meanwhile on rospy's thread is not half seen: one human's body from it
    and its head from the one before, for one tick). :meth:`TfTree.poses` gives them as
    arrays."""
    poses, lost = tree.poses(targets, changed)
    updates = [
        PoseUpdate(
            target.entity_id,
            target.kind,
            (x, y, z),
            (qx, qy, qz, qw),
            t_ns,
            target.owner_id,
            target.joint,
        )
        for target, (x, y, z), (qx, qy, qz, qw), t_ns in zip(
            poses.targets, poses.pos.tolist(), poses.quat.tolist(), poses.stamps, strict=True
        )
    ]
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
