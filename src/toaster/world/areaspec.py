"""Area specs: what an area is (shape, owner, band, hysteresis, facts), checked and completed.

An area spec is a JSON-able dict (what the store keeps)::

    {"shape": "polygon", "points": [[x, y], ...],        # or "shape": "circle",
     "center": [x, y] | [x, y, z], "radius": r, "height": h,        # circle only
     "owner": "", "area_type": "", "facts": [],           # "interaction", "density"
     "entity_types": ["entities"], "z_min": None, "z_max": None,
     "enter_hysteresis": 0.0, "leave_hysteresis": 0.0}

Input files, the ROS bridge and recordings check specs here; the area_manager producer
(:mod:`toaster.producers.areas`) computes the facts. shapely is imported only to check a polygon.
"""

from __future__ import annotations

import math
from collections.abc import Mapping
from typing import Any

from toaster.errors import InvalidInputError
from toaster.world.state import HUMAN, JOINT, OBJECT, ROBOT

ENTITY_WORDS: dict[str, frozenset[int]] = {
    "human": frozenset({HUMAN}),
    "robot": frozenset({ROBOT}),
    "object": frozenset({OBJECT}),
    "joint": frozenset({JOINT}),
    "agent": frozenset({HUMAN, ROBOT}),
    "entity": frozenset({HUMAN, ROBOT, OBJECT}),
    "all": frozenset({HUMAN, ROBOT, OBJECT, JOINT}),
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
            msg = (
                f"unknown entity type {word!r}: use humans, robots, objects, joints, agents "
                "or entities (singular is fine)"
            )
            raise InvalidInputError(msg)
        kinds |= ENTITY_WORDS[key]
    return frozenset(kinds)


def _num(
    spec: Mapping[str, Any], key: str, area_id: str, default: float | None = None
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
            pts = [[float(p[0]), float(p[1])] for p in points or ()]
        except (TypeError, ValueError, IndexError):
            pts = []
        import shapely  # here: `toaster --help` loads no shapely

        if len(pts) < 3 or not shapely.Polygon(pts).is_valid:
            msg = (
                f"area {area_id!r}: points {points!r} do not make a simple polygon; give at "
                "least three [x, y] corners in order"
            )
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
        "owner": str(area.get("myOwner", "") or ""),
        "area_type": area.get("areaType", ""),
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
