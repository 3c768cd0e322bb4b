"""area_manager: polygon and circle areas, owner-relative areas, hysteresis, area facts.

An area spec is a JSON-able dict (what the store keeps)::

    {"shape": "polygon", "points": [[x, y], ...],        # or "shape": "circle",
     "center": [x, y] | [x, y, z], "radius": r, "height": h,        # circle only
     "owner": "", "area_type": "", "facts": [],           # "interaction", "density"
     "entity_types": ["entities"], "z_min": None, "z_max": None,
     "enter_hysteresis": 0.0, "leave_hysteresis": 0.0}

Coordinates of an owned area are in the owner's frame (x forward, y left); the area moves and
turns with the owner. The vertical band is unbounded unless z_min / z_max (or a circle's
height) is given; it is shifted by the owner's z. Membership is a Schmitt trigger: an entity
enters when it crosses the inner boundary (shrunk by enter_hysteresis) and leaves when it
crosses the outer one (grown by leave_hysteresis). The owner and its joints are never inside.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely

from toaster.errors import InvalidInputError
from toaster.model import Fact
from toaster.producers.config import make_config, ns
from toaster.world.geometry import bearing, to_local_xy, wrap_angle
from toaster.world.state import HUMAN, JOINT, OBJECT, ROBOT, World

ENTITY_WORDS: dict[str, frozenset[int]] = {
    "human": frozenset({HUMAN}), "robot": frozenset({ROBOT}), "object": frozenset({OBJECT}),
    "joint": frozenset({JOINT}), "agent": frozenset({HUMAN, ROBOT}),
    "entity": frozenset({HUMAN, ROBOT, OBJECT}), "all": frozenset({HUMAN, ROBOT, OBJECT, JOINT}),
}
FACT_KINDS = frozenset({"interaction", "density"})


def entity_kinds(words: Any) -> frozenset[int]:
    """Kind codes named by entity-type words, singular or plural ("human", "agents", …)."""
    if isinstance(words, str):
        words = [w for w in words.replace(",", " ").split() if w]
    kinds: set[int] = set()
    for word in words or ["entities"]:
        key = str(word).lower().strip()
        key = key[:-3] + "y" if key.endswith("ies") else key.removesuffix("s")
        if key not in ENTITY_WORDS:
            msg = (f"unknown entity type {word!r}: use humans, robots, objects, joints, agents "
                   "or entities (singular is fine)")
            raise InvalidInputError(msg)
        kinds |= ENTITY_WORDS[key]
    return frozenset(kinds)


def _num(spec: Mapping[str, Any], key: str, area_id: str, default: float | None = None
         ) -> float | None:
    value = spec.get(key, default)
    if value is None:
        return None
    if isinstance(value, bool) or not isinstance(value, int | float) or not math.isfinite(value):
        msg = f"area {area_id!r}: {key} = {value!r} is not a number (metres)"
        raise InvalidInputError(msg)
    return float(value)


def normalize_area(area_id: str, spec: Mapping[str, Any]) -> dict[str, Any]:
    """Validate an area spec and return it with every key filled in (JSON-able)."""
    if not area_id:
        msg = "an area needs a non-empty name"
        raise InvalidInputError(msg)
    shape = str(spec.get("shape", "circle" if "radius" in spec else "polygon")).lower()
    out: dict[str, Any] = {"shape": shape, "owner": str(spec.get("owner", "") or "")}
    if shape == "polygon":
        points = spec.get("points")
        try:
            pts = [[float(p[0]), float(p[1])] for p in points]
        except (TypeError, ValueError, IndexError):
            pts = []
        if len(pts) < 3 or not shapely.Polygon(pts).is_valid:
            msg = (f"area {area_id!r}: points {points!r} do not make a simple polygon; give at "
                   "least three [x, y] corners in order")
            raise InvalidInputError(msg)
        out["points"] = pts
    elif shape == "circle":
        center = spec.get("center")
        if not isinstance(center, list | tuple) or len(center) not in (2, 3):
            msg = f"area {area_id!r}: center {center!r} must be [x, y] or [x, y, z]"
            raise InvalidInputError(msg)
        out["center"] = [float(c) for c in center]
        radius = _num(spec, "radius", area_id)
        if radius is None or radius <= 0:
            msg = f"area {area_id!r}: radius {spec.get('radius')!r} must be a positive number"
            raise InvalidInputError(msg)
        out["radius"] = radius
        out["height"] = _num(spec, "height", area_id)
    else:
        msg = f"area {area_id!r}: unknown shape {shape!r}; use polygon or circle"
        raise InvalidInputError(msg)
    out["area_type"] = str(spec.get("area_type", "") or "")
    facts = spec.get("facts", [])
    facts = list(facts.replace(",", " ").split()) if isinstance(facts, str) else list(facts)
    unknown = set(facts) - FACT_KINDS
    if unknown:
        msg = f"area {area_id!r}: unknown facts {sorted(unknown)}; use interaction and/or density"
        raise InvalidInputError(msg)
    out["facts"] = facts
    types = spec.get("entity_types", ["entities"])
    entity_kinds(types)
    out["entity_types"] = [types] if isinstance(types, str) else list(types)
    out["z_min"] = _num(spec, "z_min", area_id)
    out["z_max"] = _num(spec, "z_max", area_id)
    out["enter_hysteresis"] = _num(spec, "enter_hysteresis", area_id, 0.0) or 0.0
    out["leave_hysteresis"] = _num(spec, "leave_hysteresis", area_id, 0.0) or 0.0
    if out["enter_hysteresis"] < 0 or out["leave_hysteresis"] < 0:
        msg = f"area {area_id!r}: hysteresis must be ≥ 0 metres"
        raise InvalidInputError(msg)
    return out


def area_from_original(area: Mapping[str, Any]) -> tuple[str, dict[str, Any]]:
    """Convert an original area_manager add_area record (extracted_areas.json) to a spec.

    The original's zmin = zmax = 0 default becomes an unbounded band, a factType outside
    interaction / density is dropped, and singular entity types are accepted.
    """
    name = str(area["name"])
    fact_type = str(area.get("factType", ""))
    spec: dict[str, Any] = {
        "owner": str(area.get("myOwner", "") or ""), "area_type": area.get("areaType", ""),
        "facts": [f for f in ("interaction", "density") if f == fact_type],
        "entity_types": [area.get("entityType") or "entities"],
    }
    if area.get("isCircle"):
        c = area["center"]
        spec |= {"shape": "circle", "center": [c["x"], c["y"]], "radius": area["ray"]}
    else:
        pts = [p[:2] for p in area["poly"]]
        if len(pts) > 3 and pts[0] == pts[-1]:
            pts = pts[:-1]
        spec |= {"shape": "polygon", "points": pts}
    zmin, zmax = area.get("zmin"), area.get("zmax")
    if zmin is not None and zmax is not None and not zmin == zmax == 0:
        spec |= {"z_min": zmin, "z_max": zmax}
    return name, normalize_area(name, spec)


@dataclass
class _Compiled:
    area_id: str
    spec: dict[str, Any]
    kinds: np.ndarray
    inner: Any
    outer: Any
    bounds: tuple[float, float, float, float]
    z_lo: float
    z_hi: float


def _compile(area_id: str, spec: dict[str, Any]) -> _Compiled:
    enter, leave = spec["enter_hysteresis"], spec["leave_hysteresis"]
    z_lo = -np.inf if spec["z_min"] is None else spec["z_min"]
    z_hi = np.inf if spec["z_max"] is None else spec["z_max"]
    if spec["shape"] == "circle":
        cx, cy = spec["center"][:2]
        r = spec["radius"]
        inner, outer = (cx, cy, max(r - enter, 0.0)), (cx, cy, r + leave)
        bounds = (cx - r - leave, cy - r - leave, cx + r + leave, cy + r + leave)
        if spec["height"] is not None:
            cz = spec["center"][2] if len(spec["center"]) == 3 else 0.0
            z_lo, z_hi = cz - spec["height"] / 2, cz + spec["height"] / 2
    else:
        poly = shapely.Polygon(spec["points"])
        inner = poly.buffer(-enter, join_style="mitre") if enter else poly
        outer = poly.buffer(leave, join_style="mitre") if leave else poly
        shapely.prepare(inner)
        shapely.prepare(outer)
        bounds = tuple(outer.bounds)
    kinds = np.zeros(4, bool)
    kinds[list(entity_kinds(spec["entity_types"]))] = True
    return _Compiled(area_id, spec, kinds, inner, outer, bounds, z_lo, z_hi)


def _inside(shape: Any, xy: np.ndarray) -> np.ndarray:
    if isinstance(shape, tuple):
        cx, cy, r = shape
        return (xy[:, 0] - cx) ** 2 + (xy[:, 1] - cy) ** 2 <= r * r
    if shape.is_empty:
        return np.zeros(len(xy), bool)
    return shapely.intersects_xy(shape, xy[:, 0], xy[:, 1])


class AreaManager:
    """Computes IsInRoom / IsAt / IsInArea / IsFacing / AreaDensity for a set of areas."""

    name = "area_manager"

    def __init__(self, areas: Mapping[str, Mapping[str, Any]] | None = None,
                 config: Mapping[str, Any] | None = None) -> None:
        self.config = make_config(config)
        self._areas: dict[str, _Compiled] = {}
        self._state: dict[str, np.ndarray] = {}
        for area_id, spec in (areas or {}).items():
            self.set_area(area_id, spec)

    @property
    def areas(self) -> dict[str, dict[str, Any]]:
        """The normalised specs, by area name."""
        return {k: v.spec for k, v in self._areas.items()}

    def set_area(self, area_id: str, spec: Mapping[str, Any]) -> dict[str, Any]:
        """Add or replace an area (membership state starts empty)."""
        norm = normalize_area(area_id, spec)
        self._areas[area_id] = _compile(area_id, norm)
        self._state[area_id] = np.zeros(0, bool)
        return norm

    def remove_area(self, area_id: str) -> None:
        """Forget an area."""
        self._areas.pop(area_id, None)
        self._state.pop(area_id, None)

    def inside(self, area_id: str, world: World) -> list[str]:
        """Ids currently inside an area (after the last compute)."""
        state = self._state[area_id]
        return [world.ids[r] for r in np.flatnonzero(state)]

    def compute(self, world: World, t_ns: int) -> list[Fact]:
        """Update memberships and return this tick's area facts."""
        n = world.n
        live = world.live_mask(t_ns, ns(self.config, "presence_timeout"))
        kind, pos, owner_of = world.kind[:n], world.pos[:n], world.owner[:n]

        facts: list[Fact] = []
        for area_id, area in self._areas.items():
            state = np.zeros(n, bool)
            prev = self._state[area_id]
            state_prev = np.zeros(n, bool)
            state_prev[: len(prev)] = prev[:n]
            owner_id = area.spec["owner"]
            owner = world.index.get(owner_id, -1) if owner_id else -1
            if owner_id and (owner < 0 or not live[owner]):
                self._state[area_id] = state
                continue
            cand_mask = live & area.kinds[kind]
            if owner >= 0:
                cand_mask[owner] = False
                cand_mask &= owner_of != owner
            cand = np.flatnonzero(cand_mask)
            xy = pos[cand, :2]
            z = pos[cand, 2]
            z_lo, z_hi = area.z_lo, area.z_hi
            if owner >= 0:
                xy = to_local_xy(xy, pos[owner, :2], world.rpy[owner, 2])
                z_lo, z_hi = z_lo + pos[owner, 2], z_hi + pos[owner, 2]
            x0, y0, x1, y1 = area.bounds
            near = ((xy[:, 0] >= x0) & (xy[:, 0] <= x1) & (xy[:, 1] >= y0) & (xy[:, 1] <= y1)
                    & (z >= z_lo) & (z <= z_hi))
            cand, xy = cand[near], xy[near]
            in_outer = _inside(area.outer, xy)
            in_inner = in_outer if area.inner is area.outer else _inside(area.inner, xy)
            state[cand] = in_inner | (state_prev[cand] & in_outer)
            self._state[area_id] = state
            facts.extend(self._facts(world, area, owner, state, live))
        return facts

    def _facts(self, world: World, area: _Compiled, owner: int, state: np.ndarray,
               live: np.ndarray) -> list[Fact]:
        spec, area_id = area.spec, area.area_id
        rows = np.flatnonzero(state)
        owner_id = spec["owner"] if owner >= 0 else ""
        area_type = spec["area_type"]
        if area_type == "room":
            prop, sub = "IsInRoom", "room"
        elif area_type == "support":
            prop, sub = "IsAt", "location"
        else:
            prop, sub = "IsInArea", area_type
        obs = self.config["observability_area"]
        ids, owners = world.ids, world.owner
        facts = [Fact(ids[r], prop, area_id, "true", None, 1.0, obs, "position", sub,
                      ids[owners[r]] if owners[r] >= 0 else "", owner_id) for r in rows.tolist()]
        if "interaction" in spec["facts"] and owner >= 0 and rows.size:
            pos = world.pos
            angle = wrap_angle(world.rpy[rows, 2] - bearing(pos[rows, :2], pos[owner, :2]))
            limit = self.config["facing_angle"]
            conf = (limit - np.abs(angle)) / limit
            keep = conf > 0
            obs_facing = self.config["observability_facing"]
            facts.extend(
                Fact(ids[r], "IsFacing", owner_id, "true", a, c, obs_facing, "posture", "angle",
                     ids[owners[r]] if owners[r] >= 0 else "", "")
                for r, a, c in zip(rows[keep].tolist(), angle[keep].tolist(),
                                   conf[keep].tolist(), strict=True))
        if "density" in spec["facts"]:
            population = live & area.kinds[world.kind[: world.n]]
            if owner >= 0:
                population[owner] = False
                population &= world.owner[: world.n] != owner
            total = int(population.sum())
            ratio = rows.size / total if total else 0.0
            facts.append(Fact(area_id, "AreaDensity", "", "true", ratio, 1.0, 0.0, "density",
                              "ratio", owner_id, ""))
        return facts


LABELS = ((math.pi / 6, "ahead", "ahead"), (math.pi / 4, "ahead right", "ahead left"),
          (3 * math.pi / 4, "right", "left"), (5 * math.pi / 6, "back right", "back left"))


def direction_label(angle: float) -> str:
    """The original's labels for a wrapped angle (positive = to the right)."""
    a = abs(angle)
    for bound, right, left in LABELS:
        if a < bound:
            return right if angle > 0 else left
    return "back"


def relative_position(world: World, subject_id: str, target_id: str) -> tuple[str, float]:
    """Where the target is for the subject: (label, angle = wrap(yaw − bearing(S→T)))."""
    s, t = world.row(subject_id), world.row(target_id)
    angle = wrap_angle(world.rpy[s, 2] - bearing(world.pos[s, :2], world.pos[t, :2]))
    return direction_label(angle), float(angle)


def multiple_relative_position(world: World, agent_id: str, object_id: str,
                               target_id: str) -> tuple[str, float]:
    """Where the target is relative to the object, seen from the agent (sign bug fixed).

    angle = wrap(bearing(agent→object) − bearing(object→target)).
    """
    a, o, t = world.row(agent_id), world.row(object_id), world.row(target_id)
    p = world.pos
    angle = wrap_angle(bearing(p[a, :2], p[o, :2]) - bearing(p[o, :2], p[t, :2]))
    return direction_label(angle), float(angle)
