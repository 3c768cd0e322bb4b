"""Fact batches: the integer-key diff counts what the tuple diff counts."""

from __future__ import annotations

import numpy as np

from toaster.producers import AgentMonitor, AreaManager, PerceptionFacts, SnapshotDiff
from toaster.world import World

S = 1_000_000_000


def test_batch_diff_matches_tuple_diff():
    rng = np.random.default_rng(3)
    world = World()
    n = 60
    for i in range(n):
        world.add_entity(f"e{i}", "human" if i < 4 else "object")
    for i in range(4):
        for j in ("head", "rightHand"):
            world.add_entity(f"e{i}/{j}", "joint", owner_id=f"e{i}", name=j)
            world.set_joint_local(f"e{i}/{j}", (0.2, 0.0, 1.7 if j == "head" else 1.0))
    areas = {
        "room": {
            "points": [[0, 0], [5, 0], [5, 5], [0, 5]],
            "area_type": "room",
            "facts": ["density"],
            "enter_hysteresis": 0.2,
            "leave_hysteresis": 0.2,
        },
        "disc": {"shape": "circle", "center": [3, 3], "radius": 1.5},
        "front": {
            "points": [[0, -1], [2, -1], [2, 1], [0, 1]],
            "owner": "e0",
            "facts": ["interaction", "density"],
        },
    }
    world.put_in_hand("e10", "e1", "rightHand")
    producers = [PerceptionFacts(), AreaManager(areas), AgentMonitor()]
    by_batch, by_list = SnapshotDiff(), SnapshotDiff()
    pos = np.column_stack([rng.uniform(0, 6, (n, 2)), np.zeros(n)])
    yaw = np.zeros((n, 3))
    t = 10 * S
    seen = set()
    for tick in range(30):
        pos[: 4 if tick % 7 else n, :2] += rng.normal(0, 0.15, (4 if tick % 7 else n, 2))
        yaw[:, 2] = rng.uniform(-3.2, 3.2, n)
        world.observe("test", np.arange(n), np.full(n, t), pos, yaw)
        world.commit()
        for p in producers:
            batch = p.compute_batch(world, t)
            facts = batch.facts()
            assert len(batch) == len(facts)
            assert by_batch.apply(p.name, batch) == by_list.apply(p.name, facts)
            seen |= {f.property for f in facts}
        t += S // 10
    assert {
        "isPresent",
        "IsInHand",
        "IsInRoom",
        "IsInArea",
        "AreaDensity",
        "IsLookingToward",
        "IsMoving",
        "IsMovingToward",
        "Distance",
    } <= seen


def test_a_group_of_labelled_targets_is_one_constant_group_per_label():
    """Many areas' memberships in one group (targets as codes into labels) give the keys,
    value codes and facts of one group per area, in the same order."""
    from toaster.producers.batch import FactBatch

    rng = np.random.default_rng(5)
    world = World()
    for i in range(30):
        world.add_entity(f"e{i}", "human" if i % 3 else "object")
    labels = np.array([f"zone{k}" for k in range(6)], dtype=object)
    codes = np.sort(rng.integers(0, 6, 40))
    rows = rng.integers(0, 30, 40)
    merged, split = FactBatch(world), FactBatch(world)
    merged.add("IsInArea", rows, (codes, labels), obs=0.8, property_type="position")
    for k in range(6):
        here = codes == k
        split.add("IsInArea", rows[here], str(labels[k]), obs=0.8, property_type="position")
    for batch in (merged, split):  # a row target of the same property beside them
        batch.add("IsInArea", rows[:3], rows[3:6], obs=0.8, property_type="position")
    assert merged.facts() == split.facts()
    keys, values = merged.keys()
    want_keys, want_values = split.keys()
    assert keys.tolist() == want_keys.tolist() and values.tolist() == want_values.tolist()
    assert merged.facts_at(np.array([39, 2, 41])) == split.facts_at(np.array([39, 2, 41]))
