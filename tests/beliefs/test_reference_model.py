"""Random stories of a flat against a small reference model of first-order beliefs.

People walk between two rooms; things are carried between containers of both rooms, sometimes
by a named actor. The model (a few lines of Python, written from the rules of
docs/beliefs.md, independent of the SQL) says where each person believes each thing is after
every step: you see a thing leave a place if you could see it there before the change; you see
it arrive if you can see it where it arrives; the actor sees both wherever it is; entering a
room (or a thing arriving in yours) shows you where the things in it are. toaster, replaying
the same story as scenario steps, must agree as of every step, on both backends.
"""

from __future__ import annotations

import random
from typing import Any

import pytest
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import toaster
from toaster.beliefs import api, scenario

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

PEOPLE = ("SALLY", "ANNE", "BOB")
ROOMS = ("KITCHEN", "HALL")
CONTAINERS = {"BASKET": "KITCHEN", "BOX": "HALL", "DRAWER": "KITCHEN"}
THINGS = ("MARBLE", "KEY")


def story(seed: int, length: int) -> list[dict[str, Any]]:
    """Scenario steps: the set-up, then one change per step."""
    rng = random.Random(seed)
    rooms = {p: rng.choice(ROOMS) for p in PEOPLE}
    inside = {x: rng.choice(list(CONTAINERS)) for x in THINGS}
    steps: list[dict[str, Any]] = [{"t": 1, "rooms": {**rooms, **CONTAINERS}, "inside": inside}]
    for i in range(length):
        if rng.random() < 0.4:
            person = rng.choice(PEOPLE)
            steps.append({"t": i + 2, "rooms": {person: rng.choice(ROOMS)}})
        else:
            step: dict[str, Any] = {
                "t": i + 2,
                "inside": {rng.choice(THINGS): rng.choice(list(CONTAINERS))},
            }
            if rng.random() < 0.4:
                step["actor"] = rng.choice(PEOPLE)
            steps.append(step)
    return steps


def model(steps: list[dict[str, Any]]) -> list[dict[str, dict[str, str | None]]]:
    """Where each person believes each thing is after each step (None: does not know)."""
    rooms: dict[str, str] = {}
    inside: dict[str, str] = {}
    belief: dict[str, dict[str, str | None]] = {p: dict.fromkeys(THINGS) for p in PEOPLE}
    out = []
    for step in steps:
        room_before = dict(rooms)
        thing_room_before = {x: CONTAINERS[c] for x, c in inside.items()}
        inside_before = dict(inside)
        rooms.update({k: v for k, v in step.get("rooms", {}).items() if k in PEOPLE})
        inside.update(step.get("inside", {}))
        thing_room = {x: CONTAINERS[c] for x, c in inside.items()}
        actor = step.get("actor")
        for p in PEOPLE:
            for x in THINGS:
                sees_after = rooms.get(p) == thing_room[x]
                saw_before = (
                    x in thing_room_before
                    and p in room_before
                    and room_before[p] == thing_room_before[x]
                )
                moved = inside_before.get(x) != inside[x]  # putting it where it is: no change
                if sees_after and (moved or not saw_before or p == actor):
                    belief[p][x] = inside[x]  # sees it arrive, or sees it again
                elif moved and (saw_before or p == actor):
                    if p == actor:
                        belief[p][x] = inside[x]
                    elif belief[p][x] != inside[x]:
                        belief[p][x] = None  # saw it leave, not where it went
        out.append({p: dict(belief[p]) for p in PEOPLE})
    return out


def believed(db: toaster.Database, person: str, t_ns: int) -> dict[str, str | None]:
    rows = api.beliefs(db, person, property="IsIn", at=t_ns)
    where: dict[str, str | None] = dict.fromkeys(THINGS)
    for row in rows:
        if row.subject_id in where:
            where[row.subject_id] = row.target_id
    return where


@settings(
    max_examples=12,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(seed=st.integers(0, 2**32 - 1), length=st.integers(3, 14))
def test_first_order_beliefs_match_the_reference_model(db_url: str, seed: int, length: int) -> None:
    steps = story(seed, length)
    sc = scenario.parse(
        {
            "self": "ROBOT",
            "agents": list(PEOPLE),
            "objects": [*THINGS, *CONTAINERS, *ROOMS],
            "settings": {"depth": 1},
            "steps": steps,
        },
        f"story-{seed}",
    )
    with toaster.connect(db_url) as db:
        db.store().empty()
        scenario.Replayer(db, sc).run()
        expected = model(steps)
        for step, want in zip(steps, expected, strict=True):
            t_ns = int(step["t"] * 1e9)
            for person in PEOPLE:
                assert believed(db, person, t_ns) == want[person], (step, person)
