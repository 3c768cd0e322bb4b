"""The original's pieces toaster lacked (issue 27 item 6), end to end over real ROS: IsSeen,
set_entity_keyboard, publish_all_areas, print_area's entity lists (upcoming and leaving
included), load_save and the /database_manager/tables topic."""

from __future__ import annotations

import sqlite3
import time
from typing import Any

import pytest

import toaster
from tests.processes import NodeProcess, wait_for
from tests.ros1.conftest import RosClient
from toaster import queries as q

SELF = "toaster"
RING = {  # a circle of 2 m around (10, 0) whose boundary is 0.5 m thick on each side
    "id": 7,
    "name": "ring",
    "areaType": "",
    "entityType": "entities",
    "isCircle": True,
    "center": {"x": 10.0, "y": 0.0, "z": 0.0},
    "ray": 2.0,
    "enterHysteresis": 0.5,
    "leaveHysteresis": 0.5,
}


def pose(x: float, y: float, z: float = 0.0) -> dict[str, Any]:
    return {"position": {"x": x, "y": y, "z": z}, "orientation": {"x": 0, "y": 0, "z": 0, "w": 1}}


def transform(parent: str, child: str, x: float, y: float, z: float) -> dict[str, Any]:
    return {
        "header": {"frame_id": parent, "stamp": "now"},
        "child_frame_id": child,
        "transform": {
            "translation": {"x": x, "y": y, "z": z},
            "rotation": {"x": 0, "y": 0, "z": 0, "w": 1},
        },
    }


def seen_by(db: toaster.Database, subject: str) -> set[tuple[str, str]]:
    rows = q.current_facts(db, SELF, property="IsSeen", subject=subject)
    return {(r.target_id, r.sub_property) for r in rows}


def place(client: RosClient, entity_id: str, kind: str, x: float, y: float, z: float = 0) -> None:
    assert client.call("/toaster_simu/add_entity", "AddEntity", id=entity_id, type=kind)["answer"]
    assert client.call(
        "/toaster_simu/set_entity_pose",
        "SetEntityPose",
        id=entity_id,
        type=kind,
        pose=pose(x, y, z),
    )["answer"]


def log_count(client: RosClient) -> int:
    """How many /rosout lines the client got so far (0 before the first)."""
    return int(client.send("latest", topic="/rosout_agg", after=0, timeout=0).get("count", 0))


def logged(client: RosClient, text: str, count: int) -> str:
    """The first /rosout line containing ``text`` after the ``count``-th."""
    deadline = time.monotonic() + 60
    while time.monotonic() < deadline:
        got = client.latest("/rosout_agg", after=count)
        count = got["count"]
        if text in got["msg"]["msg"]:
            return str(got["msg"]["msg"])
    pytest.fail(f"no log line with {text!r}")


@pytest.fixture(scope="module")
def scene(node: NodeProcess, client: RosClient, db: toaster.Database) -> RosClient:
    """A simulated robot pr2 at the origin looking along +x, bob 3 m ahead of it, a mug
    behind it (toaster_simu services)."""
    client.subscribe("/rosout_agg", "rosgraph_msgs/Log")
    place(client, "pr2", "robot", 0, 0)
    place(client, "bob", "human", 3, 0)
    place(client, "mug", "object", -3, 0, 0.8)
    wait_for(lambda: seen_by(db, "bob") == {("pr2", "view")}, message="bob IsSeen pr2")
    return client


def test_is_seen_in_the_simulated_robots_field_of_view(scene: RosClient, db) -> None:
    """Simulated input: the robot sees what is in its camera cone within range."""
    row = q.current_facts(db, SELF, property="IsSeen", subject="bob")[0]
    assert (row.property_type, row.source) == ("affordance", "pdg_seen")
    assert seen_by(db, "mug") == set()  # behind it
    scene.subscribe("/pdg_seen/factList", "FactList")
    facts = scene.latest("/pdg_seen/factList")["msg"]["factList"]
    assert {(f["subjectId"], f["property"], f["targetId"]) for f in facts} == {
        ("bob", "IsSeen", "pr2")
    }


def test_is_seen_from_ros4hri_tracked_ids(scene: RosClient, db) -> None:
    """ROS4HRI's tracked bodies are what the robot detects: h9, behind the robot, is seen
    while listed (by the node's self agent) and no longer once the list stops."""
    scene.publish(
        "/tf",
        "tf2_msgs/TFMessage",
        {"transforms": [transform("map", "body_h9", -2, 1, 0)]},
        rate=20,
        key="h9",
    )
    scene.publish(
        "/humans/bodies/tracked",
        "hri_msgs/IdsList",
        {"header": {"stamp": "now"}, "ids": ["h9"]},
        rate=10,
        key="tracked",
    )
    wait_for(lambda: seen_by(db, "h9") == {(SELF, "detected")}, message="h9 detected")
    scene.stop("tracked")
    wait_for(lambda: not seen_by(db, "h9"), message="h9 no longer detected")
    scene.stop("h9")


def test_set_entity_keyboard_chooses_a_known_entity(scene: RosClient, db) -> None:
    assert scene.call("/toaster_simu/set_entity_keyboard", "AddAgent", id="bob")["answer"]
    from toaster.ros1 import dbcalls

    assert dbcalls.keyboard_entity(db) == "bob"
    assert not scene.call("/toaster_simu/set_entity_keyboard", "AddAgent", id="nobody")["answer"]
    assert dbcalls.keyboard_entity(db) == "bob"


def test_area_lists_print_area_and_publish_all_areas(scene: RosClient, db) -> None:
    """box comes within the ring's nominal circle but not its inner one: upcoming (not
    inside); crate, inside, steps past the nominal circle: leaving (still inside). The area
    list and print_area carry them; publish_all_areas switches the area list off and on."""
    assert scene.call("/area_manager/add_area", "AddArea", myArea=RING)["answer"]
    place(scene, "crate", "object", 10, 0)
    place(scene, "box", "object", 11.8, 0)
    wait_for(lambda: q.current_facts(db, SELF, property="IsInArea", subject="crate"), "crate in")
    assert scene.call(
        "/toaster_simu/set_entity_pose",
        "SetEntityPose",
        id="crate",
        type="object",
        pose=pose(7.7, 0),
    )["answer"]
    scene.subscribe("/area_manager/areaList", "AreaList")

    def ring() -> dict[str, Any] | None:
        areas = scene.latest("/area_manager/areaList", after=0)["msg"]["areaList"]
        found = next(a for a in areas if a["name"] == "ring")
        return found if found["leavingEntities_"] == ["crate"] else None

    area = wait_for(ring, message="crate leaving")
    assert (area["id"], area["insideEntities_"], area["upcomingEntities_"]) == (
        7,
        ["crate"],
        ["box"],
    )
    count = log_count(scene)
    assert scene.call("/area_manager/print_area", "PrintArea", id=7)["answer"]
    line = logged(scene, "area 7 'ring'", count)
    assert "inside ['crate']; upcoming ['box']; leaving ['crate']" in line
    count = log_count(scene)
    scene.call("/area_manager/print_all_areas", "Empty")
    assert "upcoming ['box']" in logged(scene, "area 7 'ring'", count)
    count = log_count(scene)
    scene.call("/area_manager/publish_all_areas", "Empty")
    logged(scene, "/area_manager/areaList is off", count)
    before = scene.latest("/area_manager/areaList")["count"]
    time.sleep(1.0)  # 10 lists a second while on
    assert scene.latest("/area_manager/areaList")["count"] <= before + 1
    scene.call("/area_manager/publish_all_areas", "Empty")
    scene.latest("/area_manager/areaList", after=before + 1)  # on again


def test_database_tables_topic(scene: RosClient) -> None:
    """/database_manager/tables: one DatabaseTable per agent with its current facts; the
    first message after a change says changed."""
    scene.subscribe("/database_manager/tables", "DatabaseTables", connected=True)
    got = scene.latest("/database_manager/tables")["msg"]["tables"]
    robot = next(t for t in got if t["agentName"] == SELF)
    assert any(
        (f["subjectId"], f["property"], f["targetId"]) == ("bob", "IsSeen", "pr2")
        for f in robot["facts"]
    )
    count = scene.latest("/database_manager/tables")["count"]
    assert scene.call(
        "/toaster_simu/set_entity_pose",
        "SetEntityPose",
        id="bob",
        type="human",
        pose=pose(-3, 0),  # behind the robot: bob is no longer seen
    )["answer"]

    def changed() -> dict[str, Any] | None:
        nonlocal count
        got = scene.latest("/database_manager/tables", after=count)
        count = got["count"]
        table = next(t for t in got["msg"]["tables"] if t["agentName"] == SELF)
        return table if table["changed"] else None

    table = wait_for(changed, message="a changed table")
    assert not any(f["subjectId"] == "bob" and f["property"] == "IsSeen" for f in table["facts"])
    after = scene.latest("/database_manager/tables", after=count)["msg"]["tables"]
    assert not next(t for t in after if t["agentName"] == SELF)["changed"]
    scene.call(
        "/toaster_simu/set_entity_pose", "SetEntityPose", id="bob", type="human", pose=pose(3, 0)
    )


def test_load_save_backs_up_and_restores_the_live_database(
    scene: RosClient, node: NodeProcess, db: toaster.Database
) -> None:
    """load_save with the original's fields: toSave copies the live database into a file
    (SQLite's backup API), a load puts it back while the node runs; bad files are refused
    with an SQLite status and a warning line."""
    wait_for(lambda: seen_by(db, "bob") == {("pr2", "view")}, message="bob seen again")
    folder = node.log.parent
    saved = folder / "backup.db"
    assert (
        scene.call("/database_manager/load_save", "LoadSaveDB", fileName=str(saved), toSave=True)[
            "sqlstatus"
        ]
        == 0
    )
    with toaster.connect(f"sqlite:///{saved}") as copy:
        assert ("pr2", "view") in {
            (r.target_id, r.sub_property)
            for r in q.current_facts(copy, SELF, property="IsSeen", subject="bob")
        }
    fact = {"subjectId": "bob", "property": "Likes", "targetId": "mug", "stringValue": "true"}
    assert scene.call(
        "/database_manager/set_info", "SetInfoDB", add=True, infoType="FACT", facts=[fact]
    )["answer"]
    assert q.current_facts(db, SELF, property="Likes")
    assert (
        scene.call("/database_manager/load_save", "LoadSaveDB", fileName=str(saved), toSave=False)[
            "sqlstatus"
        ]
        == 0
    )
    with toaster.connect(node.url) as fresh:
        assert not q.current_facts(fresh, SELF, property="Likes")  # the saved state is back
        before = len(q.memory(fresh, SELF, property="IsSeen", subject="bob"))
        scene.call(
            "/toaster_simu/set_entity_pose",
            "SetEntityPose",
            id="bob",
            type="human",
            pose=pose(-3, 1),
        )
        wait_for(lambda: not seen_by(fresh, "bob"), message="the node writes on after a load")
        assert len(q.memory(fresh, SELF, property="IsSeen", subject="bob")) == before + 1
    bad = folder / "notes.txt"
    bad.write_text("not a database")
    for name, to_save in ((bad, False), (bad, True), (folder / "missing.db", False)):
        answer = scene.call(
            "/database_manager/load_save", "LoadSaveDB", fileName=str(name), toSave=to_save
        )
        assert answer["sqlstatus"] == 1, name
    assert bad.read_text() == "not a database"  # never overwritten
    wait_for(lambda: "is no SQLite" in node.stderr(), message="the refusal's warning line")
    assert node.alive()
    assert sqlite3.connect(saved).execute("PRAGMA integrity_check").fetchone() == ("ok",)
