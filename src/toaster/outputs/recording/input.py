"""The input of a recording, checked before anything is written: frames ``(t_ns, entities,
areas)`` whose entities are :class:`EntityPose` (or tuples / mappings of its fields) and whose
areas are specs as ``toaster area add`` takes them (or fixed polygons), and the JSON-lines
frames files of ``toaster record``."""

from __future__ import annotations

import math
from collections.abc import Iterable, Mapping, Sequence
from itertools import pairwise
from pathlib import Path
from typing import Any, NamedTuple

from toaster.errors import InvalidInputError
from toaster.outputs.recording.msgs import EntityPose

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


# -- input checks -------------------------------------------------------------------------------
_POSE_HELP = "give (id, kind, x, y, z, yaw[, roll, pitch, size, owner, name, held_by, t_ns])"


def entity_poses(entities: Iterable[Any]) -> list[EntityPose]:
    """Checked poses of one frame; a joint's owner must be one of its humans or robots."""
    poses = [_entity(item) for item in entities]
    agents = {p.id for p in poses if p.kind in ("human", "robot")}
    for pose in poses:
        if pose.kind == "joint" and pose.owner not in agents:
            msg = (
                f"invalid entity pose {pose.id!r}: joint owner {pose.owner!r} is not a human "
                "or robot of the same frame"
            )
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
            str(values["id"]),
            kind if kind in KINDS else "object",
            x,
            y,
            z,
            yaw,
            float(values.get("roll") or 0.0),
            float(values.get("pitch") or 0.0),
            _size(values.get("size")),
            owner,
            str(values.get("name") or ""),
            str(values.get("held_by") or ""),
            None if values.get("t_ns") is None else int(values["t_ns"]),
        )
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
    from toaster.world.areaspec import normalize_area

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


def check_frames(frames: Iterable[Frame | Sequence[Any]]) -> list[Frame]:
    """Checked frames in time order, or a one-line error naming the first bad one."""
    frame_list = [_frame(f) for f in frames]
    for before, after in pairwise(frame_list):
        if after.t_ns < before.t_ns:
            msg = (
                f"frames out of time order: {after.t_ns} comes after {before.t_ns}; "
                "sort the frames by time"
            )
            raise InvalidInputError(msg)
    return frame_list


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
                frames.append(Frame(int(item["t_ns"]), item.get("entities", []), item.get("areas")))
            except (ValueError, KeyError, TypeError) as exc:
                msg = (
                    f"{Path(path).name} line {number}: not a frame ({exc}); write "
                    '{"t_ns": 0, "entities": [["pr2", "robot", 0, 0, 0, 0]]}'
                )
                raise FileFormatError(msg) from None
    return frames
