"""move3d_facts: spatial relations and perspective taking from oriented boxes, vectorised.

Shapes: every live object with a size and every live agent (``agent_size`` when it has none) is a
box standing on its position (x, y centred, z from the position up), turned by its yaw. Roles
(``World.roles``): ``support`` (table, shelf) and ``container`` (box, basket); ``World.closed``
marks containers with their lid on. Held objects follow the hand (``World.commit``).

Facts per tick: IsOn, IsIn (innermost container), IsNextTo (same support or floor), IsClosed,
IsVisibleBy / CanSee (cone of ``view_aperture`` around the gaze of the head joint, or of the body
at ``eye_height``, within ``view_range``; rays from the eyes to 5 points of the target are tested
against every other box with a numpy slab test; confidence = visible share; nothing inside a
closed container is visible), IsReachableBy / CanReach (shoulder to nearest box point within
``arm_reach``). :func:`relative_position_from` answers "left / right / in front / behind / above /
below" from an agent's viewpoint on request.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from toaster.model import Fact
from toaster.producers.batch import FactBatch
from toaster.world.config import make_config, ns
from toaster.world.geometry import gaze_axis, to_local
from toaster.world.state import OBJECT, ROBOT, World

#: Target sample points, as fractions of the box size from its centre.
POINTS = np.array(
    [
        [0.0, 0.0, 0.0],
        [0.35, 0.35, 0.35],
        [0.35, -0.35, 0.35],
        [-0.35, 0.35, 0.35],
        [-0.35, -0.35, 0.35],
    ]
)


@dataclass
class Boxes:
    """The tick's boxes: world rows, centres, half sizes, yaw cos/sin, roles."""

    rows: np.ndarray
    centre: np.ndarray
    half: np.ndarray
    cos: np.ndarray
    sin: np.ndarray
    is_agent: np.ndarray

    def subset(self, idx: np.ndarray) -> Boxes:
        """The boxes ``idx``."""
        return Boxes(
            self.rows[idx],
            self.centre[idx],
            self.half[idx],
            self.cos[idx],
            self.sin[idx],
            self.is_agent[idx],
        )

    def to_local(self, pts: np.ndarray) -> np.ndarray:
        """World points (..., 3) into every box frame: (..., n_boxes, 3)."""
        d = pts[..., None, :] - self.centre
        x = self.cos * d[..., 0] + self.sin * d[..., 1]
        y = -self.sin * d[..., 0] + self.cos * d[..., 1]
        return np.stack([x, y, d[..., 2]], axis=-1)


def collect_boxes(world: World, live: np.ndarray, agent_size: Any) -> Boxes:
    """Boxes of live sized objects and of live agents (default size for agents)."""
    n = world.n
    kind = world.kind[:n]
    size = world.size[:n].copy()
    agents = live & (kind <= ROBOT)
    size[agents & np.isnan(size).any(axis=1)] = agent_size
    rows = np.flatnonzero((live & (kind == OBJECT) & np.isfinite(size).all(axis=1)) | agents)
    sz = size[rows]
    centre = world.pos[rows] + np.stack([0 * sz[:, 0], 0 * sz[:, 0], sz[:, 2] / 2], axis=1)
    yaw = world.rpy[rows, 2]
    return Boxes(rows, centre, sz / 2, np.cos(yaw), np.sin(yaw), kind[rows] <= ROBOT)


def segment_hits(p0: np.ndarray, p1: np.ndarray, half: np.ndarray) -> np.ndarray:
    """Slab test: does the segment p0 → p1 (local frames, (..., 3)) cross the box ±half?"""
    p0, p1, half = np.broadcast_arrays(p0, p1, half)
    return _slabs(
        [p0[..., a] for a in range(3)],
        [p1[..., a] for a in range(3)],
        [half[..., a] for a in range(3)],
    )


def _slabs(p0: list[np.ndarray], p1: list[np.ndarray], half: list[np.ndarray]) -> np.ndarray:
    """Slab test on per-axis arrays (broadcasting), no reductions over a short last axis."""
    near, far = _slab(p0[0], p1[0], half[0])
    for a in (1, 2):
        lo, hi = _slab(p0[a], p1[a], half[a])
        np.maximum(near, lo, out=near)
        np.minimum(far, hi, out=far)
    return (near < far) & (far > 0.0) & (near < 1.0)


def _slab(p0: np.ndarray, p1: np.ndarray, half: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Entry and exit parameters of the segment p0 → p1 through the slab ±half of one axis."""
    d = p1 - p0
    d[np.abs(d) < 1e-12] = 1e-12
    inv = np.reciprocal(d, out=d)
    t1 = (-half - p0) * inv
    t2 = (half - p0) * inv
    return np.minimum(t1, t2), np.maximum(t1, t2)


def _ray_hits(eye: np.ndarray, pts: np.ndarray, boxes: Boxes, om: np.ndarray) -> np.ndarray:
    """(R, M) hits of the segments eye → pts (R, 3) with boxes ``om``, in float32."""
    f4 = np.float32
    c, s = boxes.cos[om].astype(f4), boxes.sin[om].astype(f4)
    centre = boxes.centre[om].astype(f4)
    half = boxes.half[om].astype(f4)
    e = eye.astype(f4) - centre  # (M, 3)
    ex, ey = c * e[:, 0] + s * e[:, 1], -s * e[:, 0] + c * e[:, 1]
    p = pts.astype(f4)
    dx = p[:, 0:1] - centre[:, 0]
    dy = p[:, 1:2] - centre[:, 1]
    px, py = c * dx + s * dy, -s * dx + c * dy
    pz = p[:, 2:3] - centre[:, 2]
    return _slabs([ex, ey, e[:, 2]], [px, py, pz], [half[:, 0], half[:, 1], half[:, 2]])


class SpatialFacts:
    """IsOn, IsIn, IsNextTo, IsClosed, IsVisibleBy/CanSee, IsReachableBy/CanReach."""

    name = "move3d_facts"

    def __init__(self, config: Mapping[str, Any] | None = None) -> None:
        self.config = make_config(config)
        self._heads: tuple[int, dict[int, int]] = (-1, {})

    def compute(self, world: World, t_ns: int) -> list[Fact]:
        """Facts for this tick."""
        return self.compute_batch(world, t_ns).facts()

    def compute_batch(self, world: World, t_ns: int) -> FactBatch:
        """Facts for this tick, as arrays."""
        cfg = self.config
        out = FactBatch(world)
        live = world.live_mask(t_ns, ns(cfg, "presence_timeout"))
        boxes = collect_boxes(world, live, cfg["agent_size"])
        obj = np.flatnonzero(~boxes.is_agent)  # box indices of objects
        container, support = self._relations(world, boxes, obj, out)
        self._closed(world, boxes, obj, out)
        self._next_to(world, boxes, obj, container, support, out)
        hidden = self._hidden(world, boxes, container)
        self._visibility(world, boxes, container, hidden, out)
        self._reach(world, boxes, obj, out)
        return out

    # -- object relations -------------------------------------------------------------------
    def _relations(
        self, world: World, boxes: Boxes, obj: np.ndarray, out: FactBatch
    ) -> tuple[np.ndarray, np.ndarray]:
        """IsIn (innermost container) and IsOn (highest support); per box, -1 for none."""
        cfg, nb = self.config, len(boxes.rows)
        ids = world.ids
        role = np.array([world.roles.get(ids[r], "") for r in boxes.rows.tolist()], object)
        held = world.held_by[boxes.rows] >= 0
        container = np.full(nb, -1)
        support = np.full(nb, -1)
        cont = obj[role[obj] == "container"]
        sup = obj[(role[obj] == "support") | (role[obj] == "container")]
        free = obj[~held[obj]]
        if cont.size and free.size:
            local = boxes.subset(cont).to_local(boxes.centre[free])  # (F, C, 3)
            h = boxes.half[cont]
            inside = (
                (np.abs(local[..., 0]) <= h[:, 0])
                & (np.abs(local[..., 1]) <= h[:, 1])
                & (np.abs(local[..., 2]) <= h[:, 2])
                & (free[:, None] != cont[None, :])
            )
            vol = h.prod(axis=1)
            inside &= boxes.half[free].prod(axis=1)[:, None] < vol[None, :]
            score = np.where(inside, vol[None, :], np.inf)
            best = score.argmin(axis=1)
            has = np.isfinite(score[np.arange(len(free)), best])
            container[free[has]] = cont[best[has]]
        if sup.size and free.size:
            bottom = boxes.centre[free] - np.stack([0 * free, 0 * free, boxes.half[free, 2]], 1)
            local = boxes.subset(sup).to_local(bottom)
            h = boxes.half[sup]
            gap = local[..., 2] - h[:, 2]
            on = (
                (np.abs(local[..., 0]) <= h[:, 0])
                & (np.abs(local[..., 1]) <= h[:, 1])
                & (gap <= cfg["on_gap"])
                & (gap >= -cfg["on_penetration"])
                & (free[:, None] != sup[None, :])
                & (container[free][:, None] < 0)
            )
            top = np.where(on, boxes.centre[sup, 2] + h[:, 2], -np.inf)
            best = top.argmax(axis=1)
            has = np.isfinite(top[np.arange(len(free)), best])
            support[free[has]] = sup[best[has]]
        obs = cfg["observability_spatial"]
        for prop, rel in (("IsIn", container), ("IsOn", support)):
            s = np.flatnonzero(rel >= 0)
            out.add(prop, boxes.rows[s], boxes.rows[rel[s]], obs=obs, property_type="position")
        return container, support

    def _closed(self, world: World, boxes: Boxes, obj: np.ndarray, out: FactBatch) -> None:
        ids = world.ids
        rows = np.array([r for r in boxes.rows[obj].tolist() if world.closed.get(ids[r])], np.int64)
        out.add(
            "IsClosed", rows, "", obs=self.config["observability_spatial"], property_type="state"
        )

    def _next_to(
        self,
        world: World,
        boxes: Boxes,
        obj: np.ndarray,
        container: np.ndarray,
        support: np.ndarray,
        out: FactBatch,
    ) -> None:
        """IsNextTo both ways between objects sharing a support, a container or the floor."""
        cfg = self.config
        held = world.held_by[boxes.rows[obj]] >= 0
        bottom = boxes.centre[obj, 2] - boxes.half[obj, 2]
        place = np.where(
            support[obj] >= 0,
            support[obj],
            np.where(container[obj] >= 0, container[obj] + len(boxes.rows), -1),
        )
        floor = (place == -1) & (np.abs(bottom) <= cfg["floor_height"])
        place = np.where((place == -1) & ~floor, -2, place)
        keep = ~held & (place != -2)
        cand, place = obj[keep], place[keep]
        if cand.size < 2:
            return
        order = np.argsort(place, kind="stable")
        cand, place = cand[order], place[order]
        starts = np.flatnonzero(np.r_[True, place[1:] != place[:-1]])
        ends = np.r_[starts[1:], len(place)]
        subj, tgt, dist = [], [], []
        radius = boxes.half[:, :2].mean(axis=1)
        for a, b in zip(starts.tolist(), ends.tolist(), strict=True):
            if b - a < 2:
                continue
            g = cand[a:b]
            g = g[np.argsort(boxes.centre[g, 0], kind="stable")]
            x, y, r = boxes.centre[g, 0], boxes.centre[g, 1], radius[g]
            hi = np.searchsorted(x, x + cfg["next_to_distance"] + 2 * r.max(), side="right")
            first = np.arange(len(g))
            counts = hi - first - 1
            i = np.repeat(first, counts)
            j = np.arange(counts.sum()) - np.repeat(np.cumsum(counts) - counts, counts) + i + 1
            gap = np.hypot(x[i] - x[j], y[i] - y[j]) - r[i] - r[j]
            near = gap <= cfg["next_to_distance"]
            i, j, gap = i[near], j[near], np.maximum(gap[near], 0.0)
            subj.append(g[np.r_[i, j]])
            tgt.append(g[np.r_[j, i]])
            dist.append(np.r_[gap, gap])
        if subj:
            s, t = np.concatenate(subj), np.concatenate(tgt)
            out.add(
                "IsNextTo",
                boxes.rows[s],
                boxes.rows[t],
                value_num=np.concatenate(dist),
                obs=cfg["observability_spatial"],
                property_type="position",
            )

    # -- perception --------------------------------------------------------------------------
    def _hidden(self, world: World, boxes: Boxes, container: np.ndarray) -> np.ndarray:
        """Boxes inside a closed container (transitively)."""
        ids = world.ids
        closed = np.array([bool(world.closed.get(ids[r])) for r in boxes.rows.tolist()], bool)
        hidden = np.zeros(len(boxes.rows), bool)
        has = container >= 0
        for _ in range(4):
            c = container[has]
            hidden[has] = closed[c] | hidden[c]
        return hidden

    def _eyes(self, world: World, agents: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Eye positions and gaze axes of agent rows (head joint, else body at eye height)."""
        version = world._version
        if self._heads[0] != version:
            self._heads = (version, {})
        heads = self._heads[1]
        head = np.array(
            [
                heads.setdefault(a, world.joint_of(world.ids[a], self.config["head_joint"]))
                for a in agents.tolist()
            ],
            np.int64,
        )
        has = head >= 0
        eye = world.pos[agents] + np.array([0.0, 0.0, self.config["eye_height"]])
        rpy = world.rpy[agents].copy()
        eye[has] = world.pos[head[has]]
        rpy[has] = world.rpy[head[has]]
        return eye, gaze_axis(rpy)

    def visible_fraction(
        self, world: World, boxes: Boxes, container: np.ndarray, hidden: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """(agent box indices, (A, B) share of target points seen by each agent)."""
        cfg, nb, k = self.config, len(boxes.rows), len(POINTS)
        ag = np.flatnonzero(boxes.is_agent)
        frac = np.zeros((len(ag), nb))
        if not ag.size or nb < 2:
            return ag, frac
        eye, gaze = self._eyes(world, boxes.rows[ag])
        offs = POINTS * (2 * boxes.half)[:, None, :]  # (B, K, 3) in box frames
        c, s = boxes.cos[:, None], boxes.sin[:, None]
        pts = boxes.centre[:, None, :] + np.stack(
            [
                c * offs[..., 0] - s * offs[..., 1],
                s * offs[..., 0] + c * offs[..., 1],
                offs[..., 2],
            ],
            axis=-1,
        )  # (B, K, 3)
        cos_half = np.cos(cfg["view_aperture"] / 2)
        radius = np.linalg.norm(boxes.half, axis=1)
        holder = np.full(nb, -1)
        held = world.held_by[boxes.rows]
        if (held >= 0).any():
            box_of = {int(r): i for i, r in enumerate(boxes.rows.tolist())}
            for i in np.flatnonzero(held >= 0).tolist():
                holder[i] = box_of.get(int(world.owner[held[i]]), -1)
        for i, a in enumerate(ag.tolist()):
            d = pts - eye[i]
            dist = np.linalg.norm(d, axis=-1)
            seen = (dist <= cfg["view_range"]) & (d @ gaze[i] >= cos_half * dist)
            seen[a] = False
            seen[hidden] = False
            bi, ki = np.nonzero(seen)
            if not bi.size:
                continue
            # occluders that may lie between the eye and the view cone
            dc = boxes.centre - eye[i]
            dcn = np.linalg.norm(dc, axis=1)
            occ = (dcn - radius <= cfg["view_range"]) & (
                (dc @ gaze[i] >= -radius) | (dcn <= radius)
            )
            occ[a] = False
            om = np.flatnonzero(occ)
            if om.size:
                where = np.full(nb, -1)
                where[om] = np.arange(om.size)
                hit = _ray_hits(eye[i], pts[bi, ki], boxes, om)
                r = np.arange(bi.size)
                for excl in (bi, container[bi], holder[bi]):
                    col = np.where(excl >= 0, where[np.maximum(excl, 0)], -1)
                    ok = col >= 0
                    hit[r[ok], col[ok]] = False
                vis = ~hit.any(axis=1)
                bi = bi[vis]
            frac[i] = np.bincount(bi, minlength=nb) / k
        return ag, frac

    def _visibility(
        self, world: World, boxes: Boxes, container: np.ndarray, hidden: np.ndarray, out: FactBatch
    ) -> None:
        cfg = self.config
        ag, frac = self.visible_fraction(world, boxes, container, hidden)
        ai, bi = np.nonzero(frac >= max(cfg["visible_min_fraction"], 1e-9))
        if not ai.size:
            return
        agent, target, f = boxes.rows[ag[ai]], boxes.rows[bi], frac[ai, bi]
        obs = cfg["observability_spatial"]
        out.add(
            "IsVisibleBy", target, agent, value_num=f, conf=f, obs=obs, property_type="affordance"
        )
        out.add("CanSee", agent, target, value_num=f, conf=f, obs=obs, property_type="affordance")

    def _reach(self, world: World, boxes: Boxes, obj: np.ndarray, out: FactBatch) -> None:
        cfg = self.config
        ag = np.flatnonzero(boxes.is_agent)
        if not ag.size or not obj.size:
            return
        shoulder = world.pos[boxes.rows[ag]] + np.array([0.0, 0.0, cfg["shoulder_height"]])
        local = boxes.subset(obj).to_local(shoulder)  # (A, O, 3)
        h = boxes.half[obj]
        gap = np.linalg.norm(np.maximum(np.abs(local) - h, 0.0), axis=-1)
        ai, oi = np.nonzero(gap <= cfg["arm_reach"])
        agent, target = boxes.rows[ag[ai]], boxes.rows[obj[oi]]
        obs = cfg["observability_spatial"]
        out.add(
            "IsReachableBy",
            target,
            agent,
            value_num=gap[ai, oi],
            obs=obs,
            property_type="affordance",
        )
        out.add(
            "CanReach", agent, target, value_num=gap[ai, oi], obs=obs, property_type="affordance"
        )


# -- relative position on request ---------------------------------------------------------------
RELATIVE_WORDS = (("in front", "behind"), ("left", "right"), ("above", "below"))


def relative_position_from(
    world: World,
    viewer_id: str,
    object_id: str,
    reference_id: str | None = None,
    *,
    threshold: float = 0.1,
    config: Mapping[str, Any] | None = None,
) -> tuple[list[str], list[float]]:
    """Where ``object_id`` is, seen from ``viewer_id``: relative to the viewer or to a reference.

    Returns (words, [forward, left, up] in metres in the viewer's heading frame): words among
    "in front"/"behind", "left"/"right", "above"/"below", strongest first, for components beyond
    ``threshold``. The heading is the head joint's yaw, else the body's.
    """
    cfg = make_config(config)
    facts = SpatialFacts(cfg)
    v = world.row(viewer_id)
    eye, _ = facts._eyes(world, np.array([v]))
    head = world.joint_of(viewer_id, cfg["head_joint"])
    yaw = float(world.rpy[head if head >= 0 else v, 2])

    def centre(entity: str) -> np.ndarray:
        r = world.row(entity)
        size = world.size[r]
        if world.kind[r] <= ROBOT and np.isnan(size).any():
            size = np.asarray(cfg["agent_size"], float)
        return world.pos[r] + [0.0, 0.0, 0.0 if np.isnan(size[2]) else size[2] / 2]

    origin = eye[0] if reference_id is None else centre(reference_id)
    d = centre(object_id) - origin
    local = to_local(d, np.array([0.0, 0.0, yaw])).tolist()
    order = np.argsort(-np.abs(local), kind="stable")
    words = [
        RELATIVE_WORDS[i][0 if local[i] > 0 else 1]
        for i in order.tolist()
        if abs(local[i]) > threshold
    ]
    return words, local
