"""move3d_facts: spatial relations and perspective taking from oriented boxes, vectorised.

Shapes: every live object with a size and every live agent (``agent_size`` when it has none) is a
box standing on its position (x, y centred, z from the position up), turned by its yaw. Roles
(``World.roles``): ``support`` (table, shelf) and ``container`` (box, basket); ``World.closed``
marks containers with their lid on. Held objects follow the hand (``World.commit``).

Facts per tick: IsOn, IsIn (innermost container), IsNextTo (same support or floor), IsClosed,
IsVisibleBy / CanSee (cone of ``view_aperture`` around the gaze of the head joint, or of the body
at ``eye_height``, within ``view_range``; rays from the eyes to 5 points of the target are tested
against the other boxes with a numpy slab test; confidence = visible share; nothing inside a
closed container is visible), IsReachableBy / CanReach (shoulder to nearest box point within
``arm_reach``). :func:`relative_position_from` answers "left / right / in front / behind / above /
below" from an agent's viewpoint on request.

Only candidate pairs are tested (``candidates.py``: an STRtree of the boxes' footprints queried
with each relation's distance, rays against the occluders spanning their azimuth); the tests
are those of the all-pairs computation, so are the facts.
"""

from __future__ import annotations

from collections.abc import Mapping
from dataclasses import dataclass
from typing import Any

import numpy as np

from toaster.model import Fact
from toaster.producers.batch import FactBatch
from toaster.producers.candidates import BoxIndex, azimuth_pairs, footprint, margin, window_pairs
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
SUPPORT, CONTAINER = 1, 2  # role codes
ROLES = {"support": SUPPORT, "container": CONTAINER}


@dataclass
class Boxes:
    """The tick's boxes: world rows, centres, half sizes, yaw cos/sin, roles, closed, holder."""

    rows: np.ndarray
    centre: np.ndarray
    half: np.ndarray
    cos: np.ndarray
    sin: np.ndarray
    is_agent: np.ndarray
    role: np.ndarray  # 0, SUPPORT or CONTAINER
    closed: np.ndarray
    holder: np.ndarray  # box of the agent holding it, -1

    def local(self, pts: np.ndarray, idx: np.ndarray) -> np.ndarray:
        """World points (P, 3) in the frames of boxes ``idx`` (P,): (P, 3)."""
        d = pts - self.centre[idx]
        c, s = self.cos[idx], self.sin[idx]
        x = c * d[:, 0] + s * d[:, 1]
        y = -s * d[:, 0] + c * d[:, 1]
        return np.stack([x, y, d[:, 2]], axis=-1)

    def index(self) -> BoxIndex:
        """The boxes' footprints in a spatial index."""
        lo, hi = footprint(self.centre, self.half, self.cos, self.sin)
        return BoxIndex(lo, hi, margin(self.centre))


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
    box_of = np.full(n + 1, -1)
    box_of[rows] = np.arange(rows.size)
    role, closed = np.zeros(n + 1, np.int8), np.zeros(n + 1, bool)
    index = world.index
    role[[index.get(e, n) for e in world.roles]] = [ROLES.get(r, 0) for r in world.roles.values()]
    closed[[index.get(e, n) for e in world.closed]] = [bool(c) for c in world.closed.values()]
    hand = world.held_by[rows]
    owner = np.where(hand >= 0, world.owner[np.maximum(hand, 0)], n)
    holder = box_of[np.where(owner >= 0, owner, n)]
    return Boxes(
        rows,
        centre,
        sz / 2,
        np.cos(yaw),
        np.sin(yaw),
        kind[rows] <= ROBOT,
        role[rows],
        closed[rows],
        holder,
    )


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


def _ray_hits(eye: np.ndarray, pts: np.ndarray, boxes: Boxes, o: np.ndarray) -> np.ndarray:
    """(P,) hits of the segments eye → pts (P, 3) with boxes ``o`` (P,), in float32."""
    f4 = np.float32
    c, s = boxes.cos[o].astype(f4), boxes.sin[o].astype(f4)
    centre = boxes.centre[o].astype(f4)
    half = boxes.half[o].astype(f4)
    e = eye.astype(f4) - centre
    ex, ey = c * e[:, 0] + s * e[:, 1], -s * e[:, 0] + c * e[:, 1]
    p = pts.astype(f4)
    dx = p[:, 0] - centre[:, 0]
    dy = p[:, 1] - centre[:, 1]
    px, py = c * dx + s * dy, -s * dx + c * dy
    pz = p[:, 2] - centre[:, 2]
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
        index = boxes.index()
        container, support = self._relations(world, boxes, obj, index, out)
        self._closed(boxes, obj, out)
        self._next_to(world, boxes, obj, container, support, out)
        hidden = self._hidden(boxes, container)
        self._visibility(world, boxes, container, hidden, out, index)
        self._reach(world, boxes, obj, index, out)
        return out

    # -- object relations -------------------------------------------------------------------
    def _relations(
        self, world: World, boxes: Boxes, obj: np.ndarray, index: BoxIndex, out: FactBatch
    ) -> tuple[np.ndarray, np.ndarray]:
        """IsIn (innermost container) and IsOn (highest support); per box, -1 for none.

        Pairs (support or container, object) whose bounding boxes overlap, tested exactly.
        """
        cfg, nb = self.config, len(boxes.rows)
        role = np.zeros(nb, np.int8)
        role[obj] = boxes.role[obj]
        free = ~boxes.is_agent & (world.held_by[boxes.rows] < 0)
        container = np.full(nb, -1)
        support = np.full(nb, -1)
        s, f = index.query_boxes(np.flatnonzero(role > 0))
        keep = free[f] & (f != s)
        s, f = s[keep], f[keep]
        vol = boxes.half.prod(axis=1)
        c, fi = s[role[s] == CONTAINER], f[role[s] == CONTAINER]
        if c.size:
            local, h = boxes.local(boxes.centre[fi], c), boxes.half[c]
            inside = (
                (np.abs(local[:, 0]) <= h[:, 0])
                & (np.abs(local[:, 1]) <= h[:, 1])
                & (np.abs(local[:, 2]) <= h[:, 2])
                & (vol[fi] < vol[c])
            )
            c, fi = c[inside], fi[inside]
            first = _first_of(fi, np.lexsort((c, vol[c], fi)))  # smallest, then lowest box
            container[fi[first]] = c[first]
        if s.size:
            bottom = boxes.centre[f] - np.stack([0 * f, 0 * f, boxes.half[f, 2]], 1)
            local, h = boxes.local(bottom, s), boxes.half[s]
            gap = local[:, 2] - h[:, 2]
            on = (
                (np.abs(local[:, 0]) <= h[:, 0])
                & (np.abs(local[:, 1]) <= h[:, 1])
                & (gap <= cfg["on_gap"])
                & (gap >= -cfg["on_penetration"])
                & (container[f] < 0)
            )
            s, f = s[on], f[on]
            top = boxes.centre[s, 2] + boxes.half[s, 2]
            first = _first_of(f, np.lexsort((s, -top, f)))  # highest, then lowest box
            support[f[first]] = s[first]
        obs = cfg["observability_spatial"]
        for prop, rel in (("IsIn", container), ("IsOn", support)):
            b = np.flatnonzero(rel >= 0)
            out.add(prop, boxes.rows[b], boxes.rows[rel[b]], obs=obs, property_type="position")
        return container, support

    def _closed(self, boxes: Boxes, obj: np.ndarray, out: FactBatch) -> None:
        rows = boxes.rows[obj[boxes.closed[obj]]]
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
        """IsNextTo both ways between objects sharing a support, a container or the floor.

        Per place, objects sorted by x; a pair is tested when the second lies within the
        next-to distance plus the place's largest footprint diameter in x from the first.
        """
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
        keep = ~held & (place != -2) & np.isfinite(boxes.centre[obj, :2]).all(axis=1)
        cand, place = obj[keep], place[keep]
        if cand.size < 2:
            return
        radius = boxes.half[:, :2].mean(axis=1)
        order = np.lexsort((np.arange(cand.size), boxes.centre[cand, 0], place))
        g, place = cand[order], place[order]
        x, y, r = boxes.centre[g, 0], boxes.centre[g, 1], radius[g]
        starts = np.flatnonzero(np.r_[True, place[1:] != place[:-1]])
        rmax = np.repeat(np.maximum.reduceat(r, starts), np.diff(np.r_[starts, len(g)]))
        limit = x + cfg["next_to_distance"] + 2 * rmax
        i, j = window_pairs(place, x, limit)
        far = np.abs(y[i] - y[j]) > (limit[i] - x[i]) * (1 + 1e-9) + 1e-9  # gap > distance
        i, j = i[~far], j[~far]
        gap = np.hypot(x[i] - x[j], y[i] - y[j]) - r[i] - r[j]
        near = gap <= cfg["next_to_distance"]
        i, j, gap = i[near], j[near], np.maximum(gap[near], 0.0)
        out.add(
            "IsNextTo",
            boxes.rows[g[np.r_[i, j]]],
            boxes.rows[g[np.r_[j, i]]],
            value_num=np.r_[gap, gap],
            obs=cfg["observability_spatial"],
            property_type="position",
        )

    # -- perception --------------------------------------------------------------------------
    def _hidden(self, boxes: Boxes, container: np.ndarray) -> np.ndarray:
        """Boxes inside a closed container (transitively)."""
        hidden = np.zeros(len(boxes.rows), bool)
        has = container >= 0
        for _ in range(4):
            c = container[has]
            hidden[has] = boxes.closed[c] | hidden[c]
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
        self,
        world: World,
        boxes: Boxes,
        container: np.ndarray,
        hidden: np.ndarray,
        index: BoxIndex | None = None,
    ) -> tuple[np.ndarray, np.ndarray]:
        """(agent box indices, (A, B) share of target points seen by each agent).

        Boxes within the view range of an eye (index) give the rays; each ray is tested only
        against the occluders whose footprint it may cross (:func:`azimuth_pairs`).
        """
        cfg, nb, k = self.config, len(boxes.rows), len(POINTS)
        ag = np.flatnonzero(boxes.is_agent)
        frac = np.zeros((len(ag), nb))
        if not ag.size or nb < 2:
            return ag, frac
        index = index or boxes.index()
        eye, gaze = self._eyes(world, boxes.rows[ag])
        view = cfg["view_range"]
        a, b = index.query(eye[:, :2] - view, eye[:, :2] + view)  # (agent, box) near enough
        keep = b != ag[a]
        a, b = a[keep], b[keep]
        # rays: the target points in range and in the cone
        t = ~hidden[b]
        ta, tb = a[t], b[t]
        offs = POINTS * (2 * boxes.half[tb])[:, None, :]  # (P, K, 3) in box frames
        c, s = boxes.cos[tb, None], boxes.sin[tb, None]
        pts = boxes.centre[tb, None, :] + np.stack(
            [
                c * offs[..., 0] - s * offs[..., 1],
                s * offs[..., 0] + c * offs[..., 1],
                offs[..., 2],
            ],
            axis=-1,
        )  # (P, K, 3)
        d = pts - eye[ta, None, :]
        dist = np.linalg.norm(d, axis=-1)
        cone = (d @ gaze[ta, :, None])[..., 0] >= np.cos(cfg["view_aperture"] / 2) * dist
        pi, ki = np.nonzero((dist <= view) & cone)
        ray_agent, ray_target, ray_end = ta[pi], tb[pi], pts[pi, ki]
        # occluders: in range and not behind the eyes (as the all-pairs test culls them)
        radius = np.linalg.norm(boxes.half[b], axis=1)
        dc = boxes.centre[b] - eye[a]
        dcn = np.linalg.norm(dc, axis=1)
        ahead = (dc[:, None, :] @ gaze[a, :, None])[:, 0, 0] >= -radius
        occ = (dcn - radius <= view) & (ahead | (dcn <= radius))
        oa, ob, dc = a[occ], b[occ], dc[occ]
        pad = index.pad
        reach = np.hypot(boxes.half[ob, 0], boxes.half[ob, 1]) + pad  # footprint circle
        dist2 = np.hypot(dc[:, 0], dc[:, 1])
        half_angle = np.where(
            dist2 > reach, np.arcsin(np.minimum(reach / np.maximum(dist2, pad), 1.0)), np.inf
        )
        re = ray_end - eye[ray_agent]
        ri, oi = azimuth_pairs(
            ray_agent,
            np.arctan2(re[:, 1], re[:, 0]),
            oa,
            np.arctan2(dc[:, 1], dc[:, 0]),
            half_angle,
        )
        o, tgt = ob[oi], ray_target[ri]
        keep = (
            (o != tgt)
            & (o != container[tgt])
            & (o != boxes.holder[tgt])
            & (dist2[oi] - reach[oi] <= np.hypot(re[ri, 0], re[ri, 1]) + pad)
        )
        ri, o = ri[keep], o[keep]
        hit = np.zeros(len(ray_agent), bool)
        hit[ri[_ray_hits(eye[ray_agent[ri]], ray_end[ri], boxes, o)]] = True
        seen = np.bincount(ray_agent[~hit] * nb + ray_target[~hit], minlength=frac.size)
        return ag, seen.reshape(frac.shape) / k

    def _visibility(
        self,
        world: World,
        boxes: Boxes,
        container: np.ndarray,
        hidden: np.ndarray,
        out: FactBatch,
        index: BoxIndex | None = None,
    ) -> None:
        cfg = self.config
        ag, frac = self.visible_fraction(world, boxes, container, hidden, index)
        ai, bi = np.nonzero(frac >= max(cfg["visible_min_fraction"], 1e-9))
        if not ai.size:
            return
        agent, target, f = boxes.rows[ag[ai]], boxes.rows[bi], frac[ai, bi]
        obs = cfg["observability_spatial"]
        out.add(
            "IsVisibleBy", target, agent, value_num=f, conf=f, obs=obs, property_type="affordance"
        )
        out.add("CanSee", agent, target, value_num=f, conf=f, obs=obs, property_type="affordance")

    def _reach(
        self, world: World, boxes: Boxes, obj: np.ndarray, index: BoxIndex, out: FactBatch
    ) -> None:
        """Shoulder to the nearest point of the box, for boxes within arm's reach (index)."""
        cfg = self.config
        ag = np.flatnonzero(boxes.is_agent)
        if not ag.size or not obj.size:
            return
        shoulder = world.pos[boxes.rows[ag]] + np.array([0.0, 0.0, cfg["shoulder_height"]])
        reach = cfg["arm_reach"]
        a, o = index.query(shoulder[:, :2] - reach, shoulder[:, :2] + reach)
        keep = ~boxes.is_agent[o]
        a, o = a[keep], o[keep]
        local = boxes.local(shoulder[a], o)
        gap = np.linalg.norm(np.maximum(np.abs(local) - boxes.half[o], 0.0), axis=-1)
        near = gap <= reach
        order = np.lexsort((o[near], a[near]))
        a, o, gap = a[near][order], o[near][order], gap[near][order]
        agent, target = boxes.rows[ag[a]], boxes.rows[o]
        obs = cfg["observability_spatial"]
        out.add("IsReachableBy", target, agent, value_num=gap, obs=obs, property_type="affordance")
        out.add("CanReach", agent, target, value_num=gap, obs=obs, property_type="affordance")


def _first_of(key: np.ndarray, order: np.ndarray) -> np.ndarray:
    """Indices of the first element of each run of equal keys in ``order``."""
    k = key[order]
    return order[np.r_[True, k[1:] != k[:-1]]] if k.size else order


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
