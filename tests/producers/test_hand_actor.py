"""The agent holding an object is the actor of the changes of where it is (both backends).

Producers tick a world into a store (as ``toaster run`` does); the runner names the holder as
the actor of the changed facts about where a held (or just released) object is, so the belief
rule lets the holder perceive them wherever it is, while others perceive them by co-presence.
"""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest

import toaster
from toaster.beliefs import api
from toaster.model import Fact
from toaster.producers import HandActors, Runner, load_session
from toaster.world import World

S = 1_000_000_000
RATE = 10


def _flat(timeline: list[dict[str, Any]], anne: tuple[float, float]) -> dict[str, Any]:
    """A kitchen (x 0-5) beside a hall (x 5-10); Anne, her right hand 0.6 m in front of her,
    and Bob in the kitchen with the mug; no gaze facts (only rooms and hands perceive)."""
    return {
        "name": "carried-mug",
        "self": "ROBOT",
        "rate": RATE,
        "duration": "5s",
        "config": {"monitored_agents": []},
        "areas": {
            "KITCHEN": {
                "shape": "polygon",
                "area_type": "room",
                "points": [[0, 0], [5, 0], [5, 5], [0, 5]],
            },
            "HALL": {
                "shape": "polygon",
                "area_type": "room",
                "points": [[5, 0], [10, 0], [10, 5], [5, 5]],
            },
        },
        "entities": [
            {"id": "ROBOT", "kind": "robot", "position": [0.5, 4.5, 0]},
            {
                "id": "ANNE",
                "kind": "human",
                "position": [*anne, 0],
                "yaw": 0,
                "joints": [{"name": "rightHand", "position": [0.6, -0.2, 1.0]}],
            },
            {"id": "BOB", "kind": "human", "position": [1.0, 2.5, 0], "yaw": 0},
            {"id": "MUG", "position": [2.0, 1.0, 0.8]},
        ],
        "timeline": timeline,
    }


def _run(tmp_path: Path, url: str, scenario: dict[str, Any]) -> toaster.Database:
    path = tmp_path / "story.json"
    path.write_text(json.dumps(scenario))
    db = toaster.connect(url)
    session = load_session(path)
    runner = Runner(
        session.world,
        session.sources,
        session.producers,
        store=db.store(),
        agent_id=session.self_id,
    )
    session.register(db.store())
    runner.run(session.start_ns, session.end_ns, session.rate_hz)
    return db


def _room(db: toaster.Database, holder: str, at: int) -> set[str]:
    """The rooms ``holder`` believes the mug is in at ``at``."""
    return {r.target_id for r in api.beliefs(db, holder, at=at, subject="MUG", property="IsInRoom")}


def _in_hand(db: toaster.Database, holder: str, at: int) -> bool:
    return api.belief_value(db, holder, "MUG", "IsInHand", "ANNE", at=at) is not None


@pytest.mark.slow
def test_the_holder_knows_where_it_passed_the_mug_the_other_saw_it_leave(
    tmp_path: Path, db_url: str
) -> None:
    """Anne, in the kitchen, takes the mug, passes it through the hatch into the hall, lets
    go of it there and walks back: she never was in the hall, yet knows the mug is there (she
    did it); Bob, who stayed in the kitchen, saw it leave and does not know where it went."""
    db = _run(
        tmp_path,
        db_url,
        _flat(
            [
                {"at": "1s", "put_in_hand": "MUG", "agent": "ANNE", "hand": "rightHand"},
                {
                    "at": "2s",
                    "move": "ANNE",
                    "waypoints": [[4.6, 2.5]],
                    "speed": 2,
                },  # hand at x 5.2
                {"at": "3s", "remove_from_hand": "MUG"},
                {"at": "3.5s", "move": "ANNE", "waypoints": [[1.5, 2.5]], "speed": 2},
            ],
            anne=(3.5, 2.5),
        ),
    )
    try:
        for at in (int(1.5 * S), int(2.8 * S), int(3.2 * S), 5 * S):
            assert api.belief_value(db, "ROBOT", "ANNE", "IsInRoom", "KITCHEN", at=at)
        assert _room(db, "ROBOT", 1 * S) == {"KITCHEN"}
        assert _room(db, "ANNE", 1 * S) == _room(db, "BOB", 1 * S) == {"KITCHEN"}
        # In her hand: everyone in the kitchen sees it there.
        assert _in_hand(db, "ANNE", int(1.5 * S)) and _in_hand(db, "BOB", int(1.5 * S))
        # Through the hatch, still in her hand: the robot and Anne know it is in the hall.
        at = int(2.8 * S)
        assert _room(db, "ROBOT", at) == {"HALL"}
        assert _room(db, "ANNE", at) == {"HALL"} and _in_hand(db, "ANNE", at)
        assert _room(db, "BOB", at) == set()  # saw it leave the kitchen, not where it went
        # Let go of in the hall, Anne back at the far end of the kitchen.
        end = 5 * S
        assert _room(db, "ROBOT", end) == {"HALL"}
        assert _room(db, "ANNE", end) == {"HALL"} and not _in_hand(db, "ANNE", end)
        assert _room(db, "BOB", end) == set()
        assert not _in_hand(db, "BOB", end)  # the hand is in the kitchen: Bob saw her let go
    finally:
        db.close()


@pytest.mark.slow
def test_carried_out_of_the_room_the_holder_knows_at_every_tick(
    tmp_path: Path, db_url: str
) -> None:
    """Anne walks into the hall with the mug in hand (the hand crosses the door before her):
    at every tick she believes it is where the robot sees it; Bob, staying in the kitchen,
    sees it leave and then believes it in no room."""
    db = _run(
        tmp_path,
        db_url,
        _flat(
            [
                {"at": "1s", "put_in_hand": "MUG", "agent": "ANNE", "hand": "rightHand"},
                {"at": "2s", "move": "ANNE", "waypoints": [[8.0, 2.5]], "speed": 1},
            ],
            anne=(3.45, 2.5),
        ),
    )  # never on the door line (x 5) at a tick: in one room at a time
    try:
        crossed = []
        for tick in range(RATE, 5 * RATE + 1):
            at = tick * S // RATE
            robot, anne = _room(db, "ROBOT", at), _room(db, "ANNE", at)
            assert anne == robot, at
            anne_in = {
                r.target_id
                for r in api.beliefs(db, "ROBOT", at=at, subject="ANNE", property="IsInRoom")
            }
            if robot == {"HALL"} and anne_in == {"KITCHEN"}:
                crossed.append(at)  # the mug in the hall, Anne not yet: only acting tells her
            assert _room(db, "BOB", at) == (set() if robot == {"HALL"} else {"KITCHEN"}), at
        assert crossed  # the story does test the actor
    finally:
        db.close()


def test_hand_actors_follow_hands_between_ticks() -> None:
    """Who moves what, as the world changes between two updates (a live node's ``hand put``
    / ``hand remove`` commands apply before its tick): the holder while held and in the tick
    it lets go; IsInHand by the hand's agent; only agents holding their own beliefs act."""
    world = World()
    for who in ("ANNE", "BOB", "ROBOT"):
        world.add_entity(who, "robot" if who == "ROBOT" else "human")
        world.add_entity(f"{who}/hand", "joint", owner_id=who, name="hand")
    world.add_entity("MUG")
    hands = HandActors()
    agents = {"ANNE": False, "BOB": False, "ROBOT": True, "ANNE>BOB": False}
    room = Fact("MUG", "IsInRoom", "HALL", property_type="position")
    assert hands.update(world) == {} and hands.actor_of(agents) is None
    world.put_in_hand("MUG", "ANNE", "hand")
    assert hands.update(world) == {"MUG": "ANNE"}
    actor_of = hands.actor_of(agents)
    assert actor_of is not None
    assert actor_of(room) == "ANNE"
    assert actor_of(Fact("MUG", "IsInHand", "ANNE", property_type="position")) == "ANNE"
    assert actor_of(Fact("MUG", "IsClosed", "", property_type="state")) is None
    assert actor_of(Fact("CUP", "IsInRoom", "HALL", property_type="position")) is None
    world.put_in_hand("MUG", "BOB", "hand")  # handed over: each made its own IsInHand change
    assert hands.update(world) == {"MUG": "BOB"}
    actor_of = hands.actor_of(agents)
    assert actor_of is not None
    assert actor_of(Fact("MUG", "IsInHand", "ANNE")) == "ANNE"
    assert actor_of(Fact("MUG", "IsInHand", "BOB")) == "BOB" == actor_of(room)
    world.remove_from_hand("MUG")
    assert hands.update(world) == {"MUG": "BOB"}  # the tick it is let go of
    assert hands.update(world) == {}
    world.put_in_hand("MUG", "ROBOT", "hand")  # the self agent knows anyway: no actor
    hands.update(world)
    actor_of = hands.actor_of(agents)
    assert actor_of is not None and actor_of(room) is None
    world.add_entity("PLATE")  # the world grows between two updates
    world.remove_from_hand("MUG")
    assert hands.update(world) == {"MUG": "ROBOT"}


def test_a_thing_moved_next_to_a_hand_was_moved_by_that_hand() -> None:
    """Not held, yet moved: the agent whose hand is within reach of where it is now (the
    nearest hand) moved it; a thing that moved with no hand near has no actor."""
    world = World()
    for who, x in (("ANNE", 0.0), ("BOB", 3.0)):
        world.add_entity(who, "human")
        world.set_pose(who, [x, 0.0, 0.0], 1)
        world.add_entity(f"{who}/hand", "joint", owner_id=who, name="rightHand")
        world.set_joint_local(f"{who}/hand", [0.5, 0.0, 1.0])
        world.add_entity(f"{who}/head", "joint", owner_id=who, name="head")
        world.set_joint_local(f"{who}/head", [0.0, 0.0, 1.7])
    world.add_entity("MUG")
    world.set_pose("MUG", [1.5, 0.0, 1.0], 1)
    world.add_entity("BALL")
    world.set_pose("BALL", [9.0, 0.0, 0.0], 1)
    world.commit()
    hands = HandActors(reach=0.25, moved=0.05)
    assert hands.update(world) == {}  # first sight: nothing moved yet
    world.set_pose("MUG", [3.6, 0.1, 1.0], 2)  # next to Bob's hand (x 3.5)
    world.set_pose("BALL", [9.5, 0.0, 0.0], 2)  # rolled away from everyone
    world.commit()
    assert hands.update(world) == {"MUG": "BOB"}
    world.set_pose("MUG", [3.62, 0.1, 1.0], 3)  # 2 cm: not a move
    world.commit()
    assert hands.update(world) == {}
    actor_of = HandActors().actor_of({"BOB": False})
    assert actor_of is None  # nothing moved: no per-fact actors at all
