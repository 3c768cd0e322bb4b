"""The world as TF frames, entity lists and RViz markers: plain dicts (no rospy import).

Marker dicts carry visualization_msgs/Marker field names; the transport turns them into
messages. Each array starts with a DELETEALL marker, so entities that left disappear. Shapes
use the entities' sizes (``world.size``) when known, else a default per kind: humans are
cylinders with a heading arrow and their joints as spheres, robots boxes, objects boxes,
areas polygons or discs (brighter while something is inside) and the motion and attention
facts of agent_monitor arrows and lines (``marker_motion``).

The topics are the original toaster_visualizer's (:data:`MARKER_TOPICS`), the same live (the ROS 1
bridge), in recordings (``.bag`` and ``.mcap``) and in the shipped RViz config
(``toaster/ros1/toaster.rviz``).
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from typing import Any

import numpy as np

from toaster.model import Fact
from toaster.quoting import ros_name
from toaster.world.geometry import (
    Quat,
    from_local_xy,
    rotation_matrices,
    rpy_to_quats,
)
from toaster.world.history import NO_TIME
from toaster.world.state import HUMAN, JOINT, OBJECT, ROBOT, World

FRAME = "map"
ARROW, CUBE, SPHERE, CYLINDER, LINE_STRIP, LINE_LIST, SPHERE_LIST, TEXT = 0, 1, 2, 3, 4, 5, 7, 9
ADD, DELETEALL = 0, 3
DEFAULT_SIZE = {HUMAN: (0.5, 0.5, 1.7), ROBOT: (0.6, 0.6, 1.2), OBJECT: (0.2, 0.2, 0.2)}
COLORS = {HUMAN: (1.0, 0.8, 0.2), ROBOT: (0.4, 0.6, 1.0), OBJECT: (0.0, 1.0, 1.0)}
#: the original toaster_visualizer's MarkerArray topics, live and recorded alike
OBJECTS_TOPIC = "/toaster_visualizer/marker_object"
HUMANS_TOPIC = "/toaster_visualizer/marker_human"
ROBOTS_TOPIC = "/toaster_visualizer/marker_robot"
AREAS_TOPIC = "/toaster_visualizer/marker_area"
MOTION_TOPIC = "/toaster_visualizer/marker_motion"
MARKER_TOPICS = (OBJECTS_TOPIC, AREAS_TOPIC, HUMANS_TOPIC, ROBOTS_TOPIC, MOTION_TOPIC)
#: the entity marker topic of each kind
TOPICS = {HUMAN: HUMANS_TOPIC, ROBOT: ROBOTS_TOPIC, OBJECT: OBJECTS_TOPIC}


def live_rows(world: World) -> np.ndarray:
    """Rows of active entities that have a pose."""
    n = world.n
    return np.flatnonzero(world.active[:n] & (world.t_ns[:n] != NO_TIME))


def frame_of(world: World, row: int) -> str:
    """pdg's TF frame names: objects "/<id>", agents "<id>/base", joints "/<agent>/<joint>",
    each id one ROS name token (:func:`toaster.quoting.ros_name`: ``a b`` → ``x0a_20b``), so
    that every entity has a frame of its own."""
    kind = int(world.kind[row])
    if kind in (HUMAN, ROBOT):
        return f"{ros_name(world.ids[row])}/base"
    if kind == JOINT:
        owner = world.ids[int(world.owner[row])]
        return f"/{ros_name(owner)}/{ros_name(world.joint_names[row] or world.ids[row])}"
    return f"/{ros_name(world.ids[row])}"


def quats_of(world: World, rows: Sequence[int], yaw_only: bool = False) -> dict[int, Quat]:
    """Orientation (x, y, z, w) of each row (``yaw_only``: of its heading alone)."""
    rpy = world.rpy[np.asarray(rows, dtype=np.int64)]
    if yaw_only:
        rpy = rpy * [0.0, 0.0, 1.0]
    return {
        r: (x, y, z, w) for r, (x, y, z, w) in zip(rows, rpy_to_quats(rpy).tolist(), strict=True)
    }


def _xyz(values: Sequence[float]) -> dict[str, float]:
    return {"x": float(values[0]), "y": float(values[1]), "z": float(values[2])}


def _pose(position: Sequence[float], q: Quat = (0.0, 0.0, 0.0, 1.0)) -> dict[str, Any]:
    return {"position": _xyz(position), "orientation": {"x": q[0], "y": q[1], "z": q[2], "w": q[3]}}


def transforms(world: World) -> list[tuple[str, tuple[float, float, float], Quat, int]]:
    """(child frame, position, quaternion, stamp) of every live entity, parent "map"."""
    out = []
    rows = live_rows(world).tolist()
    quats = quats_of(world, rows)
    for r in rows:
        x, y, z = (float(v) for v in world.pos[r])
        out.append((frame_of(world, r), (x, y, z), quats[r], int(world.t_ns[r])))
    return out


def entity_list_fields(world: World, t_ns: int) -> dict[str, list[dict[str, Any]]]:
    """pdg/humanList, robotList, objectList items (toaster_msgs Human / Robot / Object)."""
    rows = live_rows(world).tolist()
    quats = quats_of(world, rows)
    joints: dict[int, list[int]] = {}
    for r in rows:
        if world.kind[r] == JOINT:
            joints.setdefault(int(world.owner[r]), []).append(r)

    def entity(r: int) -> dict[str, Any]:
        return {
            "id": world.ids[r],
            "name": world.names[r],
            "time": int(world.t_ns[r]),
            "pose": _pose(world.pos[r], quats[r]),
        }

    def agent(r: int) -> dict[str, Any]:
        skeleton = joints.get(r, [])
        return {
            "mobility": 0,
            "busyHands": world.busy_hands(world.ids[r]),
            "hasObjects": world.held_objects(world.ids[r]),
            "skeletonNames": [world.joint_names[j] for j in skeleton],
            "skeletonJoint": [
                {"jointOwner": world.ids[r], "position": 0.0, "meEntity": entity(j)}
                for j in skeleton
            ],
            "meEntity": entity(r),
        }

    out: dict[str, list[dict[str, Any]]] = {"human": [], "robot": [], "object": []}
    for r in rows:
        kind = int(world.kind[r])
        if kind == HUMAN:
            out["human"].append({"age": 0, "meAgent": agent(r)})
        elif kind == ROBOT:
            out["robot"].append({"maxSpeed": 0, "meAgent": agent(r)})
        elif kind == OBJECT:
            out["object"].append({"value": "", "meEntity": entity(r)})
    return out


# -- markers ------------------------------------------------------------------------------------
def marker(
    ns: str,
    mid: int,
    mtype: int,
    t_ns: int,
    *,
    pose: dict[str, Any] | None = None,
    scale: Sequence[float] = (1.0, 1.0, 1.0),
    color: Sequence[float] = (1.0, 1.0, 1.0),
    alpha: float = 1.0,
    points: Sequence[Sequence[float]] = (),
    text: str = "",
) -> dict[str, Any]:
    """One Marker's fields in the map frame."""
    return {
        "header": {"frame_id": FRAME, "stamp": t_ns},
        "ns": ns,
        "id": mid,
        "type": mtype,
        "action": ADD,
        "pose": pose or _pose((0.0, 0.0, 0.0)),
        "scale": _xyz(scale),
        "color": {"r": color[0], "g": color[1], "b": color[2], "a": alpha},
        "points": [_xyz(p) for p in points],
        "text": text,
        "frame_locked": False,
    }


def _clear(t_ns: int) -> dict[str, Any]:
    out = marker("", 0, CUBE, t_ns)
    out["action"] = DELETEALL
    return out


def _size(world: World, row: int) -> tuple[float, float, float]:
    size = world.size[row]
    default = DEFAULT_SIZE.get(int(world.kind[row]), (0.1, 0.1, 0.1))
    return tuple(
        float(s) if np.isfinite(s) and s > 0 else d  # type: ignore[return-value]
        for s, d in zip(size, default, strict=True)
    )


def entity_markers(world: World, t_ns: int) -> dict[str, list[dict[str, Any]]]:
    """Arrays by topic (:data:`TOPICS`): marker_human, marker_robot and marker_object."""
    out: dict[str, list[dict[str, Any]]] = {topic: [_clear(t_ns)] for topic in TOPICS.values()}
    rows = live_rows(world).tolist()
    quats, headings = quats_of(world, rows), quats_of(world, rows, yaw_only=True)
    ups = dict(zip(rows, rotation_matrices(world.rpy[rows])[:, :, 2].tolist(), strict=True))
    skeleton: dict[int, list[int]] = {}
    for r in rows:
        if world.kind[r] == JOINT:
            skeleton.setdefault(int(world.owner[r]), []).append(r)
    for r in rows:
        kind = int(world.kind[r])
        if kind == JOINT:
            continue
        topic, color, eid = TOPICS[kind], COLORS[kind], world.ids[r]
        sx, sy, sz = _size(world, r)
        x, y, z = (float(v) for v in world.pos[r])
        items = out[topic]
        if kind == OBJECT:
            # an object's box stands on its position (as the spatial producer sees it)
            q = quats[r]
            lift = [c * sz / 2 for c in ups[r]]
            items.append(
                marker(
                    eid,
                    0,
                    CUBE,
                    t_ns,
                    pose=_pose((x + lift[0], y + lift[1], z + lift[2]), q),
                    scale=(sx, sy, sz),
                    color=color,
                )
            )
        else:
            shape = CYLINDER if kind == HUMAN else CUBE
            items.append(
                marker(
                    eid,
                    0,
                    shape,
                    t_ns,
                    scale=(sx, sy, sz),
                    color=color,
                    alpha=0.8,
                    pose=_pose((x, y, z + sz / 2), headings[r]),
                )
            )
            items.append(
                marker(
                    eid,
                    2,
                    ARROW,
                    t_ns,
                    scale=(0.6, 0.08, 0.08),
                    color=color,
                    pose=_pose((x, y, z + 0.8 * sz), headings[r]),
                )
            )
            joints = skeleton.get(r, [])
            if joints:
                items.append(
                    marker(
                        eid,
                        3,
                        SPHERE_LIST,
                        t_ns,
                        scale=(0.08, 0.08, 0.08),
                        color=(1.0, 0.3, 0.3),
                        points=[world.pos[j].tolist() for j in joints],
                    )
                )
        items.append(
            marker(
                eid,
                1,
                TEXT,
                t_ns,
                pose=_pose((x, y, z + sz + 0.2)),
                scale=(0.2, 0.2, 0.2),
                color=color,
                text=world.names[r],
            )
        )
    return out


def _area_outline(world: World, spec: Mapping[str, Any]) -> tuple[list[list[float]], float]:
    """World corners of a polygon area (owner-relative areas turned and moved) and its z."""
    z = float(spec.get("z_min") or 0.0)
    points = [list(p) for p in spec.get("points", [])]
    owner = spec.get("owner") or ""
    if owner and owner in world.index:
        row = world.index[owner]
        turned = from_local_xy(np.asarray(points, float), world.pos[row, :2], world.rpy[row, 2])
        points = turned.tolist()
        z += float(world.pos[row, 2])
    return points, z


def area_markers(
    world: World, areas: Mapping[str, Mapping[str, Any]], occupied: set[str], t_ns: int
) -> list[dict[str, Any]]:
    """marker_area: polygons as closed lines, circles as flat discs, names above."""
    out = [_clear(t_ns)]
    for area_id, spec in sorted(areas.items()):
        busy = area_id in occupied
        color = (1.0, 0.5, 0.0) if busy else (0.0, 1.0, 0.0)
        owner = spec.get("owner") or ""
        if owner and owner not in world.index:
            continue  # an owner-relative area whose owner was never seen: nowhere to draw it
        if spec.get("shape") == "circle":
            cx, cy, *rest = spec["center"]
            cz = float(rest[0]) if rest else 0.0
            if owner:
                row = world.index[owner]
                turned = from_local_xy(
                    np.array([[cx, cy]], float), world.pos[row, :2], world.rpy[row, 2]
                )
                cx, cy = turned[0].tolist()
                cz += float(world.pos[row, 2])
            radius = float(spec["radius"])
            height = float(spec.get("height") or 0.02)
            out.append(
                marker(
                    area_id,
                    0,
                    CYLINDER,
                    t_ns,
                    pose=_pose((cx, cy, cz)),
                    scale=(2 * radius, 2 * radius, height),
                    color=color,
                    alpha=0.5 if busy else 0.25,
                )
            )
            label = (cx, cy, cz + 0.1)
        else:
            points, z = _area_outline(world, spec)
            ring = [[p[0], p[1], z] for p in [*points, points[0]]]
            out.append(
                marker(
                    area_id, 0, LINE_STRIP, t_ns, scale=(0.05, 0.0, 0.0), color=color, points=ring
                )
            )
            label = (
                sum(p[0] for p in points) / len(points),
                sum(p[1] for p in points) / len(points),
                z + 0.1,
            )
        out.append(
            marker(
                area_id,
                1,
                TEXT,
                t_ns,
                pose=_pose(label),
                scale=(0.3, 0.3, 0.3),
                color=color,
                text=area_id,
            )
        )
    return out


def _head(world: World, agent: int) -> int:
    for r in np.flatnonzero(world.owner[: world.n] == agent).tolist():
        if world.joint_names[r] == "head":
            return r
    return agent


def motion_markers(world: World, facts: Sequence[Fact], t_ns: int) -> list[dict[str, Any]]:
    """marker_motion: IsMoving arrows along the heading (length = speed over one second),
    IsMovingToward arrows to the target, IsLookingAt / IsLookingToward lines from the head."""
    out = [_clear(t_ns)]
    counts: dict[str, int] = {}
    index = world.index
    movers = {index.get(f.subject_id, -1) for f in facts if f.property == "IsMoving"}
    headings = quats_of(world, sorted(movers - {-1}), yaw_only=True)
    for fact in facts:
        s = index.get(fact.subject_id)
        if s is None:
            continue
        start = world.pos[s].tolist()
        target = index.get(fact.target_id) if fact.target_id else None
        ns = fact.property
        mid = counts[ns] = counts.get(ns, -1) + 1
        if fact.property == "IsMoving":
            length = max(0.2, float(fact.value_num or 0.0))
            out.append(
                marker(
                    ns,
                    mid,
                    ARROW,
                    t_ns,
                    scale=(length, 0.1, 0.1),
                    color=(1.0, 0.0, 0.0),
                    alpha=min(1.0, 0.3 + fact.confidence),
                    pose=_pose(start, headings[s]),
                )
            )
        elif fact.property == "IsMovingToward" and target is not None:
            out.append(
                marker(
                    ns,
                    mid,
                    ARROW,
                    t_ns,
                    scale=(0.05, 0.1, 0.15),
                    color=(1.0, 0.4, 0.0),
                    alpha=0.8,
                    points=[start, world.pos[target].tolist()],
                )
            )
        elif fact.property in ("IsLookingAt", "IsLookingToward") and target is not None:
            head = _head(world, s)
            color = (0.8, 0.0, 0.8) if fact.property == "IsLookingAt" else (0.4, 0.4, 1.0)
            out.append(
                marker(
                    ns,
                    mid,
                    LINE_LIST,
                    t_ns,
                    scale=(0.03, 0.0, 0.0),
                    color=color,
                    alpha=0.8,
                    points=[world.pos[head].tolist(), world.pos[target].tolist()],
                )
            )
    return out
