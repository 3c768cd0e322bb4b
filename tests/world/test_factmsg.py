"""toaster_msgs/Fact value fields as the original's nodes fill them (issue 27 item 5), and
back: every fact the shipped scenarios produce survives fact_fields -> fact_from_msg."""

from __future__ import annotations

from functools import cache
from pathlib import Path
from types import SimpleNamespace

import pytest

import toaster
from toaster.model import Fact
from toaster.producers import Runner, load_session
from toaster.world.factmsg import fact_fields, fact_from_msg

S = 1_000_000_000
EXAMPLES = Path(toaster.__file__).parent / "examples"
#: property -> (valueType, stringValue, what doubleValue holds), from the original's sources
#: (reference §2.0: pdg, area_manager, agent_monitor, move3d_facts)
ORIGINAL = {
    "isPresent": (False, "true", "0"),
    "IsInHand": (False, "true", "0"),
    "IsInRoom": (False, "true", "0"),
    "IsAt": (False, "true", "0"),
    "IsInArea": (False, "true", "0"),
    "IsFacing": (True, "", "angle"),
    "AreaDensity": (True, "", "ratio"),
    "IsLookingToward": (True, "", "angle"),
    "IsLookingAt": (True, "", "angle"),
    "IsMoving": (False, "true", "speed"),
    "IsMovingToward": (False, "", "number"),
    "Distance": (False, "label", "metres"),
    "IsIn": (False, "true", "0"),
    "IsOn": (False, "true", "0"),
    "IsClosed": (False, "true", "0"),
    "IsNextTo": (False, "true", "number"),
    "IsVisibleBy": (False, "true", "number"),
    "CanSee": (False, "true", "number"),
    "IsReachableBy": (False, "true", "number"),
    "CanReach": (False, "true", "number"),
}


@cache
def scenario_facts() -> list[Fact]:
    out: list[Fact] = []
    for path in sorted(EXAMPLES.glob("scenario_*.yaml")):
        session = load_session(path)
        runner = Runner(session.world, session.sources, session.producers)
        for t in range(0, 20 * S, S // 2):
            out.extend(f for batch in runner.tick(t).values() for f in batch.facts())
    return out


@pytest.mark.slow
def test_value_fields_are_the_originals_and_come_back() -> None:
    made = [
        Fact("bob", "IsFacing", "pr2", value_num=-0.2, property_type="posture"),
        Fact("desk", "AreaDensity", value_num=0.25, property_type="density"),
    ]
    seen: set[str] = set()
    for fact in scenario_facts() + made:
        fields = fact_fields(fact, 7)
        value_type, text, number = ORIGINAL[fact.property]
        seen.add(fact.property)
        assert fields["valueType"] is value_type, fact
        if text == "label":
            assert fields["stringValue"] == fact.value_text not in ("", "true"), fact
        else:
            assert fields["stringValue"] == text, fact
        if number == "0":
            assert fields["doubleValue"] == 0.0, fact
        else:
            assert fields["doubleValue"] == fact.value_num, fact
        assert fact_from_msg(SimpleNamespace(**fields)) == fact
    assert seen == set(ORIGINAL)


@pytest.mark.slow
def test_is_moving_toward_direction_carries_its_confidence() -> None:
    """The original's doubleValue of IsMovingToward/direction is the confidence (not the
    angle toaster stored before); /distance's is the metres approached, its confidence a share
    in [0, 1] (the original's confidence is those metres: a confidence above 1 is refused)."""
    toward = [f for f in scenario_facts() if f.property == "IsMovingToward"]
    direction = [f for f in toward if f.sub_property == "direction"]
    distance = [f for f in toward if f.sub_property == "distance"]
    assert direction and distance
    assert all(f.value_num == f.confidence for f in direction)
    assert all(0 <= f.confidence <= 1 and f.value_num is not None for f in distance)
    assert any(f.value_num != pytest.approx(f.confidence) for f in distance)


def test_a_users_own_facts_keep_toasters_convention() -> None:
    """A property the original does not compute: valueType 1 exactly when it has a number."""
    plain, number = Fact("cup", "IsHot"), Fact("cup", "Temperature", value_num=61.5)
    assert (fact_fields(plain, 1)["valueType"], fact_fields(plain, 1)["stringValue"]) == (
        False,
        "true",
    )
    assert (fact_fields(number, 1)["valueType"], fact_fields(number, 1)["doubleValue"]) == (
        True,
        61.5,
    )
    for fact in (plain, number):
        assert fact_from_msg(SimpleNamespace(**fact_fields(fact, 1))) == fact
