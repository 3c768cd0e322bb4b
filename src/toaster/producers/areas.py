"""area_manager: polygon and circle areas, owner-relative areas, hysteresis, area facts.

An area spec (its keys: :mod:`toaster.world.areaspec`) is a JSON-able dict.

Coordinates of an owned area are in the owner's frame (x forward, y left); the area moves and
turns with the owner. The vertical band is unbounded unless z_min / z_max (or a circle's
height) is given; it is shifted by the owner's z. Membership is a Schmitt trigger: an entity
enters when it crosses the inner boundary (shrunk by enter_hysteresis) and leaves when it
crosses the outer one (grown by leave_hysteresis). The owner and its joints are never inside.
"""

from __future__ import annotations

import math
import weakref
from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np
import shapely
from shapely.geometry.base import BaseGeometry

from toaster.model import Fact
from toaster.producers.batch import FactBatch
from toaster.producers.debounce import Debouncer
from toaster.world.areaspec import entity_kinds, normalize_area
from toaster.world.config import make_config, ns
from toaster.world.geometry import bearing, to_local_xy, wrap_angle
from toaster.world.state import World

#: A circle (centre x, centre y, radius) or a prepared shapely geometry.
_Shape = tuple[float, float, float] | BaseGeometry


@dataclass
class _Compiled:
    area_id: str
    spec: dict[str, Any]
    kinds: np.ndarray
    inner: _Shape
    outer: _Shape
    bounds: tuple[float, float, float, float]
    z_lo: float
    z_hi: float
    prop: str = "IsInArea"
    sub: str = ""


def _compile(area_id: str, spec: dict[str, Any]) -> _Compiled:
    enter, leave = spec["enter_hysteresis"], spec["leave_hysteresis"]
    inner: _Shape
    outer: _Shape
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
        inner_poly = poly.buffer(-enter, join_style="mitre") if enter else poly
        outer_poly = poly.buffer(leave, join_style="mitre") if leave else poly
        shapely.prepare(inner_poly)
        shapely.prepare(outer_poly)
        inner, outer = inner_poly, outer_poly
        x0, y0, x1, y1 = outer_poly.bounds
        bounds = (x0, y0, x1, y1)
    kinds = np.zeros(4, bool)
    kinds[list(entity_kinds(spec["entity_types"]))] = True
    area_type = spec["area_type"]
    if area_type == "room":
        prop, sub = "IsInRoom", "room"
    elif area_type == "support":
        prop, sub = "IsAt", "location"
    else:
        prop, sub = "IsInArea", area_type
    return _Compiled(area_id, spec, kinds, inner, outer, bounds, z_lo, z_hi, prop, sub)


def _inside(shape: _Shape, xy: np.ndarray) -> np.ndarray:
    if isinstance(shape, tuple):
        cx, cy, r = shape
        return (xy[:, 0] - cx) ** 2 + (xy[:, 1] - cy) ** 2 <= r * r
    if shape.is_empty:
        return np.zeros(len(xy), bool)
    return shapely.intersects_xy(shape, xy[:, 0], xy[:, 1])


_K = 1 << 32  # membership key = area slot × _K + row


class AreaManager:
    """Computes IsInRoom / IsAt / IsInArea / IsFacing / AreaDensity for a set of areas.

    Areas without owner are tested together: entities sorted by x, each area's bounding box
    picks its (entity, area) candidate pairs with two searchsorted calls, then one vectorised
    exact test per shape kind. Owned areas (few, moving) are tested one by one in their owner's
    frame. Memberships are kept as sorted int64 keys (slot × 2³² + row).
    """

    name = "area_manager"

    def __init__(
        self,
        areas: Mapping[str, Mapping[str, Any]] | None = None,
        config: Mapping[str, Any] | None = None,
    ) -> None:
        self.config = make_config(config)
        self._areas: dict[str, _Compiled] = {}
        self._keys = np.zeros(0, np.int64)
        self._slots: list[_Compiled] = []
        self._static: _StaticAreas | None = None
        self._runs: list[tuple[int, int, np.ndarray | None]] = []
        # IsFacing debounce per area: (compiled area, world, reported state by row)
        self._facing: dict[str, tuple[_Compiled, weakref.ref[World], Debouncer]] = {}
        for area_id, spec in (areas or {}).items():
            self.set_area(area_id, spec)

    @property
    def areas(self) -> dict[str, dict[str, Any]]:
        """The normalised specs, by area name."""
        return {k: v.spec for k, v in self._areas.items()}

    def _members(self) -> dict[str, np.ndarray]:
        slot = self._keys // _K
        return {a.area_id: self._keys[slot == i] % _K for i, a in enumerate(self._slots)}

    def _relayout(self, members: dict[str, np.ndarray]) -> None:
        self._slots = list(self._areas.values())
        parts = [
            i * _K + members.get(a.area_id, np.zeros(0, np.int64))
            for i, a in enumerate(self._slots)
        ]
        self._keys = np.sort(np.concatenate(parts)) if parts else np.zeros(0, np.int64)
        self._static = _StaticAreas(self._slots)
        self._runs = _runs(self._slots)

    def set_area(self, area_id: str, spec: Mapping[str, Any]) -> dict[str, Any]:
        """Add or replace an area (membership state starts empty)."""
        norm = normalize_area(area_id, spec)
        members = self._members()
        members.pop(area_id, None)
        self._areas[area_id] = _compile(area_id, norm)
        self._relayout(members)
        return norm

    def remove_area(self, area_id: str) -> None:
        """Forget an area."""
        members = self._members()
        if self._areas.pop(area_id, None) is not None:
            members.pop(area_id, None)
            self._relayout(members)

    def inside(self, area_id: str, world: World) -> list[str]:
        """Ids currently inside an area (after the last compute)."""
        rows = self._members()[area_id]
        return [world.ids[r] for r in rows.tolist()]

    def compute(self, world: World, t_ns: int) -> list[Fact]:
        """Update memberships and return this tick's area facts."""
        return self.compute_batch(world, t_ns).facts()

    def compute_batch(self, world: World, t_ns: int) -> FactBatch:
        """Update memberships and return this tick's area facts as arrays."""
        n = world.n
        out = FactBatch(world)
        if not self._slots:
            return out
        live = world.live_mask(t_ns, ns(self.config, "presence_timeout"))
        kind, pos, owner_of = world.kind[:n], world.pos[:n], world.owner[:n]
        prev = self._keys
        new_parts = []
        static = self._static
        assert static is not None
        if static.slots.size:
            new_parts.append(static.members(pos, kind, live, prev))
        owner_rows: dict[int, int] = {}
        for slot in static.owned:
            area = self._slots[slot]
            owner = world.index.get(area.spec["owner"], -1)
            if owner < 0 or not live[owner]:
                continue
            owner_rows[slot] = owner
            lo, hi = np.searchsorted(prev, [slot * _K, (slot + 1) * _K])
            prev_rows = prev[lo:hi] - slot * _K
            cand_mask = live & area.kinds[kind]
            cand_mask[owner] = False
            cand_mask &= owner_of != owner
            cand = np.flatnonzero(cand_mask)
            xy = to_local_xy(pos[cand, :2], pos[owner, :2], world.rpy[owner, 2])
            z = pos[cand, 2]
            z_lo, z_hi = area.z_lo + pos[owner, 2], area.z_hi + pos[owner, 2]
            x0, y0, x1, y1 = area.bounds
            near = (
                (xy[:, 0] >= x0)
                & (xy[:, 0] <= x1)
                & (xy[:, 1] >= y0)
                & (xy[:, 1] <= y1)
                & (z >= z_lo)
                & (z <= z_hi)
            )
            cand, xy = cand[near], xy[near]
            in_outer = _inside(area.outer, xy)
            in_inner = in_outer if area.inner is area.outer else _inside(area.inner, xy)
            was = _in_sorted(cand, prev_rows)
            new_parts.append(slot * _K + cand[in_inner | (was & in_outer)])
        keys = np.sort(np.concatenate(new_parts)) if new_parts else np.zeros(0, np.int64)
        self._keys = keys
        bounds = np.searchsorted(keys, np.arange(len(self._slots) + 1, dtype=np.int64) * _K)
        rows_all = keys % _K
        kind_count = None
        obs = self.config["observability_area"]
        for start, end, labels in self._runs:
            if labels is not None:  # areas with memberships only: one group for the run
                counts = bounds[start + 1 : end + 1] - bounds[start:end]
                area = self._slots[start]
                out.add(
                    area.prop,
                    rows_all[bounds[start] : bounds[end]],
                    (np.repeat(np.arange(end - start), counts), labels),
                    obs=obs,
                    property_type="position",
                    sub_property=area.sub,
                )
                continue
            area = self._slots[start]
            owner = owner_rows.get(start, -1)
            if area.spec["owner"] and owner < 0:
                continue
            rows = rows_all[bounds[start] : bounds[start + 1]]
            if "density" in area.spec["facts"] and owner < 0 and kind_count is None:
                kind_count = np.bincount(kind[live], minlength=4)
            self._facts(world, area, owner, rows, live, kind_count, out)
        return out

    def _facing_debouncer(self, world: World, area: _Compiled) -> Debouncer:
        """The IsFacing state of an area, new when the area or the world changed."""
        got = self._facing.get(area.area_id)
        if got is None or got[0] is not area or got[1]() is not world:
            got = (area, weakref.ref(world), Debouncer(ns(self.config, "min_duration", "IsFacing")))
            self._facing[area.area_id] = got
        return got[2]

    def _facts(
        self,
        world: World,
        area: _Compiled,
        owner: int,
        rows: np.ndarray,
        live: np.ndarray,
        kind_count: np.ndarray | None,
        out: FactBatch,
    ) -> None:
        spec, area_id = area.spec, area.area_id
        owner_id = spec["owner"] if owner >= 0 else ""
        prop, sub = area.prop, area.sub
        out.add(
            prop,
            rows,
            area_id,
            obs=self.config["observability_area"],
            property_type="position",
            sub_property=sub,
            tgt_owner=owner_id,
        )
        if "interaction" in spec["facts"] and owner >= 0 and rows.size:
            pos = world.pos
            angle = wrap_angle(world.rpy[rows, 2] - bearing(pos[rows, :2], pos[owner, :2]))
            limit = self.config["facing_angle"]
            conf = (limit - np.abs(angle)) / limit
            # debounced (min_duration["IsFacing"]); a held fact keeps the measured angle
            clock = np.maximum(world.t_ns[: world.n], world.t_ns[owner])
            keep = self._facing_debouncer(world, area).update(rows, conf > 0, clock)
            out.add(
                "IsFacing",
                rows[keep],
                owner_id,
                value_num=angle[keep],
                conf=np.maximum(conf[keep], 0.0),
                obs=self.config["observability_facing"],
                property_type="posture",
                sub_property="angle",
            )
        if "density" in spec["facts"]:
            if owner >= 0:
                population = live & area.kinds[world.kind[: world.n]]
                population[owner] = False
                population &= world.owner[: world.n] != owner
                total = int(population.sum())
            else:
                assert kind_count is not None  # counted for every unowned density area
                total = int(kind_count[area.kinds].sum())
            ratio = rows.size / total if total else 0.0
            out.add(
                "AreaDensity",
                area_id,
                "",
                value_num=ratio,
                conf=1.0,
                obs=0.0,
                property_type="density",
                sub_property="ratio",
                subj_owner=owner_id,
            )


def _runs(slots: list[_Compiled]) -> list[tuple[int, int, np.ndarray | None]]:
    """The slots as runs (start, end, labels): consecutive areas without owner that give
    their memberships only (no density), of one property and sub-property, are one run whose
    facts are one group (their ids as target labels, in slot order: the facts and their
    order of one group per area); any other area is a run of its own (labels None)."""
    runs: list[tuple[int, int, np.ndarray | None]] = []
    start = 0
    while start < len(slots):
        area = slots[start]
        if area.spec["owner"] or "density" in area.spec["facts"]:
            runs.append((start, start + 1, None))
            start += 1
            continue
        end = start + 1
        while end < len(slots):
            other = slots[end]
            if other.spec["owner"] or "density" in other.spec["facts"]:
                break
            if (other.prop, other.sub) != (area.prop, area.sub):
                break
            end += 1
        labels = np.array([a.area_id for a in slots[start:end]], dtype=object)
        runs.append((start, end, labels))
        start = end
    return runs


def _in_sorted(values: np.ndarray, sorted_keys: np.ndarray) -> np.ndarray:
    """``np.isin(values, sorted_keys)`` for a sorted key array (cheaper than np.isin)."""
    if len(sorted_keys) == 0:
        return np.zeros(len(values), bool)
    pos = np.minimum(np.searchsorted(sorted_keys, values), len(sorted_keys) - 1)
    return sorted_keys[pos] == values


class _StaticAreas:
    """Areas without owner, compiled to arrays for a vectorised membership test."""

    def __init__(self, slots: list[_Compiled]) -> None:
        static = [i for i, a in enumerate(slots) if not a.spec["owner"]]
        self.owned = [i for i, a in enumerate(slots) if a.spec["owner"]]
        self.slots = np.asarray(static, np.int64)
        areas = [slots[i] for i in static]
        b = np.asarray([a.bounds for a in areas], float).reshape(-1, 4)
        self.x0, self.y0, self.x1, self.y1 = b.T
        self.z_lo = np.asarray([a.z_lo for a in areas], float)
        self.z_hi = np.asarray([a.z_hi for a in areas], float)
        self.kinds = np.asarray([a.kinds for a in areas], bool).reshape(-1, 4)
        self.any_kind: np.ndarray = np.asarray(self.kinds.any(axis=0), bool)  # (4,)
        self.circle = np.asarray([isinstance(a.outer, tuple) for a in areas], bool)
        self.same = np.asarray([a.inner is a.outer for a in areas], bool)
        none = (0.0, 0.0, 0.0)
        circ = [
            (a.outer, a.inner)
            if isinstance(a.outer, tuple) and isinstance(a.inner, tuple)
            else (none, none)
            for a in areas
        ]
        self.cx = np.asarray([c[0][0] for c in circ], float)
        self.cy = np.asarray([c[0][1] for c in circ], float)
        self.r_out = np.asarray([c[0][2] for c in circ], float)
        self.r_in = np.asarray([c[1][2] for c in circ], float)
        self.outer = np.asarray(
            [None if isinstance(a.outer, tuple) else a.outer for a in areas] + [None], object
        )[:-1]
        self.inner = np.asarray(
            [None if isinstance(a.inner, tuple) else a.inner for a in areas] + [None], object
        )[:-1]

    def members(
        self, pos: np.ndarray, kind: np.ndarray, live: np.ndarray, prev: np.ndarray
    ) -> np.ndarray:
        """New membership keys of the static areas (unsorted)."""
        cand = np.flatnonzero(live & self.any_kind[kind])
        if cand.size == 0:
            return np.zeros(0, np.int64)
        x = pos[cand, 0]
        order = np.argsort(x, kind="stable")
        xs = x[order]
        lo = np.searchsorted(xs, self.x0, side="left")
        hi = np.searchsorted(xs, self.x1, side="right")
        counts = np.maximum(hi - lo, 0)
        total = int(counts.sum())
        if total == 0:
            return np.zeros(0, np.int64)
        area = np.repeat(np.arange(len(counts)), counts)
        start = np.cumsum(counts) - counts
        ent = cand[order[np.arange(total) - np.repeat(start - lo, counts)]]
        p = pos[ent]
        ok = (
            (p[:, 1] >= self.y0[area])
            & (p[:, 1] <= self.y1[area])
            & (p[:, 2] >= self.z_lo[area])
            & (p[:, 2] <= self.z_hi[area])
            & self.kinds[area, kind[ent]]
        )
        area, ent, p = area[ok], ent[ok], p[ok]
        circle = self.circle[area]
        in_outer = np.empty(len(area), bool)
        in_inner = np.empty(len(area), bool)
        c = np.flatnonzero(circle)
        if c.size:
            ac = area[c]
            d2 = (p[c, 0] - self.cx[ac]) ** 2 + (p[c, 1] - self.cy[ac]) ** 2
            in_outer[c] = d2 <= self.r_out[ac] * self.r_out[ac]
            in_inner[c] = d2 <= self.r_in[ac] * self.r_in[ac]
        g = np.flatnonzero(~circle)
        if g.size:
            ag = area[g]
            in_outer[g] = shapely.intersects_xy(self.outer[ag], p[g, 0], p[g, 1])
            same = self.same[ag]
            in_inner[g] = in_outer[g]
            diff = g[~same]
            if diff.size:
                in_inner[diff] = shapely.intersects_xy(
                    self.inner[area[diff]], p[diff, 0], p[diff, 1]
                )
        keys = self.slots[area] * _K + ent
        was = _in_sorted(keys, prev)
        return keys[in_inner | (was & in_outer)]


LABELS = (
    (math.pi / 6, "ahead", "ahead"),
    (math.pi / 4, "ahead right", "ahead left"),
    (3 * math.pi / 4, "right", "left"),
    (5 * math.pi / 6, "back right", "back left"),
)


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
    angle = float(wrap_angle(world.rpy[s, 2] - bearing(world.pos[s, :2], world.pos[t, :2])))
    return direction_label(angle), angle


def multiple_relative_position(
    world: World, agent_id: str, object_id: str, target_id: str
) -> tuple[str, float]:
    """Where the target is relative to the object, seen from the agent (sign bug fixed).

    angle = wrap(bearing(agent→object) − bearing(object→target)).
    """
    a, o, t = world.row(agent_id), world.row(object_id), world.row(target_id)
    p = world.pos
    angle = float(wrap_angle(bearing(p[a, :2], p[o, :2]) - bearing(p[o, :2], p[t, :2])))
    return direction_label(angle), angle
