"""Relevance: pair facts only within range, found with a KD-tree, equal to the dense result."""

from __future__ import annotations

import math

import numpy as np
import pytest

from toaster.errors import InvalidInputError
from toaster.producers import AgentMonitor, make_config, relevance
from toaster.producers.relevance import pairs_within
from toaster.world import World

S = 1_000_000_000
NO_DEBOUNCE = {"min_duration": {"IsMoving": 0, "IsMovingToward": 0}}


@pytest.mark.parametrize("dims", [2, 3])
@pytest.mark.parametrize("dense_max", [0, 10**12])  # always the tree / always dense
def test_pairs_within_matches_brute_force(monkeypatch, dims, dense_max):
    monkeypatch.setattr(relevance, "DENSE_MAX_PAIRS", dense_max)
    rng = np.random.default_rng(dims)
    a = rng.uniform(0, 30, (40, dims))
    b = rng.uniform(0, 30, (3000, 3))
    b[:5, :dims] = a[:5]  # zero distances
    brute = np.sqrt(((a[:, None, :] - b[None, :, :dims]) ** 2).sum(axis=2))
    for strict in (False, True):
        ai, bi, d = pairs_within(a, b, 4.0, strict=strict)
        want = np.nonzero(brute < 4.0 if strict else brute <= 4.0)
        assert np.array_equal(ai, want[0]) and np.array_equal(bi, want[1])
        np.testing.assert_allclose(d, brute[want], rtol=1e-12)
    assert pairs_within(a[:0], b, 4.0)[0].size == 0


def random_scene(seed: int, n: int = 700, agents: int = 16, density: float = 0.4):
    """Agents with head and hand joints among objects; the first half of the agents stand."""
    rng = np.random.default_rng(seed)
    side = math.sqrt(n / density)
    world = World()
    for i in range(n):
        world.add_entity(f"e{i}", "human" if i < agents else "object")
    for i in range(agents):
        for name, local in (("head", (0.1, 0.0, 1.7)), ("rightHand", (0.3, -0.2, 1.0))):
            world.add_entity(f"e{i}/{name}", "joint", owner_id=f"e{i}", name=name)
            world.set_joint_local(f"e{i}/{name}", local, (0.0, rng.normal(0, 0.3), 0.0))
    pos = np.column_stack([rng.uniform(0, side, (n, 2)), rng.uniform(0, 2, n)])
    pos[:agents, 2] = 0.0
    yaw = rng.uniform(-math.pi, math.pi, n)
    velocity = rng.normal(0, 1.0, (n, 2))
    velocity[: agents // 2] = 0.0  # standing agents: their joints give Distance facts
    velocity[agents:] *= rng.uniform(size=(n - agents, 1)) < 0.2
    return world, pos, yaw, velocity, rng


def ticks(world, pos, yaw, velocity, rng, count: int = 12):
    t = 10 * S
    for _ in range(count):
        pos[:, :2] += velocity / 30
        rpy = np.column_stack(
            [np.zeros(len(pos)), np.zeros(len(pos)), yaw + rng.normal(0, 0.05, len(pos))]
        )
        world.observe("test", np.arange(len(pos)), np.full(len(pos), t), pos, rpy)
        world.commit()
        yield t
        t += S // 30


def planar(world, f) -> float:
    a, b = world.pos[world.index[f.subject_id], :2], world.pos[world.index[f.target_id], :2]
    return float(np.sqrt(((b - a) ** 2).sum()))


@pytest.mark.slow
@pytest.mark.parametrize("seed", [0, 1])
def test_indexed_facts_equal_dense_facts_within_range(monkeypatch, seed):
    world, pos, yaw, velocity, rng = random_scene(seed)
    indexed = AgentMonitor(NO_DEBOUNCE)
    dense = AgentMonitor(NO_DEBOUNCE | {"toward_range": 1e6})
    seen: dict[str, int] = {}
    cut = 0
    for t in ticks(world, pos, yaw, velocity, rng):
        monkeypatch.setattr(relevance, "DENSE_MAX_PAIRS", 0)  # the KD-tree path
        got = indexed.compute(world, t)
        monkeypatch.setattr(relevance, "DENSE_MAX_PAIRS", 10**12)  # every pair, dense
        everything = dense.compute(world, t)
        want = [
            f
            for f in everything
            if not (f.property == "IsMovingToward" and planar(world, f) >= 8.0)
        ]
        assert got == want  # same facts, same values, same order
        cut += len(everything) - len(got)
        for f in got:
            seen[f.property] = seen.get(f.property, 0) + 1
    assert {"IsMovingToward", "Distance", "IsLookingToward", "IsLookingAt"} <= set(seen)
    assert cut > 0  # the range did leave far targets out


def test_distance_and_looking_pairs_are_every_pair_in_range(monkeypatch):
    monkeypatch.setattr(relevance, "DENSE_MAX_PAIRS", 0)
    world, pos, yaw, velocity, rng = random_scene(3)
    monitor = AgentMonitor(NO_DEBOUNCE)
    for t in ticks(world, pos, yaw, velocity, rng, 8):
        facts = monitor.compute(world, t)
    distance = {(f.subject_id, f.target_id): f.value_num for f in facts if f.property == "Distance"}
    joints = sorted({world.index[s] for s, _ in distance})
    targets = np.flatnonzero(world.kind[: world.n] != 3)
    d = np.linalg.norm(world.pos[joints][:, None] - world.pos[targets][None], axis=2)
    ji, ti = np.nonzero(d < 8.0)
    assert distance == {
        (world.ids[joints[j]], world.ids[targets[k]]): d[j, k]
        for j, k in zip(ji.tolist(), ti.tolist(), strict=True)
    }
    looked = {(f.subject_id, f.target_id) for f in facts if f.property == "IsLookingToward"}
    assert looked
    for agent, target in looked:
        head = world.joint_of(agent, "head")
        tgt_head = world.joint_of(target, "head")
        point = world.pos[tgt_head if tgt_head >= 0 else world.index[target]]
        assert np.linalg.norm(point - world.pos[head]) <= 2.0


def walk_toward(
    target_x: float, config: dict | None = None, kind: str = "object"
) -> set[tuple[str, str]]:
    """Bob walks along +x at 1 m/s toward a "door" (of ``kind``) at target_x; (sub_property,
    target) pairs."""
    world = World()
    world.add_entity("bob", "human")
    world.add_entity("door", kind)
    world.add_entity("cup", "object")
    monitor = AgentMonitor(config)
    t = 10 * S
    world.set_pose("door", (target_x, 0.2, 0.0), t)
    world.set_pose("cup", (3.0, -0.1, 0.0), t)
    for k in range(20):
        world.set_pose("bob", (k / 10, 0.0, 0.0), t)
        world.set_pose("door", (target_x, 0.2, 0.0), t)  # agents are seen every tick
        world.commit()
        facts = monitor.compute(world, t)
        t += S // 10
    return {(f.sub_property, f.target_id) for f in facts if f.property == "IsMovingToward"}


def test_target_beyond_toward_range_gets_no_moving_toward():
    both = {("direction", "door"), ("distance", "door")}
    near_cup = {("direction", "cup"), ("distance", "cup")}
    assert walk_toward(7.0) == both | near_cup  # 5.1 m ahead of bob
    assert walk_toward(10.5) == near_cup  # 8.6 m ahead: beyond the 8 m default
    assert walk_toward(10.5, {"toward_range": 10.0}) == both | near_cup


def test_people_are_moved_toward_only_when_asked_and_within_their_range():
    """Toward a person the range is toward_range_humans: 0 by default (not computed: crowds),
    e.g. 3.6 m (Hall's social distance) when asked; the robot and objects keep toward_range."""
    both = {("direction", "door"), ("distance", "door")}
    near_cup = {("direction", "cup"), ("distance", "cup")}
    social = {"toward_range_humans": 3.6}
    assert walk_toward(5.0, kind="human") == near_cup  # a person 3.1 m ahead: off by default
    assert walk_toward(7.0, social, kind="human") == near_cup  # 5.1 m ahead: not approached
    assert walk_toward(5.0, social, kind="human") == both | near_cup  # 3.1 m ahead
    assert walk_toward(7.0, kind="robot") == both | near_cup
    assert walk_toward(7.0, {"toward_range_humans": 8.0}, kind="human") == both | near_cup


def test_toward_range_is_validated():
    with pytest.raises(InvalidInputError, match="toward_range"):
        make_config({"toward_range": -1})
    assert make_config({"toward_range": 12})["toward_range"] == 12.0
