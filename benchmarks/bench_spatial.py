"""move3d_facts tick (IsOn/IsIn/IsNextTo/visibility with occlusion/reach) vs a naive Python loop.

Run: .venv/bin/python benchmarks/bench_spatial.py [--quick]
World: 10 agents with heads in a room sized for the object count, objects of 0.1-0.6 m (every
box is an occluder, agents included), a tenth of them tables (supports), a tenth boxes
(containers, half closed). Median of repeated ticks, one core (numpy single-threaded work): wall
time and the thread's CPU time (steadier on a shared machine).
"""

from __future__ import annotations

import argparse
import math
import statistics
import time

import numpy as np

from toaster.producers.spatial import POINTS, SpatialFacts
from toaster.world import World

S = 1_000_000_000


def build(n_objects: int, n_agents: int = 10, seed: int = 0) -> World:
    rng = np.random.default_rng(seed)
    side = math.sqrt(n_objects / 0.5)  # 0.5 object per m²
    world = World()
    for i in range(n_agents):
        world.add_entity(f"h{i}", "human")
        world.add_entity(f"h{i}/head", "joint", owner_id=f"h{i}", name="head")
        world.set_joint_local(f"h{i}/head", (0.0, 0.0, 1.6))
    for i in range(n_objects):
        world.add_entity(f"o{i}", size=rng.uniform(0.1, 0.6, 3).tolist())
        if i % 10 == 0:
            world.set_shape(f"o{i}", role="support", size=[1.2, 0.8, 0.75])
        elif i % 10 == 1:
            world.set_shape(f"o{i}", role="container", closed=bool(i % 20 == 1))
    world.observe(
        "b",
        [f"h{i}" for i in range(n_agents)],
        np.zeros(n_agents, np.int64),
        np.column_stack([rng.uniform(0, side, (n_agents, 2)), np.zeros(n_agents)]),
        np.column_stack([np.zeros((n_agents, 2)), rng.uniform(-3, 3, n_agents)]),
    )
    pos = np.column_stack([rng.uniform(0, side, (n_objects, 2)), np.zeros(n_objects)])
    world.observe(
        "b",
        [f"o{i}" for i in range(n_objects)],
        np.zeros(n_objects, np.int64),
        pos,
        np.column_stack([np.zeros((n_objects, 2)), rng.uniform(-3, 3, n_objects)]),
    )
    world.commit()
    return world


def naive(world: World, producer: SpatialFacts) -> dict[tuple[int, int], float]:
    """Same visibility (and reach, IsOn, IsIn, IsNextTo) with plain Python loops per pair."""
    cfg = producer.config
    rows = [r for r in range(world.n) if world.kind[r] != 3]
    boxes = []
    for r in rows:
        size = world.size[r] if world.kind[r] == 2 else cfg["agent_size"]
        x, y, z = world.pos[r].tolist()
        yaw = float(world.rpy[r, 2])
        boxes.append(
            (
                r,
                (x, y, z + size[2] / 2),
                (size[0] / 2, size[1] / 2, size[2] / 2),
                math.cos(yaw),
                math.sin(yaw),
            )
        )

    def local(p, box):
        _, c, _, co, si = box
        dx, dy, dz = p[0] - c[0], p[1] - c[1], p[2] - c[2]
        return (co * dx + si * dy, -si * dx + co * dy, dz)

    def hits(p0, p1, half):
        near, far = -math.inf, math.inf
        for a in range(3):
            d = p1[a] - p0[a]
            if abs(d) < 1e-12:
                d = 1e-12
            t1, t2 = (-half[a] - p0[a]) / d, (half[a] - p0[a]) / d
            near, far = max(near, min(t1, t2)), min(far, max(t1, t2))
        return near < far and far > 0 and near < 1

    cos_half = math.cos(cfg["view_aperture"] / 2)
    out: dict[tuple[int, int], float] = {}
    agents = [b for b in boxes if world.kind[b[0]] <= 1]
    for ag in agents:
        head = world.joint_of(world.ids[ag[0]], "head")
        eye = world.pos[head].tolist()
        yaw = float(world.rpy[head, 2])
        pitch = float(world.rpy[head, 1])
        gaze = (math.cos(pitch) * math.cos(yaw), math.cos(pitch) * math.sin(yaw), -math.sin(pitch))
        shoulder = (ag[1][0], ag[1][1], world.pos[ag[0], 2] + cfg["shoulder_height"])
        for tb in boxes:
            if tb is ag:
                continue
            seen = 0
            for px, py, pz in POINTS.tolist():
                ox, oy, oz = px * 2 * tb[2][0], py * 2 * tb[2][1], pz * 2 * tb[2][2]
                p = (
                    tb[1][0] + tb[3] * ox - tb[4] * oy,
                    tb[1][1] + tb[4] * ox + tb[3] * oy,
                    tb[1][2] + oz,
                )
                d = (p[0] - eye[0], p[1] - eye[1], p[2] - eye[2])
                dist = math.sqrt(d[0] ** 2 + d[1] ** 2 + d[2] ** 2)
                if (
                    dist > cfg["view_range"]
                    or d[0] * gaze[0] + d[1] * gaze[1] + d[2] * gaze[2] < cos_half * dist
                ):
                    continue
                if not any(
                    hits(local(eye, ob), local(p, ob), ob[2])
                    for ob in boxes
                    if ob is not tb and ob is not ag
                ):
                    seen += 1
            if seen:
                out[(ag[0], tb[0])] = seen / len(POINTS)
            q = local(shoulder, tb)
            gap = math.sqrt(sum(max(abs(q[a]) - tb[2][a], 0.0) ** 2 for a in range(3)))
            _ = gap <= cfg["arm_reach"]
    objs = [b for b in boxes if world.kind[b[0]] == 2]
    for a in objs:  # IsOn / IsIn / IsNextTo pairs
        for b in objs:
            if a is b:
                continue
            q = local(a[1], b)
            _ = all(abs(q[i]) <= b[2][i] for i in range(3))
            _ = math.hypot(a[1][0] - b[1][0], a[1][1] - b[1][1]) <= cfg["next_to_distance"]
    return out


def vectorised(world: World, producer: SpatialFacts) -> dict[tuple[int, int], float]:
    from toaster.producers.spatial import collect_boxes

    live = world.live_mask(0, None)
    boxes = collect_boxes(world, live, producer.config["agent_size"])
    container = np.full(len(boxes.rows), -1)
    hidden = np.zeros(len(boxes.rows), bool)
    ag, frac = producer.visible_fraction(world, boxes, container, hidden)
    ai, bi = np.nonzero(frac)
    return {
        (int(boxes.rows[ag[a]]), int(boxes.rows[b])): float(frac[a, b])
        for a, b in zip(ai, bi, strict=True)
    }


def bench(n_objects: int, repeat: int, with_naive: bool) -> None:
    world = build(n_objects)
    producer = SpatialFacts()
    times, cpu = [], []
    for i in range(repeat):
        start, start_cpu = time.perf_counter(), time.thread_time()
        batch = producer.compute_batch(world, i)
        cpu.append(time.thread_time() - start_cpu)
        times.append(time.perf_counter() - start)
    med, med_cpu = statistics.median(times) * 1e3, statistics.median(cpu) * 1e3
    line = (
        f"10 agents x {n_objects:>5} objects: {med:8.2f} ms/tick median, {med_cpu:6.2f} ms of CPU"
        f" ({len(batch)} facts)"
    )
    if with_naive:
        start = time.perf_counter()
        ref = naive(world, producer)
        slow = (time.perf_counter() - start) * 1e3
        fast = vectorised(world, producer)
        same = ref.keys() == fast.keys() and all(abs(ref[k] - fast[k]) < 1e-9 for k in ref)
        line += f"; naive loop {slow:9.1f} ms -> {slow / med:6.1f}x faster; same visibility: {same}"
    print(line, flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n", 1)[0])
    parser.add_argument("--quick", action="store_true", help="fewer ticks, no naive loop at 1,000")
    quick = parser.parse_args().quick
    bench(100, 5 if quick else 31, True)
    bench(1000, 3 if quick else 11, not quick)


if __name__ == "__main__":
    main()
