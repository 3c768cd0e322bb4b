"""Telling (toaster.beliefs.tell), the actor of a change and attention, on both backends."""

from __future__ import annotations

import pytest
from click.testing import CliRunner

import toaster
import toaster.queries as q
from toaster.beliefs import api
from toaster.beliefs.tell import tell
from toaster.cli import cli
from toaster.errors import InvalidInputError

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

F = toaster.Fact
S = 1_000_000_000


def _flat(db: toaster.Database, **settings: object) -> None:
    """Sally in the hall; Anne and Bob in the room, where the marble moves to the box."""
    api.configure(db, depth=2, **settings)
    st = db.store()
    st.add_entity("ROBOT", "robot", is_self=True, t_ns=0)
    for who in ("SALLY", "ANNE", "BOB"):
        st.add_entity(who, "human", t_ns=0)
    for thing in ("CUP", "SHELF", "TABLE"):
        st.add_entity(thing, "object", t_ns=0)
    room = [
        F("BASKET", "IsInRoom", "ROOM"),
        F("BOX", "IsInRoom", "ROOM"),
        F("ANNE", "IsInRoom", "ROOM"),
        F("BOB", "IsInRoom", "ROOM"),
    ]
    st.sync_snapshot(
        "s", "ROBOT", 1 * S, [*room, F("SALLY", "IsInRoom", "ROOM"), F("MARBLE", "IsIn", "BASKET")]
    )
    st.sync_snapshot(
        "s", "ROBOT", 2 * S, [*room, F("SALLY", "IsInRoom", "HALL"), F("MARBLE", "IsIn", "BASKET")]
    )
    st.sync_snapshot(
        "s", "ROBOT", 3 * S, [*room, F("SALLY", "IsInRoom", "HALL"), F("MARBLE", "IsIn", "BOX")]
    )


def _where(db: toaster.Database, holder: str, at: int | None = None) -> set[str]:
    agent, *about = holder.split(">")
    return {
        r.target_id
        for r in api.beliefs(db, agent, about or None, at=at, subject="MARBLE", property="IsIn")
    }


def test_a_told_place_replaces_the_believed_one_and_carries_its_source(
    db: toaster.Database,
) -> None:
    _flat(db)
    assert _where(db, "SALLY") == {"BASKET"}
    learnt = tell(db, "ANNE", F("MARBLE", "IsIn", "BOX"), listeners=["SALLY"], t_ns=4 * S)
    assert "SALLY" in learnt and "ANNE>SALLY" in learnt and "SALLY>ANNE" in learnt
    assert "BOB>SALLY" not in learnt  # Bob did not hear it
    assert _where(db, "SALLY") == {"BOX"} and _where(db, "SALLY", 3 * S) == {"BASKET"}
    row = api.belief_value(db, "SALLY", "MARBLE", "IsIn", "BOX")
    assert row is not None and row.source == "told:ANNE" and row.valid_from_ns == 4 * S
    said = q.events(db, "ROBOT", kind="event", subject="ANNE")
    assert [(e.property, e.target_id, e.value_text) for e in said] == [
        ("Tells", "SALLY", "MARBLE IsIn BOX")
    ]


def test_distrusted_speakers_and_witness_trust(db: toaster.Database) -> None:
    _flat(db, distrust=["BOB"])
    tell(db, "BOB", F("MARBLE", "IsIn", "BOX"), listeners=["SALLY"], t_ns=4 * S)
    assert _where(db, "SALLY") == {"BASKET"}  # nobody believes Bob
    assert _where(db, "BOB>SALLY") == {"BASKET"}  # and Bob knows it
    api.configure(db, distrust=[], trust="witnesses")
    # Anne saw the marble later than Sally did: Sally believes her ...
    tell(db, "ANNE", F("MARBLE", "IsIn", "BOX"), listeners=["SALLY"], t_ns=5 * S)
    assert _where(db, "SALLY") == {"BOX"}
    # ... but Anne does not believe Sally, who saw it earlier than she did.
    tell(db, "SALLY", F("MARBLE", "IsIn", "BASKET"), listeners=["ANNE"], t_ns=6 * S)
    assert _where(db, "ANNE") == {"BOX"}


def test_a_told_lie_is_refuted_by_seeing(db: toaster.Database) -> None:
    _flat(db)
    tell(db, "BOB", F("MARBLE", "IsIn", "BASKET"), listeners=["SALLY"], t_ns=4 * S)
    assert _where(db, "SALLY") == {"BASKET"}
    st = db.store()
    st.sync_snapshot(
        "s",
        "ROBOT",
        5 * S,
        [
            F("BASKET", "IsInRoom", "ROOM"),
            F("BOX", "IsInRoom", "ROOM"),
            F("ANNE", "IsInRoom", "ROOM"),
            F("BOB", "IsInRoom", "ROOM"),
            F("SALLY", "IsInRoom", "ROOM"),
            F("MARBLE", "IsIn", "BOX"),
        ],
    )
    assert _where(db, "SALLY") == {"BOX"}


def test_public_telling_reaches_the_speakers_room(db: toaster.Database) -> None:
    _flat(db)
    learnt = tell(db, "ANNE", F("MARBLE", "IsIn", "BOX"), t_ns=4 * S)
    assert {"BOB", "ANNE>BOB", "BOB>ANNE"} <= set(learnt)
    assert not [h for h in learnt if "SALLY" in h]  # in the hall: heard nothing


def test_bad_tellings_fail_in_one_line(db: toaster.Database) -> None:
    _flat(db)
    with pytest.raises(InvalidInputError, match="unknown agent 'NOBODY' in a telling"):
        tell(db, "NOBODY", F("MARBLE", "IsIn", "BOX"), listeners=["SALLY"])
    with pytest.raises(InvalidInputError, match="unknown agent 'ANNE>SALLY'"):
        tell(db, "ANNE", F("MARBLE", "IsIn", "BOX"), listeners=["ANNE>SALLY"])


def test_tell_and_actor_from_the_command_line(db_url: str) -> None:
    with toaster.connect(db_url) as db:
        _flat(db)
    runner = CliRunner()
    out = runner.invoke(
        cli,
        ["--db", db_url, "tell", "ROBOT", "MARBLE", "IsIn", "BOX", "--to", "SALLY", "--at", "4s"],
    )
    assert out.exit_code == 0, out.output
    assert "SALLY" in out.output
    # Sally, in the hall, puts the cup on the shelf: she knows, Anne and Bob do not.
    out = runner.invoke(
        cli,
        [
            "--db",
            db_url,
            "set-info",
            "FACT",
            "--agent",
            "ROBOT",
            "--subject",
            "CUP",
            "--property",
            "IsOn",
            "--target",
            "SHELF",
            "--actor",
            "SALLY",
            "--at",
            "5s",
        ],
    )
    assert out.exit_code == 0, out.output
    bad = runner.invoke(
        cli,
        [
            "--db",
            db_url,
            "set-info",
            "FACT",
            "--agent",
            "ROBOT",
            "--subject",
            "CUP",
            "--property",
            "IsOn",
            "--target",
            "TABLE",
            "--actor",
            "NOBODY",
            "--at",
            "6s",
        ],
    )
    assert bad.exit_code != 0 and "unknown actor 'NOBODY'" in bad.output
    with toaster.connect(db_url) as db:
        assert _where(db, "SALLY") == {"BOX"}
        assert api.belief_value(db, "SALLY", "CUP", "IsOn", "SHELF") is not None
        assert api.belief_value(db, "ANNE", "CUP", "IsOn", "SHELF") is None
        assert api.belief_value(db, "ROBOT", "CUP", "IsOn", "TABLE") is None  # nothing written


def test_attention_off_by_default_changes_nothing(db: toaster.Database) -> None:
    """Default behaviour stays as it was: being in the room is enough."""
    _flat(db)
    assert _where(db, "ANNE") == {"BOX"}
    assert api.config(db)["attention"] == {}


def test_a_told_fact_takes_the_robots_sub_property(db: toaster.Database) -> None:
    """The robot's IsInRoom facts carry the areas producer's sub-property ``room``; a telling
    that names none is about the same key: Sally, told where Bob is (truly), holds no false
    belief, and one told where he is not believes it on the robot's key."""
    api.configure(db, depth=1)
    st = db.store()
    st.add_entity("ROBOT", "robot", is_self=True, t_ns=0)
    for who in ("SALLY", "ANNE", "BOB"):
        st.add_entity(who, "human", t_ns=0)
    st.sync_snapshot(
        "areas",
        "ROBOT",
        1 * S,
        [
            F("SALLY", "IsInRoom", "HALL", sub_property="room"),
            F("ANNE", "IsInRoom", "HALL", sub_property="room"),
            F("BOB", "IsInRoom", "ROOM", sub_property="room"),
        ],
    )
    tell(db, "ANNE", F("BOB", "IsInRoom", "ROOM"), listeners=["SALLY"], t_ns=2 * S)
    assert [d for d in api.false_beliefs(db, "SALLY") if d.subject_id == "BOB"] == []
    told = [r for r in api.beliefs(db, "SALLY", subject="BOB") if r.property == "IsInRoom"]
    assert [(r.target_id, r.sub_property, r.source) for r in told] == [
        ("ROOM", "room", "told:ANNE")
    ]
