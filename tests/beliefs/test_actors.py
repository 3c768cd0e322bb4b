"""Per-fact actors: one write, changes made by different agents (both backends).

``Store.sync_snapshot`` / ``sync_many`` take ``actors`` (per fact: a mapping fact key ->
agent, or a function of the fact) over the write's ``actor``; each changed key reaches the
belief rule with its own actor, who perceives that change wherever it is, and only that one.
"""

from __future__ import annotations

import pytest
from sqlalchemy import Connection

import toaster
from toaster.beliefs import api
from toaster.db.writer.store import ChangeSet
from toaster.errors import UnknownAgentError
from toaster.model import fact_key

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

F = toaster.Fact
S = 1_000_000_000
PEOPLE = ("ANNE", "BOB", "SALLY")
PLACES = [F(p, "IsInRoom", "ROOM") for p in ("BASKET", "DRAWER", "BOX", "SHELF")]


class Recorder:
    """A store rule that keeps the change sets it is given (it runs beside the belief rule)."""

    def __init__(self) -> None:
        self.changes: list[ChangeSet] = []

    def __call__(self, conn: Connection, changes: ChangeSet) -> None:
        self.changes.append(changes)

    def detach(self, conn: Connection, agent_id: str | None, *, keep: bool) -> None:
        """Nothing of its own to detach."""


def _setup(db: toaster.Database) -> toaster.Store:
    """Everyone sees the marble in the basket and the key in the box, then goes to the hall."""
    st = db.store()
    st.add_entity("ROBOT", "robot", is_self=True, t_ns=0)
    for who in PEOPLE:
        st.add_entity(who, "human", t_ns=0)
    st.sync_snapshot(
        "s",
        "ROBOT",
        1 * S,
        [
            *PLACES,
            *(F(p, "IsInRoom", "ROOM") for p in PEOPLE),
            F("MARBLE", "IsIn", "BASKET"),
            F("KEY", "IsIn", "BOX"),
        ],
    )
    return st


def _hall(*things: toaster.Fact) -> list[toaster.Fact]:
    return [*PLACES, *(F(p, "IsInRoom", "HALL") for p in PEOPLE), *things]


def _where(db: toaster.Database, holder: str, thing: str) -> set[str]:
    return {r.target_id for r in api.beliefs(db, holder, subject=thing, property="IsIn")}


def test_two_changes_two_actors_each_perceives_only_its_own(db: toaster.Database) -> None:
    st = _setup(db)
    recorder = Recorder()
    st.add_rule(recorder)
    st.sync_snapshot(
        "s", "ROBOT", 2 * S, _hall(F("MARBLE", "IsIn", "BASKET"), F("KEY", "IsIn", "BOX"))
    )
    # Out of the room, Anne moves the marble and Bob the key, in one snapshot.
    marble, key = F("MARBLE", "IsIn", "DRAWER"), F("KEY", "IsIn", "SHELF")
    st.sync_snapshot(
        "s",
        "ROBOT",
        3 * S,
        _hall(marble, key),
        actors={
            fact_key(marble): "ANNE",
            fact_key(key): "BOB",
            fact_key(F("MARBLE", "IsIn", "BASKET")): "ANNE",
            fact_key(F("KEY", "IsIn", "BOX")): "BOB",
        },
    )
    changes = recorder.changes[-1]
    by_subject = {
        (f.subject_id, f.target_id): changes.actor_of(k)
        for part in (changes.appeared, changes.ended)
        for k, f in part
    }
    assert by_subject == {
        ("MARBLE", "DRAWER"): "ANNE",
        ("MARBLE", "BASKET"): "ANNE",
        ("KEY", "SHELF"): "BOB",
        ("KEY", "BOX"): "BOB",
    }
    assert changes.actor is None
    assert _where(db, "ANNE", "MARBLE") == {"DRAWER"} and _where(db, "ANNE", "KEY") == {"BOX"}
    assert _where(db, "BOB", "MARBLE") == {"BASKET"} and _where(db, "BOB", "KEY") == {"SHELF"}
    assert _where(db, "SALLY", "MARBLE") == {"BASKET"} and _where(db, "SALLY", "KEY") == {"BOX"}
    # Anne did not see Bob do it (nor Bob Anne): each models the other as not knowing.
    assert _where(db, "ANNE>BOB", "MARBLE") == {"BASKET"}
    assert _where(db, "BOB>ANNE", "KEY") == {"BOX"}


def test_the_write_actor_is_the_default_of_keys_without_their_own(db: toaster.Database) -> None:
    """``actor`` names who made the changes a per-fact function leaves unnamed; sync_many
    merges two sources' changes with their actors into one rule run."""
    st = _setup(db)
    st.sync_snapshot(
        "s", "ROBOT", 2 * S, _hall(F("MARBLE", "IsIn", "BASKET"), F("KEY", "IsIn", "BOX"))
    )
    recorder = Recorder()
    st.add_rule(recorder)
    st.sync_many(
        "ROBOT",
        3 * S,
        [
            ("s", _hall(F("MARBLE", "IsIn", "DRAWER"), F("KEY", "IsIn", "BOX"))),
            ("u", [F("CUP", "IsOn", "SHELF")]),
        ],
        actor="SALLY",
        actors=lambda f: "BOB" if f.subject_id == "CUP" else None,
    )
    assert len(recorder.changes) == 1  # merged: one rule run
    changes = recorder.changes[0]
    assert {f.subject_id: changes.actor_of(k) for k, f in changes.appeared} == {
        "MARBLE": "SALLY",
        "CUP": "BOB",
    }
    assert _where(db, "SALLY", "MARBLE") == {"DRAWER"}
    assert _where(db, "BOB", "MARBLE") == _where(db, "ANNE", "MARBLE") == {"BASKET"}
    on_shelf = {h for h in PEOPLE if api.belief_value(db, h, "CUP", "IsOn", "SHELF")}
    assert on_shelf == {"BOB"}


def test_an_ended_fact_carries_its_actor(db: toaster.Database) -> None:
    """Anne takes the marble out of the basket (it is nowhere the robot knows): she no longer
    believes it is there; the others, away, still do."""
    st = _setup(db)
    st.sync_snapshot(
        "s", "ROBOT", 2 * S, _hall(F("MARBLE", "IsIn", "BASKET"), F("KEY", "IsIn", "BOX"))
    )
    st.sync_snapshot(
        "s",
        "ROBOT",
        3 * S,
        _hall(F("KEY", "IsIn", "BOX")),
        actors=lambda f: "ANNE" if f.subject_id == "MARBLE" else None,
    )
    assert _where(db, "ANNE", "MARBLE") == set()
    assert _where(db, "BOB", "MARBLE") == _where(db, "SALLY", "MARBLE") == {"BASKET"}


def test_unknown_per_fact_actors_fail_and_write_nothing(db: toaster.Database) -> None:
    st = _setup(db)
    moved = _hall(F("MARBLE", "IsIn", "DRAWER"), F("KEY", "IsIn", "BOX"))
    with pytest.raises(UnknownAgentError, match="unknown actor 'NOBODY'"):
        st.sync_snapshot(
            "s", "ROBOT", 2 * S, moved, actors={fact_key(F("MARBLE", "IsIn", "DRAWER")): "NOBODY"}
        )
    with pytest.raises(UnknownAgentError, match="unknown actor 'ANNE>BOB'"):
        st.sync_snapshot("s", "ROBOT", 2 * S, moved, actors=lambda f: "ANNE>BOB")
    assert _where(db, "ROBOT", "MARBLE") == {"BASKET"}  # rolled back
    st.sync_snapshot("s", "ROBOT", 2 * S, moved)  # the store still writes
    assert _where(db, "ROBOT", "MARBLE") == {"DRAWER"}
