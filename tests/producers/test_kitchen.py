"""move3d_facts on the kitchen example and on small hand-built worlds."""

from __future__ import annotations

from pathlib import Path

import numpy as np
import pytest

import toaster
from toaster.errors import InvalidInputError
from toaster.producers import Runner, load_session
from toaster.producers.spatial import SpatialFacts, relative_position_from, segment_hits
from toaster.world.state import World

EXAMPLES = Path(toaster.__file__).parent / "examples"
KITCHEN = EXAMPLES / "scenario_spatial_kitchen.yaml"
S = 1_000_000_000


def facts_at(t_ns: int) -> tuple[World, set[tuple[str, str, str]], dict]:
    session = load_session(KITCHEN)
    runner = Runner(session.world, session.sources, session.producers)
    for t in range(0, t_ns + 1, S // 2):
        out = runner.tick(t)
    facts = out["move3d_facts"].facts()
    keys = {(f.subject_id, f.property, f.target_id) for f in facts}
    by_key = {(f.subject_id, f.property, f.target_id): f for f in facts}
    return session.world, keys, by_key


def test_mug_on_table_ball_in_closed_box() -> None:
    _, keys, _ = facts_at(0)
    assert ("MUG", "IsOn", "TABLE") in keys
    assert ("BALL", "IsIn", "BOX") in keys
    assert ("BALL", "IsOn", "BOX") not in keys
    assert ("BOX", "IsClosed", "") in keys
    assert ("MUG", "IsNextTo", "BOX") in keys and ("BOX", "IsNextTo", "MUG") in keys
    assert ("MUG", "IsNextTo", "TABLE") not in keys


def test_visibility_and_occlusion() -> None:
    _, keys, by_key = facts_at(0)
    assert ("MUG", "IsVisibleBy", "BOB") in keys and ("BOB", "CanSee", "MUG") in keys
    assert ("MUG", "IsVisibleBy", "ROBOT") in keys
    assert ("MUG", "IsVisibleBy", "ALICE") not in keys  # the shelf is in the way
    assert ("SHELF", "IsVisibleBy", "ALICE") in keys
    assert ("BALL", "IsVisibleBy", "ROBOT") not in keys  # closed box
    f = by_key[("MUG", "IsVisibleBy", "BOB")]
    assert 0 < f.confidence <= 1 and f.value_num == f.confidence


def test_open_box_and_turning_away() -> None:
    _, keys, _ = facts_at(3 * S + S // 2)
    assert ("BALL", "IsVisibleBy", "ROBOT") in keys
    assert ("BOX", "IsClosed", "") not in keys
    assert ("MUG", "IsVisibleBy", "BOB") not in keys  # Bob turned around


def test_reach() -> None:
    _, keys, by_key = facts_at(0)
    assert ("MUG", "IsReachableBy", "BOB") in keys and ("BOB", "CanReach", "MUG") in keys
    assert ("VASE", "IsReachableBy", "BOB") not in keys
    assert by_key[("MUG", "IsReachableBy", "BOB")].value_num <= 0.75


@pytest.mark.slow
def test_on_your_left_flips_when_bob_turns() -> None:
    world, _, _ = facts_at(0)
    words, local = relative_position_from(world, "BOB", "MUG", "BOX")
    assert words[0] == "left" and local[1] > 0
    world, _, _ = facts_at(2 * S + S // 2)
    assert relative_position_from(world, "BOB", "MUG", "BOX")[0][0] == "right"
    assert relative_position_from(world, "ROBOT", "MUG")[0] == ["in front", "below", "right"]


def test_spatial_is_opt_in() -> None:
    names = [p.name for p in load_session(EXAMPLES / "scenario_flat.yaml").producers]
    assert "move3d_facts" not in names
    assert "move3d_facts" in [p.name for p in load_session(KITCHEN).producers]


def test_slab_hits() -> None:
    half = np.array([0.5, 0.5, 0.5])
    p0 = np.array([[-2.0, 0, 0], [-2.0, 0, 0], [-2.0, 2, 0], [-2.0, 0, 0]])
    p1 = np.array([[2.0, 0, 0], [-1.0, 0, 0], [2.0, 2, 0], [2.0, 0.49, 0.49]])
    assert segment_hits(p0, p1, half).tolist() == [True, False, False, True]


def small_world() -> World:
    world = World()
    world.add_entity("H", "human")
    world.add_entity("head", "joint", owner_id="H", name="head")
    world.set_joint_local("head", [0, 0, 1.6])
    world.add_entity("CUP", size=[0.1, 0.1, 0.1])
    world.add_entity("WALL", size=[0.1, 2.0, 2.0])
    world.set_pose("H", [0, 0, 0], 0)
    world.set_pose("CUP", [3, 0, 1.0], 0)
    world.set_pose("WALL", [5, 0, 0], 0)
    world.commit()
    return world


def test_hand_built_world_and_held_objects() -> None:
    world = small_world()
    producer = SpatialFacts()
    keys = {(f.subject_id, f.property, f.target_id) for f in producer.compute(world, 0)}
    assert ("CUP", "IsVisibleBy", "H") in keys
    world.set_pose("WALL", [1.5, 0, 0], 1)  # now between the eyes and the cup
    world.commit()
    keys = {(f.subject_id, f.property, f.target_id) for f in producer.compute(world, 1)}
    assert ("CUP", "IsVisibleBy", "H") not in keys
    assert ("WALL", "IsVisibleBy", "H") in keys


def test_set_shape_checks_role() -> None:
    world = small_world()
    world.set_shape("CUP", role="container", closed=True, size=[0.2, 0.2, 0.2])
    assert world.roles["CUP"] == "container" and world.closed["CUP"]
    with pytest.raises(InvalidInputError):
        world.set_shape("CUP", role="lid")
