"""The mapping of :mod:`toaster.outputs.foxglove`, decoded from the protobuf bytes the SDK
encodes (with the schema the channel carries), and the false-belief marks."""

from __future__ import annotations

import base64
import json
import math
import random

import pytest

from toaster.model import Fact
from toaster.outputs.foxglove import beliefs_message, facts_json, facts_message, scene_update
from toaster.outputs.markers import area_markers, motion_markers
from toaster.outputs.recording.msgs import Scene
from toaster.world.state import EntityPose

foxglove = pytest.importorskip("foxglove")
pytest.importorskip("google.protobuf")
pytest.importorskip("websockets")  # tests/foxglove/client.py's imports
pytest.importorskip("jsonschema")

FRONT = {"shape": "polygon", "points": [[0.5, -0.5], [1.5, -0.5], [1.5, 0.5], [0.5, 0.5]]}


def decoded(update: object) -> dict:
    """A SceneUpdate as the protobuf schema of a SceneUpdate channel decodes it."""
    from google.protobuf import json_format

    from tests.foxglove.client import protobuf_class

    schema = foxglove.messages.SceneUpdate.get_schema()
    cls = protobuf_class(schema.name, base64.b64encode(schema.data).decode())
    return json_format.MessageToDict(cls.FromString(update.encode()))  # type: ignore[attr-defined]


def world_with(x: float, yaw: float) -> Scene:
    scene = Scene()
    scene.update(
        0,
        [
            EntityPose("BOB", "human", x, 0.0, 0.0, yaw),
            EntityPose("BOB/head", "joint", x, 0.0, 1.6, yaw, owner="BOB", name="head"),
            EntityPose("MUG", "object", 3.0, 0.0, 0.0, 0.0),
        ],
    )
    return scene


def test_owner_relative_area_moves_and_turns_with_its_owner() -> None:
    areas = {"front": {**FRONT, "owner": "BOB"}}
    before = decoded(scene_update(0, area_markers(world_with(0, 0).world, areas, set(), 0)))
    after = decoded(
        scene_update(0, area_markers(world_with(2, math.pi / 2).world, areas, set(), 0))
    )

    def ring(update: dict) -> list[tuple[float, float]]:
        (entity,) = [e for e in update["entities"] if e["id"] == "front"]
        return [(p.get("x", 0.0), p.get("y", 0.0)) for p in entity["lines"][0]["points"]]

    assert ring(before)[0] == pytest.approx((0.5, -0.5))
    assert ring(after)[0] == pytest.approx((2.5, 0.5))  # turned a quarter, moved 2 m
    assert before["deletions"][0]["type"] == "ALL"


def test_gaze_is_a_line_from_the_head_to_the_target() -> None:
    world = world_with(0, 0).world
    facts = [Fact("BOB", "IsLookingAt", "MUG")]
    update = decoded(scene_update(0, motion_markers(world, facts, 0)))
    (entity,) = update["entities"]
    points = entity["lines"][0]["points"]
    assert (points[0]["z"], points[1].get("x")) == (1.6, 3.0)


def test_false_beliefs_are_those_the_self_agent_does_not_hold_with_that_value() -> None:
    robot = [Fact("MARBLE", "IsIn", "BOX")]
    sally = [Fact("MARBLE", "IsIn", "BASKET"), Fact("BOX", "IsClosed", value_text="true")]
    message = beliefs_message(5, "SALLY", sally, [*robot, Fact("BOX", "IsClosed")])
    marks = {f["target"] or f["property"]: f["false_belief"] for f in message["facts"]}
    assert marks == {"BASKET": True, "IsClosed": False}
    assert message["false_beliefs"] == 1 and message["chain"] == ["SALLY"]
    nested = beliefs_message(5, "ANNE>SALLY", sally, robot)
    assert nested["chain"] == ["ANNE", "SALLY"]
    assert beliefs_message(5, "ROBOT", robot, robot, is_self=True)["false_beliefs"] == 0


def test_facts_json_is_the_messages_json() -> None:
    """The live /toaster/facts text is what ``json.dumps`` makes of :func:`facts_message`,
    hostile strings, numbers and None included."""
    rng = random.Random(7)
    texts = ["", "a", 'q"uote', "back\\slash", "tab\tnl\n", "é ü 中", "\x7f\x01", "</script>"]
    facts = [
        Fact(
            rng.choice(texts) + str(i),
            rng.choice(texts) or "P",
            rng.choice(texts),
            rng.choice(texts) or "true",
            rng.choice([None, 0.0, -1.5, 1e-300, 123456789.123, float(i), math.nan, -math.inf, 2]),
            rng.choice([0.0, 0.25, 1.0, 1 / 3]),
        )
        for i in range(200)
    ]
    for t_ns in (0, 1_700_000_000_123_456_789):
        for chosen in (facts, facts[:1], []):
            expected = json.dumps(facts_message(t_ns, 'r"1', "area_manager", chosen))
            assert facts_json(t_ns, 'r"1', "area_manager", chosen) == expected.encode()
