"""The indexed spatial producer gives the facts of the all-pairs computation, value for value.

The reference below is the producer as it was before the index (issue 28): every object in
every box's frame, every ray against every box in range. Scenes are random (seeded): tables,
containers (some closed, some on tables), rotated objects, held objects, agents with and
without heads, and objects exactly at the thresholds (on_gap, on_penetration, floor height,
next-to distance, arm reach, view range), under several configurations.
"""

from __future__ import annotations

import math

import numpy as np
import pytest

from toaster.model import Fact
from toaster.producers.batch import FactBatch
from toaster.producers.candidates import BoxIndex, azimuth_pairs, expand, window_pairs
from toaster.producers.spatial import POINTS, SpatialFacts, _ray_hits, collect_boxes
from toaster.world.config import ns
from toaster.world.state import World


def random_scene(seed: int, most: int = 60) -> tuple[World, dict]:
    """A random room; ``most`` caps the small objects."""
    rng = np.random.default_rng(seed)
    cfg = {
        "view_range": float(rng.choice([3.0, 8.0])),
        "view_aperture": float(rng.choice([2.0944, 3.6])),  # 3.6 > π: rays may go backwards
        "arm_reach": float(rng.choice([0.75, 1.2])),
        "next_to_distance": float(rng.choice([0.3, 0.05])),
    }
    side = float(rng.uniform(3, 14))
    world = World()
    ids: list[str] = []
    pos: list[list[float]] = []
    yaws: list[float] = []

    def place(eid: str, p: list[float], yaw: float = 0.0) -> None:
        ids.append(eid)
        pos.append([float(v) for v in p])
        yaws.append(yaw)

    def angle() -> float:
        return float(rng.uniform(-math.pi, math.pi))

    agents = []
    for i in range(int(rng.integers(1, 6))):
        a = f"A{i}"
        world.add_entity(a, "robot" if i % 3 == 2 else "human", size=None)
        if rng.random() < 0.4:
            world.set_shape(a, size=[0.4, 0.4, 1.5])
        if rng.random() < 0.7:
            world.add_entity(f"{a}/head", "joint", owner_id=a, name="head")
            pitch, yaw = float(rng.uniform(-0.4, 0.6)), float(rng.uniform(-1, 1))
            world.set_joint_local(f"{a}/head", (0.0, 0.0, 1.6), (0.0, pitch, yaw))
        world.add_entity(f"{a}/hand", "joint", owner_id=a, name="right_hand")
        world.set_joint_local(f"{a}/hand", (0.3, -0.2, 1.0))
        xy = rng.uniform(0, side, 2)
        place(a, [xy[0], xy[1], 0.0], angle())
        agents.append((a, xy))
    count = 0

    def new(size: list[float], role: str | None = None, closed: bool | None = None) -> str:
        nonlocal count
        eid = f"O{count}"
        count += 1
        world.add_entity(eid, size=size)
        world.set_shape(eid, role=role, closed=closed)
        return eid

    def within(centre: list[float], size: list[float], yaw: float, z: float) -> list[float]:
        u = rng.uniform(-0.5, 0.5, 2) * np.array(size[:2])
        c, s = math.cos(yaw), math.sin(yaw)
        return [centre[0] + c * u[0] - s * u[1], centre[1] + s * u[0] + c * u[1], z]

    gaps = [0.0, 0.05, -0.03, 0.05 + 1e-12, -0.03 - 1e-12, 0.05 * (1 - 1e-15), 0.2]
    tables = []
    for _ in range(int(rng.integers(0, 5))):
        size = [rng.uniform(0.6, 2.0), rng.uniform(0.5, 1.0), rng.uniform(0.4, 1.0)]
        xy, yaw = rng.uniform(0, side, 2), angle()
        place(new(size, "support"), [xy[0], xy[1], 0.0], yaw)
        tables.append(([xy[0], xy[1], 0.0], size, yaw))

    def on_table(height: float) -> list[float]:
        centre, size, yaw = tables[int(rng.integers(len(tables)))]
        return within(centre, size, yaw, size[2] + height + float(rng.choice(gaps)))

    boxes = []
    for _ in range(int(rng.integers(0, 5))):
        size = [rng.uniform(0.25, 0.7), rng.uniform(0.25, 0.7), rng.uniform(0.2, 0.5)]
        eid, yaw = new(size, "container", bool(rng.random() < 0.5)), angle()
        xy = rng.uniform(0, side, 2)
        p = on_table(0.0) if tables and rng.random() < 0.5 else [xy[0], xy[1], 0.0]
        place(eid, p, yaw)
        boxes.append((p, size, yaw))
    small: list[tuple[str, list[float], list[float]]] = []
    for _ in range(int(rng.integers(3, most))):
        size = rng.uniform(0.05, 0.35, 3).tolist()
        eid, yaw, r = new(size), angle(), rng.random()
        xy = rng.uniform(0, side, 2)
        if tables and r < 0.35:
            p = on_table(0.0)
        elif boxes and r < 0.55:
            centre, bsize, byaw = boxes[int(rng.integers(len(boxes)))]
            p = within(centre, bsize, byaw, centre[2] + float(rng.uniform(0, bsize[2] / 2)))
        elif r < 0.8:
            heights = [0.0, 0.05, 0.05 + 1e-12, 0.05 * (1 - 1e-16), 0.3]
            p = [xy[0], xy[1], float(rng.choice(heights))]
        elif small and r < 0.9:  # beside another, footprint gap at the next-to distance
            _, p0, s0 = small[int(rng.integers(len(small)))]
            step = cfg["next_to_distance"] + (s0[0] + s0[1]) / 4 + (size[0] + size[1]) / 4
            p, yaw = [p0[0] + step + float(rng.choice([0.0, 1e-12, -1e-12])), p0[1], p0[2]], 0.0
        else:  # in front of a shoulder at arm's reach
            _, a = agents[int(rng.integers(len(agents)))]
            step = cfg["arm_reach"] + size[0] / 2 + float(rng.choice([0.0, 1e-12, -1e-12]))
            p, yaw = [a[0] + step, a[1], 1.3 - size[2] / 2], 0.0
        place(eid, p, yaw)
        small.append((eid, p, size))
    for _, a in agents[:2]:  # at the view range's edge
        place(new([0.2, 0.2, 0.2]), [a[0] + cfg["view_range"] - 0.1, a[1], 1.5])
    rpy = np.column_stack([np.zeros((len(ids), 2)), yaws])
    world.observe("s", ids, np.zeros(len(ids), np.int64), np.array(pos), rpy)
    if rng.random() < 0.6:
        world.put_in_hand(small[0][0], agents[0][0], "right_hand")
    world.commit()
    return world, cfg


def reference(world: World, config: dict) -> list[Fact]:
    """The all-pairs computation (the producer before its index), facts sorted."""
    producer = SpatialFacts(config)
    cfg = producer.config
    out = FactBatch(world)
    b = collect_boxes(world, world.live_mask(0, ns(cfg, "presence_timeout")), cfg["agent_size"])
    nb, obs = len(b.rows), cfg["observability_spatial"]
    obj, ag = np.flatnonzero(~b.is_agent), np.flatnonzero(b.is_agent)
    ids = world.ids

    def local(pts: np.ndarray, idx: np.ndarray) -> np.ndarray:  # (..., 3) → (..., len(idx), 3)
        d = pts[..., None, :] - b.centre[idx]
        c, s = b.cos[idx], b.sin[idx]
        return np.stack(
            [c * d[..., 0] + s * d[..., 1], -s * d[..., 0] + c * d[..., 1], d[..., 2]], -1
        )

    role = np.array([world.roles.get(ids[r], "") for r in b.rows], object)
    closed = np.array([bool(world.closed.get(ids[r])) for r in b.rows], bool)
    free = obj[world.held_by[b.rows[obj]] < 0]
    cont = obj[role[obj] == "container"]
    sup = obj[(role[obj] == "support") | (role[obj] == "container")]
    container, support = np.full(nb, -1), np.full(nb, -1)
    vol = b.half.prod(axis=1)
    if cont.size and free.size:
        inside = (np.abs(local(b.centre[free], cont)) <= b.half[cont]).all(axis=-1)
        inside &= (free[:, None] != cont) & (vol[free][:, None] < vol[cont])
        best = np.where(inside, vol[cont], np.inf).argmin(axis=1)  # smallest, first of equals
        has = inside.any(axis=1)
        container[free[has]] = cont[best[has]]
    if sup.size and free.size:
        bottom = b.centre[free] - np.stack([0 * free, 0 * free, b.half[free, 2]], 1)
        loc, h = local(bottom, sup), b.half[sup]
        gap = loc[..., 2] - h[:, 2]
        on = (np.abs(loc[..., :2]) <= h[:, :2]).all(axis=-1) & (free[:, None] != sup)
        on &= (gap <= cfg["on_gap"]) & (gap >= -cfg["on_penetration"])
        on &= container[free][:, None] < 0
        best = np.where(on, b.centre[sup, 2] + h[:, 2], -np.inf).argmax(axis=1)
        has = on.any(axis=1)
        support[free[has]] = sup[best[has]]
    for prop, rel in (("IsIn", container), ("IsOn", support)):
        s = np.flatnonzero(rel >= 0)
        out.add(prop, b.rows[s], b.rows[rel[s]], obs=obs, property_type="position")
    out.add("IsClosed", b.rows[obj[closed[obj]]], "", obs=obs, property_type="state")
    # IsNextTo: every pair sharing a place; i before j in (x, box) order, as the sweep had it
    place = np.where(support >= 0, support, np.where(container >= 0, container + nb, -1))
    floor = (place == -1) & (np.abs(b.centre[:, 2] - b.half[:, 2]) <= cfg["floor_height"])
    place[(place == -1) & ~floor] = -2
    c = obj[(world.held_by[b.rows[obj]] < 0) & (place[obj] != -2)]
    c = c[np.lexsort((c, b.centre[c, 0]))]
    r = b.half[:, :2].mean(axis=1)
    rmax = {p: r[c[place[c] == p]].max() for p in set(place[c].tolist())}
    thr = cfg["next_to_distance"]
    i, j = np.triu_indices(len(c), 1)
    i, j = c[i], c[j]
    x, y = b.centre[:, 0], b.centre[:, 1]
    lim = np.array([rmax.get(p, 0.0) for p in place[i].tolist()])
    gap = np.hypot(x[i] - x[j], y[i] - y[j]) - r[i] - r[j]
    near = (place[i] == place[j]) & (x[j] <= x[i] + thr + 2 * lim) & (gap <= thr)  # the window
    i, j, gap = i[near], j[near], np.maximum(gap[near], 0.0)
    out.add(
        "IsNextTo",
        b.rows[np.r_[i, j]],
        b.rows[np.r_[j, i]],
        value_num=np.r_[gap, gap],
        obs=obs,
        property_type="position",
    )
    # visibility: every ray against every box in range and not behind the eyes
    hidden = np.zeros(nb, bool)
    for _ in range(4):
        hidden[container >= 0] = (
            closed[container[container >= 0]] | hidden[container[container >= 0]]
        )
    holder = np.full(nb, -1)
    box_of = {int(row): k for k, row in enumerate(b.rows)}
    for k in np.flatnonzero(world.held_by[b.rows] >= 0):
        holder[k] = box_of.get(int(world.owner[world.held_by[b.rows[k]]]), -1)
    frac = np.zeros((len(ag), nb))
    if ag.size and nb > 1:
        eye, gaze = producer._eyes(world, b.rows[ag])
        offs = POINTS * (2 * b.half)[:, None, :]
        cs, sn = b.cos[:, None], b.sin[:, None]
        turned = [cs * offs[..., 0] - sn * offs[..., 1], sn * offs[..., 0] + cs * offs[..., 1]]
        pts = b.centre[:, None, :] + np.stack([*turned, offs[..., 2]], axis=-1)
        radius = np.linalg.norm(b.half, axis=1)
        view = cfg["view_range"]
        for n, a in enumerate(ag.tolist()):
            d = pts - eye[n]
            dist = np.linalg.norm(d, axis=-1)
            seen = (dist <= view) & (d @ gaze[n] >= np.cos(cfg["view_aperture"] / 2) * dist)
            seen[a] = False
            seen[hidden] = False
            bi, ki = np.nonzero(seen)
            dc = b.centre - eye[n]
            dcn = np.linalg.norm(dc, axis=1)
            occ = (dcn - radius <= view) & ((dc @ gaze[n] >= -radius) | (dcn <= radius))
            occ[a] = False
            om = np.flatnonzero(occ)
            ray, o = np.repeat(np.arange(bi.size), om.size), np.tile(om, bi.size)
            hit = _ray_hits(np.repeat(eye[n : n + 1], ray.size, 0), pts[bi, ki][ray], b, o)
            t = bi[ray]
            hit &= (o != t) & (o != container[t]) & (o != holder[t])
            vis = ~np.bincount(ray[hit], minlength=bi.size).astype(bool)
            frac[n] = np.bincount(bi[vis], minlength=nb) / len(POINTS)
    ai, bi = np.nonzero(frac >= max(cfg["visible_min_fraction"], 1e-9))
    f = frac[ai, bi]
    agent, target = b.rows[ag[ai]], b.rows[bi]
    if ai.size:
        out.add(
            "IsVisibleBy", target, agent, value_num=f, conf=f, obs=obs, property_type="affordance"
        )
        out.add("CanSee", agent, target, value_num=f, conf=f, obs=obs, property_type="affordance")
    if ag.size and obj.size:
        shoulder = world.pos[b.rows[ag]] + np.array([0.0, 0.0, cfg["shoulder_height"]])
        gap = np.linalg.norm(np.maximum(np.abs(local(shoulder, obj)) - b.half[obj], 0.0), axis=-1)
        ai, oi = np.nonzero(gap <= cfg["arm_reach"])
        agent, target, g = b.rows[ag[ai]], b.rows[obj[oi]], gap[ai, oi]
        out.add("IsReachableBy", target, agent, value_num=g, obs=obs, property_type="affordance")
        out.add("CanReach", agent, target, value_num=g, obs=obs, property_type="affordance")
    return sorted(out.facts())


@pytest.mark.parametrize("first", range(0, 600, 100))
def test_indexed_facts_are_the_all_pairs_facts(first: int) -> None:
    kinds: set[str] = set()
    for seed in range(first, first + 100):
        world, cfg = random_scene(seed)
        want = reference(world, cfg)
        assert sorted(SpatialFacts(cfg).compute(world, 0)) == want, f"seed {seed}"
        kinds |= {f.property for f in want}
    assert len(kinds) == 8  # every fact kind occurs


def test_crowded_rooms() -> None:
    for seed in range(3):
        world, cfg = random_scene(1000 + seed, most=400)
        assert sorted(SpatialFacts(cfg).compute(world, 0)) == reference(world, cfg)


def test_edges_are_met() -> None:
    """The scenes do put facts at the thresholds (the cases an index loses first)."""
    at_reach = at_next_to = 0
    for seed in range(40):
        world, cfg = random_scene(seed)
        for f in SpatialFacts(cfg).compute(world, 0):
            at_reach += f.property == "CanReach" and abs(f.value_num - cfg["arm_reach"]) < 1e-9
            next_to = cfg["next_to_distance"]
            at_next_to += f.property == "IsNextTo" and abs(f.value_num - next_to) < 1e-9
    assert at_reach > 5 and at_next_to > 5


# -- the candidate generators against brute force ---------------------------------------------
def pairs(first: np.ndarray, second: np.ndarray) -> set[tuple[int, int]]:
    return set(zip(first.tolist(), second.tolist(), strict=True))


def test_expand() -> None:
    owner, pos = expand(np.array([3, 0, 5]), np.array([5, 0, 6]))
    assert owner.tolist() == [0, 0, 2] and pos.tolist() == [3, 4, 5]


def test_box_index_finds_every_overlap() -> None:
    rng = np.random.default_rng(1)
    lo = rng.uniform(0, 10, (300, 2))
    hi = lo + rng.uniform(0, 1, (300, 2))
    lo[7] = np.nan  # left out
    qlo = rng.uniform(-1, 10, (50, 2))
    qhi = qlo + rng.uniform(0, 3, (50, 2))
    index = BoxIndex(lo, hi, 0.0)
    got = pairs(*index.query(qlo, qhi))
    overlap = (qlo[:, None] <= hi).all(-1) & (lo <= qhi[:, None]).all(-1)
    assert got == pairs(*np.nonzero(overlap))
    mine = np.array([2, 7, 40])
    got = pairs(*index.query_boxes(mine))
    overlap = (lo[mine][:, None] <= hi).all(-1) & (lo <= hi[mine][:, None]).all(-1)
    want = {(int(mine[q]), int(t)) for q, t in zip(*np.nonzero(overlap), strict=True)}
    assert got == want and all(7 not in p for p in got)


def test_window_pairs() -> None:
    rng = np.random.default_rng(2)
    group = np.sort(rng.integers(0, 6, 200))
    x = rng.uniform(0, 20, 200)
    order = np.lexsort((x, group))
    group, x = group[order], x[order]
    limit = x + rng.uniform(0, 2, 200)
    i, j = np.triu_indices(200, 1)
    keep = (group[i] == group[j]) & (x[j] <= limit[i])
    got = window_pairs(group, x, limit)
    assert pairs(*got) == pairs(i[keep], j[keep])


def test_azimuth_pairs() -> None:
    rng = np.random.default_rng(3)
    ray_owner, ray_angle = rng.integers(0, 4, 300), rng.uniform(-np.pi, np.pi, 300)
    ray_angle[:4] = [np.pi, -np.pi, 0.0, np.pi / 2]
    occ_owner, occ_angle = rng.integers(0, 4, 80), rng.uniform(-np.pi, np.pi, 80)
    occ_half = rng.uniform(0, np.pi / 2, 80)
    occ_half[:5] = np.inf
    got = azimuth_pairs(ray_owner, ray_angle, occ_owner, occ_angle, occ_half)
    assert len(pairs(*got)) == len(got[0])  # each pair once
    diff = np.abs((ray_angle[:, None] - occ_angle + np.pi) % (2 * np.pi) - np.pi)
    want = (ray_owner[:, None] == occ_owner) & (diff <= occ_half)
    assert pairs(*got) == pairs(*np.nonzero(want))
