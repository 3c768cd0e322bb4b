"""Holders that perceive alike share the rule's work (``belief_groups``, revision 0011).

A group is computed once per run while no perception fact changes; its members must end up
with exactly the beliefs they would hold if each were computed alone (``group_holders =
false``), whatever happens: people walking, things carried (by an actor or not), things
told, numbers and values changing while nobody moves.
"""

from __future__ import annotations

import random
from typing import Any

import pytest
import sqlalchemy as sa
from hypothesis import HealthCheck, given, settings
from hypothesis import strategies as st

import toaster
from toaster.beliefs import api, scenario
from toaster.beliefs.tell import tell

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

PEOPLE = ("ANNE", "BOB", "CARL", "DORA")
ROOMS = ("KITCHEN", "HALL")
CONTAINERS = {"BASKET": "KITCHEN", "BOX": "HALL", "DRAWER": "KITCHEN"}
THINGS = ("MARBLE", "KEY", "CUP")


def story(seed: int, length: int) -> list[dict[str, Any]]:
    """Scenario steps; most steps change values only (the runs groups serve)."""
    rng = random.Random(seed)
    steps: list[dict[str, Any]] = [
        {
            "t": 1,
            "rooms": {**{p: rng.choice(ROOMS) for p in PEOPLE}, **CONTAINERS},
            "inside": {x: rng.choice(list(CONTAINERS)) for x in THINGS},
        }
    ]
    for i in range(length):
        step: dict[str, Any] = {"t": i + 2}
        roll = rng.random()
        if roll < 0.2:
            step["rooms"] = {rng.choice(PEOPLE): rng.choice(ROOMS)}
        elif roll < 0.4:
            step["inside"] = {rng.choice(THINGS): rng.choice(list(CONTAINERS))}
            if rng.random() < 0.4:
                step["actor"] = rng.choice(PEOPLE)
        elif roll < 0.5:
            speaker, listener = rng.sample(PEOPLE, 2)
            step["tell"] = {
                "speaker": speaker,
                "listeners": [listener],
                "fact": [rng.choice(THINGS), "IsIn", rng.choice(list(CONTAINERS))],
            }
        else:
            step["facts"] = [
                [x, "Temperature", "", rng.choice(("hot", "cold"))]
                for x in rng.sample(THINGS, rng.randint(1, len(THINGS)))
            ]
        steps.append(step)
    return steps


def holders_view(db: toaster.Database) -> tuple[list[tuple[Any, ...]], list[tuple[Any, ...]]]:
    """Every holder's intervals and events, as the views show them."""
    with db.transaction() as conn:
        facts = conn.execute(
            sa.text(
                "SELECT agent_id, subject_id, property, target_id, value_text, valid_from_ns, "
                "valid_to_ns, ROUND(CAST(confidence AS NUMERIC), 9) FROM fact_history "
                "WHERE agent_id <> 'ROBOT'"
            )
        ).all()
        events = conn.execute(
            sa.text(
                "SELECT agent_id, kind, stamp_ns, subject_id, property, target_id, value_text, "
                "previous_text FROM event_log WHERE agent_id <> 'ROBOT'"
            )
        ).all()
    return sorted(tuple(r) for r in facts), sorted(tuple(r) for r in events)


def replay(db: toaster.Database, steps: list[dict[str, Any]], grouped: bool) -> Any:
    sc = scenario.parse(
        {
            "self": "ROBOT",
            "agents": list(PEOPLE),
            "objects": [*THINGS, *CONTAINERS, *ROOMS],
            "settings": {"depth": 2, "group_holders": grouped},
            "steps": steps,
        },
        "groups",
    )
    db.store().empty()
    scenario.Replayer(db, sc).run()
    return holders_view(db)


@settings(
    max_examples=8,
    deadline=None,
    suppress_health_check=[HealthCheck.function_scoped_fixture, HealthCheck.too_slow],
)
@given(seed=st.integers(0, 2**32 - 1), length=st.integers(4, 16))
def test_grouped_holders_believe_what_each_would_alone(db_url: str, seed: int, length: int) -> None:
    steps = story(seed, length)
    with toaster.connect(db_url) as db:
        grouped = replay(db, steps, grouped=True)
        alone = replay(db, steps, grouped=False)
    assert grouped[0] == alone[0]
    assert grouped[1] == alone[1]


def groups(db: toaster.Database) -> dict[str, set[str]]:
    with db.transaction() as conn:
        rows = conn.execute(sa.text("SELECT holder_id, rep_id FROM belief_groups")).all()
    out: dict[str, set[str]] = {}
    for holder, rep in rows:
        out.setdefault(rep, set()).add(holder)
    return out


def groups_for(db: toaster.Database) -> str | None:
    with db.transaction() as conn:
        return conn.execute(sa.text("SELECT groups_for FROM store_state")).scalar_one()


def temperature(db: toaster.Database, holder: str, t: int) -> set[str]:
    return {
        r.value_text for r in api.beliefs(db, holder, property="Temperature", at=t * 1_000_000_000)
    }


def lab(db: toaster.Database) -> Any:
    api.configure(db, depth=2)
    st_ = db.store()
    st_.add_entity("ROBOT", "robot", is_self=True, t_ns=0)
    for person in ("ANNE", "BOB", "CARL"):
        st_.add_entity(person, "human", t_ns=0)

    def tick(t: int, carl: str, temp: str) -> None:
        rooms = {"ANNE": "LAB", "BOB": "LAB", "CARL": carl, "CUP": "LAB"}
        st_.sync_snapshot(
            "eyes",
            "ROBOT",
            t * 1_000_000_000,
            [toaster.Fact(x, "IsInRoom", r) for x, r in rooms.items()]
            + [toaster.Fact("CUP", "Temperature", "", temp)],
        )

    return tick


def test_people_in_one_room_share_the_work_until_one_leaves(db: toaster.Database) -> None:
    tick = lab(db)
    tick(1, "LAB", "hot")
    tick(2, "LAB", "cold")
    everyone = {
        "ANNE",
        "BOB",
        "CARL",
        "ANNE>BOB",
        "ANNE>CARL",
        "BOB>ANNE",
        "BOB>CARL",
        "CARL>ANNE",
        "CARL>BOB",
    }
    assert list(groups(db).values()) == [everyone]
    assert groups_for(db) == "ROBOT"
    tick(3, "HALL", "hot")  # Carl leaves as the cup warms: he saw it (before the tick)
    assert list(groups(db).values()) == [{"ANNE", "BOB", "ANNE>BOB", "BOB>ANNE"}]
    tick(4, "HALL", "cold")  # a change with the groups in use: Carl misses it
    tick(5, "HALL", "hot")
    tick(6, "HALL", "cold")
    assert temperature(db, "ANNE", 6) == temperature(db, "BOB>ANNE", 6) == {"cold"}
    assert temperature(db, "CARL", 6) == temperature(db, "ANNE>CARL", 6) == {"hot"}
    assert temperature(db, "CARL>ANNE", 6) == {"hot"}  # Carl believes Anne saw no change


def test_writes_that_change_one_holder_end_the_groups(db: toaster.Database) -> None:
    tick = lab(db)
    tick(1, "LAB", "hot")
    assert groups(db)
    tell(
        db,
        "ANNE",
        toaster.Fact("CUP", "Temperature", "", "frozen"),
        listeners=["BOB"],
        t_ns=2_000_000_000,
    )  # Bob no longer follows the robot's cup temperature
    assert groups_for(db) is None
    tick(3, "LAB", "hot")  # no change: no run; Bob keeps what he was told
    assert temperature(db, "BOB", 3) == {"frozen"}
    assert temperature(db, "ANNE", 3) == {"hot"}
    assert temperature(db, "ANNE>BOB", 3) == {"frozen"}  # Anne knows what she told him
    tick(4, "LAB", "cold")  # Bob sees it change: the rule runs alone, then forms them again
    assert temperature(db, "BOB", 4) == temperature(db, "ANNE", 4) == {"cold"}
    assert groups_for(db) == "ROBOT"
    api.configure(db, self_perception=True)  # any settings change: the rule forms them again
    assert groups_for(db) is None
    tick(5, "LAB", "hot")
    assert groups_for(db) == "ROBOT"


def test_group_holders_false_keeps_no_groups(db: toaster.Database) -> None:
    tick = lab(db)
    api.configure(db, group_holders=False)
    tick(1, "LAB", "hot")
    tick(2, "LAB", "cold")
    assert groups(db) == {}
    assert temperature(db, "CARL>BOB", 2) == {"cold"}
