"""Kept perception when a second robot comes and goes (revision 0028).

The kept perception and the groups of holders are one robot's (``store_state``): while one
robot writes, its steady runs reuse who perceives what (revision 0023); registering a second
robot ends them, and while several robots write, no run keeps either (each run computes
perception and writes no ``store_state``, so that runs of robots whose people never meet do not
wait for each other); once one robot is left, its runs keep perception again. Two robots with
disjoint people write random stories (test_kept_perception's): R1 alone, then R1 and R2
alternating, then R1 alone once R2 is no longer a self agent. Every holder's intervals, events
and as-of beliefs equal those of the same writes on a database that forgets the kept
perception before every write.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest
import sqlalchemy as sa

import toaster
import toaster.queries as q
from tests.beliefs.test_kept_perception import (
    BOXES,
    HUMANS,
    ROOMS,
    THINGS,
    Step,
    _databases,
    _facts,
    story,
)
from toaster import Fact
from toaster.beliefs import api

_INBOX = sa.text(
    "INSERT INTO fact_inbox (agent_id, subject_id, property, value_text, value_num, t_ns, "
    "actor_id) VALUES (:r, :s, :p, :v, :n, :t, :a)"
)
_HOLDER = sa.text(
    "INSERT INTO fact_inbox (agent_id, subject_id, property, target_id, t_ns) "
    "VALUES (:h, :s, 'IsIn', :tg, :t)"
)


def _name(robot: str, x: str) -> str:
    """R2's world is R1's with every entity renamed: no person (nor thing) in common."""
    return x if robot == "R1" or not x else f"{x}_2"


def _register(db: toaster.Database, robot: str) -> None:
    store = db.store()
    with store.transaction():
        store.add_entity(robot, "robot", is_self=True, t_ns=0)
        for h in HUMANS:
            store.add_entity(_name(robot, h), "human", t_ns=0)
        for x in (*BOXES, *THINGS, *ROOMS):
            store.add_entity(_name(robot, x), "object", t_ns=0)


def _write(db: toaster.Database, robot: str, step: Step, forget: bool) -> None:
    if forget:
        with db.transaction() as conn:
            conn.execute(sa.text("UPDATE store_state SET perceived_for = NULL"))
    kind, t = step[0], step[1]
    if kind == "tick":
        facts = [
            f._replace(subject_id=_name(robot, f.subject_id), target_id=_name(robot, f.target_id))
            for f in _facts(step[2])
        ]
        actor = _name(robot, step[3]) if step[3] else None
        db.store().sync_snapshot("eyes", robot, t, facts, actor=actor)
        return
    with db.transaction() as conn:
        if kind == "inbox":
            _, _, subject, prop, _, value, number, actor = step
            later = conn.execute(
                sa.text(
                    "SELECT count(*) FROM facts f JOIN fact_keys k ON k.id = f.key_id "
                    "WHERE k.agent_id = :r AND k.subject_id = :s AND k.property = :p "
                    "AND COALESCE(f.valid_to_ns, f.valid_from_ns) > :t"
                ),
                {"r": robot, "s": _name(robot, subject), "p": prop, "t": t},
            ).scalar_one()
            if not later:  # (a write before the key's last change is refused)
                conn.execute(
                    _INBOX,
                    {"r": robot, "s": _name(robot, subject), "p": prop, "v": value, "n": number,
                     "t": t, "a": actor and _name(robot, actor)},
                )  # fmt: skip
        else:  # a direct write to a holder's beliefs from SQL
            _, _, listener, thing, box = step
            names = {"h": _name(robot, listener), "s": _name(robot, thing), "tg": _name(robot, box)}
            conn.execute(_HOLDER, {**names, "t": t})


def _state(db: toaster.Database) -> tuple[Any, ...]:
    """(perceived_for, groups_for, groups of holders)."""
    with db.transaction() as conn:
        return tuple(
            conn.execute(
                sa.text(
                    "SELECT perceived_for, groups_for, (SELECT count(*) FROM belief_groups) "
                    "FROM store_state"
                )
            ).one()
        )


def _story(db: toaster.Database, seed: int, forget: bool) -> tuple[list[int], set[Any]]:
    """R1 alone, R1 and R2 alternating, R1 alone again (R2 no longer a self agent): the times
    of the writes, and the kept perception's owners seen in each part."""
    api.configure(db, depth=2)
    first, second = story(seed, 45, tells=False), story(seed + 100, 14, tells=False)
    times, owners = [], set()
    _register(db, "R1")
    for step in first[:15]:
        _write(db, "R1", step, forget)
        times.append(step[1])
        owners.add(("alone", _state(db)[0]))
    _register(db, "R2")
    assert _state(db)[:2] == (None, None)  # a second robot ends both (the next run the rows)
    for mine, theirs in zip(first[15:30], second, strict=True):
        for robot, step in (("R1", mine), ("R2", theirs)):
            _write(db, robot, step, forget)
            times.append(step[1])
            assert _state(db)[:2] == (None, None)  # several robots keep neither
    assert _state(db)[2] == 0
    db.store().set_self("R2", False)
    for step in first[30:]:
        _write(db, "R1", step, forget)
        times.append(step[1])
        owners.add(("again", _state(db)[0]))
    return times, owners


def _views(db: toaster.Database, times: list[int]) -> tuple[list[Any], ...]:
    """Every holder's intervals, events and as-of beliefs (ids and write times left out)."""
    with db.transaction() as conn:
        facts = conn.execute(
            sa.text(
                "SELECT agent_id, subject_id, property, target_id, value_text, value_num, "
                "valid_from_ns, valid_to_ns, ROUND(CAST(confidence AS NUMERIC), 9), source "
                "FROM fact_history WHERE agent_id NOT IN ('R1', 'R2')"
            )
        ).all()
        events = conn.execute(
            sa.text(
                "SELECT agent_id, kind, stamp_ns, subject_id, property, target_id, value_text, "
                "value_num, previous_text, source FROM event_log "
                "WHERE agent_id NOT IN ('R1', 'R2')"
            )
        ).all()
    as_of = [
        (holder, t, sorted(row._replace(recorded_ns=0) for row in q.beliefs_at(db, holder, t)))
        for holder in api.holders(db)
        if holder != "R2"
        for t in sorted(set(times))
    ]
    return sorted(map(tuple, facts)), sorted(map(tuple, events)), as_of


@pytest.mark.slow
@pytest.mark.parametrize("seed", [3, 8])
def test_kept_perception_with_a_second_robot_believes_as_computed(
    empty_url: str, tmp_path: Path, seed: int
) -> None:
    """R1's kept perception ends when R2 registers, none is kept while both write, and R1
    keeps it again alone: the same beliefs as perception computed by every run."""
    with (
        _databases(empty_url, tmp_path, 2) as (kept_url, forgot_url),
        toaster.connect(kept_url) as kept,
        toaster.connect(forgot_url) as forgot,
    ):
        times, owners = _story(kept, seed, forget=False)
        _story(forgot, seed, forget=True)
        expected = _views(forgot, times)
        assert _views(kept, times) == expected
    assert {("alone", "R1"), ("again", "R1")} <= owners  # it was kept in both parts
    holders = {row[0] for row in expected[0]}
    assert {"SALLY", "SALLY_2", "ANNE_2"} <= holders and len(expected[0]) > 80


def test_two_robots_runs_write_no_store_state(db: toaster.Database) -> None:
    """With two robots, a steady tick (values only) of either forms no groups and keeps no
    perception; alone, the same ticks do both."""
    store = db.store()

    def tick(robot: str, t: int, temp: str) -> None:
        world = [Fact(_name(robot, x), "IsInRoom", _name(robot, "KITCHEN")) for x in HUMANS]
        world.append(Fact(_name(robot, "CUP"), "IsInRoom", _name(robot, "KITCHEN")))
        world.append(Fact(_name(robot, "CUP"), "Temperature", "", temp))
        store.sync_snapshot("eyes", robot, t * 1_000_000_000, world)

    _register(db, "R1")
    for t, temp in ((1, "hot"), (2, "cold"), (3, "hot")):
        tick("R1", t, temp)
    assert _state(db)[:2] == ("R1", "R1")
    _register(db, "R2")
    for t, temp in ((4, "cold"), (5, "hot"), (6, "cold")):
        tick("R1", t, temp)
        tick("R2", t, temp)
        assert _state(db) == (None, None, 0)
    assert {r.value_text for r in api.beliefs(db, "ANNE_2", property="Temperature")} == {"cold"}
