"""The ROS 1 bridge end to end: a real roscore, the toaster node in its own process on a
SQLite file, and a rospy client process publishing poses, calling the original's services
and reading the fact lists. Assertions read the database with toaster's queries."""

from __future__ import annotations

import math
import time
from pathlib import Path
from typing import Any

import pytest

import toaster
from tests.processes import NodeProcess, wait_for
from tests.ros1.conftest import RosClient
from toaster import queries as q

SELF = "toaster"
TF_MAP = """frames:
  cup_link: {id: cup, kind: object}
  bob_hand: {kind: joint, owner: bob, joint: rightHand}
"""
KITCHEN = {
    "id": 0,
    "name": "kitchen",
    "areaType": "room",
    "entityType": "entities",
    "poly": {
        "points": [{"x": -1, "y": -1}, {"x": 5, "y": -1}, {"x": 5, "y": 3}, {"x": -1, "y": 3}]
    },
}
ALL_STREAMS = (
    "morseHuman",
    "niutHuman",
    "groupHuman",
    "mocapHuman",
    "adreamMocapHuman",
    "toasterSimuHuman",
    "pr2Robot",
    "spencerRobot",
    "toasterSimuRobot",
    "toasterSimuObject",
    "arObject",
    "om2mObject",
    "gazeboObject",
    "mocapObject",
)


def pose_msg(x: float, y: float, z: float = 0.0, frame: str = "map") -> dict[str, Any]:
    return {
        "header": {"frame_id": frame, "stamp": "now"},
        "pose": {
            "position": {"x": x, "y": y, "z": z},
            "orientation": {"x": 0, "y": 0, "z": 0, "w": 1},
        },
    }


def transform(parent: str, child: str, x: float, y: float, z: float) -> dict[str, Any]:
    return {
        "header": {"frame_id": parent, "stamp": "now"},
        "child_frame_id": child,
        "transform": {
            "translation": {"x": x, "y": y, "z": z},
            "rotation": {"x": 0, "y": 0, "z": 0, "w": 1},
        },
    }


def holds(db: toaster.Database, prop: str, subject: str, target: str | None = None) -> bool:
    filters: dict[str, Any] = {"property": prop, "subject": subject}
    if target is not None:
        filters["target"] = target
    return bool(q.current_facts(db, SELF, **filters))


@pytest.fixture(scope="module")
def node_args(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    frames = tmp_path_factory.mktemp("ros1_frames") / "frames.yaml"
    frames.write_text(TF_MAP)
    return [
        "--tf-map",
        str(frames),
        "--pose-topic",
        "/mocap/bob=bob:human",
        "--pose-topic",
        "/mocap/box=box:object",
    ]


@pytest.fixture(scope="module")
def world(node: NodeProcess, client: RosClient, db: toaster.Database) -> RosClient:
    """bob (pose topic) at the origin with his right hand (TF) 0.5 m ahead, a cup (TF chain
    map -> table_link -> cup_link) at (2.1, 0, 0.75), and the kitchen room around them."""
    client.publish("/mocap/bob", "geometry_msgs/PoseStamped", pose_msg(0, 0), rate=20)
    client.publish(
        "/tf",
        "tf2_msgs/TFMessage",
        {"transforms": [transform("map", "bob_hand", 0.5, 0.0, 1.2)]},
        rate=20,
        key="hand",
    )
    client.publish(
        "/tf_static",
        "tf2_msgs/TFMessage",
        {
            "transforms": [
                transform("map", "table_link", 2.0, 0.0, 0.7),
                transform("/table_link", "cup_link", 0.1, 0.0, 0.05),
            ]
        },
    )
    assert client.call("/area_manager/add_area", "AddArea", myArea=KITCHEN)["answer"]
    wait_for(
        lambda: holds(db, "IsInRoom", "bob", "kitchen") and holds(db, "IsInRoom", "cup", "kitchen"),
        message="bob and cup in the kitchen",
    )
    wait_for(lambda: q.entities(db, "bob/rightHand"), message="bob's right hand")
    return client


@pytest.mark.slow
def test_poses_and_tf_become_stored_facts_and_fact_lists(
    world: RosClient, db: toaster.Database
) -> None:
    row = next(r for r in q.current_facts(db, SELF, property="IsInRoom", subject="cup"))
    assert (row.target_id, row.property_type, row.sub_property) == ("kitchen", "position", "room")
    entities = {e.id: e for e in q.entities(db)}
    assert entities["bob/rightHand"].owner_id == "bob" and entities["cup"].kind == "object"
    world.subscribe("/area_manager/factList", "FactList")
    world.subscribe("/pdg/factList", "FactList")
    facts = world.latest("/area_manager/factList")["msg"]["factList"]
    cup = next(f for f in facts if f["subjectId"] == "cup")
    assert (cup["property"], cup["targetId"], cup["stringValue"], cup["valueType"]) == (
        "IsInRoom",
        "kitchen",
        "true",
        False,
    )
    assert cup["time"] > 0 and cup["confidence"] == 1.0
    pdg = world.latest("/pdg/factList")["msg"]["factList"]
    assert any(f["subjectId"] == "bob" and f["property"] == "isPresent" for f in pdg)


def test_tf_markers_and_area_list_are_published(world: RosClient) -> None:
    world.subscribe("/tf", "tf2_msgs/TFMessage")
    world.subscribe("/toaster_visualizer/marker_human", "visualization_msgs/MarkerArray")
    world.subscribe("/toaster_visualizer/marker_area", "visualization_msgs/MarkerArray")
    world.subscribe("/area_manager/areaList", "AreaList")
    frames: set[str] = set()
    after = 0
    deadline = time.monotonic() + 5
    while not {"bob/base", "/cup", "/bob/rightHand"} <= frames and time.monotonic() < deadline:
        got = world.latest("/tf", after=after)
        after = got["count"]
        frames |= {
            t["child_frame_id"]
            for t in got["msg"]["transforms"]
            if t["header"]["frame_id"] == "map"
        }
    assert {"bob/base", "/cup", "/bob/rightHand"} <= frames
    humans = world.latest("/toaster_visualizer/marker_human")["msg"]["markers"]
    assert any(m["ns"] == "bob" and m["text"] == "bob" for m in humans)
    areas = world.latest("/toaster_visualizer/marker_area")["msg"]["markers"]
    assert any(m["ns"] == "kitchen" and len(m["points"]) == 5 for m in areas)
    area_list = world.latest("/area_manager/areaList")["msg"]["areaList"]
    kitchen = next(a for a in area_list if a["name"] == "kitchen")
    assert kitchen["id"] >= 1 and {"bob", "cup"} <= set(kitchen["insideEntities_"])


def test_agent_monitor_services(world: RosClient, db: toaster.Database) -> None:
    # bob stands still: his monitored right hand gives Distance facts (humans are monitored)
    hand = "bob/rightHand"
    wait_for(lambda: holds(db, "Distance", hand, "cup"), message="Distance facts of bob")
    assert world.call("/agent_monitor/remove_agent", "RemoveAgent", id="bob")["answer"]
    wait_for(lambda: not holds(db, "Distance", hand), message="bob no longer monitored")
    assert world.call("/agent_monitor/add_agent", "AddAgent", id="bob")["answer"]
    assert world.call(
        "/agent_monitor/add_joint_to_agent", "AddJointToAgent", jointName="rightHand", agentId="bob"
    )["answer"]
    wait_for(lambda: holds(db, "Distance", hand, "cup"), message="bob monitored again")
    world.call("/agent_monitor/remove_all_agents", "Empty")
    assert not world.call(
        "/agent_monitor/add_joint_to_agent", "AddJointToAgent", jointName="head", agentId="nobody"
    )["answer"]
    wait_for(lambda: not holds(db, "Distance", hand), message="nobody monitored")
    world.call("/agent_monitor/monitor_all_humans", "MonitorAll", monitorAll=True)
    wait_for(lambda: holds(db, "Distance", hand, "cup"), message="all humans monitored")


def test_pointing_and_relative_positions(world: RosClient) -> None:
    found = world.call(
        "/agent_monitor/pointing",
        "Pointing",
        pointingAgentId="bob",
        pointingJoint="rightHand",
        pointingJointDistThreshold=0.3,
        angleThreshold=0.5,
    )
    assert found["answer"] and found["pointedId"][0] == "cup"
    assert found["confidence"][0] == pytest.approx(1.0)
    at = time.time_ns() - 200_000_000
    past = world.call(
        "/agent_monitor/pointing_time",
        "PointingTime",
        pointingAgentId="bob",
        timePointing=at,
        pointingJoint="rightHand",
        pointingJointDistThreshold=0.3,
        angleThreshold=0.5,
    )
    assert past["answer"] and "cup" in past["pointedId"]
    rel = world.call(
        "/area_manager/get_relative_position",
        "GetRelativePosition",
        subjectId="bob",
        targetId="cup",
    )
    assert rel["answer"] and rel["direction"] == "ahead" and abs(rel["angleValue"]) < 0.1
    multi = world.call(
        "/area_manager/get_multiple_relative_position",
        "GetMultiRelativePosition",
        agentSubjectId="bob",
        objectSubjectId="cup",
        targetId="bob/rightHand",
    )
    assert multi["answer"] and multi["direction"].startswith("back")


def test_put_in_hand_gives_is_in_hand(world: RosClient, db: toaster.Database) -> None:
    world.call(
        "/pdg/put_in_hand", "PutInHand", objectId="cup", agentId="bob", jointName="rightHand"
    )
    wait_for(lambda: holds(db, "IsInHand", "cup", "bob"), message="IsInHand cup bob")
    row = q.current_facts(db, SELF, property="IsInHand", subject="cup")[0]
    assert (row.property_type, row.sub_property, row.target_owner_id) == (
        "position",
        "object",
        "bob",
    )
    world.call("/pdg/remove_from_hand", "RemoveFromHand", objectId="cup")
    wait_for(lambda: not holds(db, "IsInHand", "cup"), message="cup released")


def test_watch_service_pushes_matching_events_on_its_topic(world: RosClient) -> None:
    """Subscriptions on ROS: /database_manager/watch opens a topic of BeliefEvents."""
    answer = world.call(
        "/database_manager/watch",
        "Watch",
        agentId="",
        subjectId="cup",
        property="IsInHand",
        targetId="*",
    )
    assert answer["answer"]
    topic = answer["topic"]
    world.subscribe(topic, "toaster_msgs/BeliefEvent", connected=True)
    world.call(
        "/pdg/put_in_hand", "PutInHand", objectId="cup", agentId="bob", jointName="rightHand"
    )
    got = world.latest(topic)["msg"]
    assert (
        got["kind"],
        got["fact"]["subjectId"],
        got["fact"]["property"],
        got["fact"]["targetId"],
    ) == ("appeared", "cup", "IsInHand", "bob")
    world.call("/pdg/remove_from_hand", "RemoveFromHand", objectId="cup")
    got = world.latest(topic, after=1)["msg"]
    assert got["kind"] == "ended"


@pytest.mark.slow
def test_manage_stream_off_stops_updates(world: RosClient, db: toaster.Database) -> None:
    world.publish("/mocap/box", "geometry_msgs/PoseStamped", pose_msg(1, 1), rate=20)
    wait_for(lambda: holds(db, "IsInRoom", "box", "kitchen"), message="box in the kitchen")
    world.call("/pdg/manage_stream", "AddStream", **dict.fromkeys(ALL_STREAMS, False))
    time.sleep(0.3)
    world.publish("/mocap/box", "geometry_msgs/PoseStamped", pose_msg(20, 20), rate=20)
    time.sleep(1.0)
    assert holds(db, "IsInRoom", "box", "kitchen")  # the stream is off: the box stays
    world.call("/pdg/manage_stream", "AddStream", **dict.fromkeys(ALL_STREAMS, True))
    wait_for(lambda: not holds(db, "IsInRoom", "box"), message="box seen leaving")
    world.stop("/mocap/box")


def test_toaster_simu_and_pdg_entity_services(world: RosClient, db: toaster.Database) -> None:
    assert world.call(
        "/toaster_simu/add_entity", "AddEntity", id="chair", name="Chair", type="object"
    )["answer"]
    pose = {
        "position": {"x": 1.0, "y": 2.0, "z": 0.0},
        "orientation": {"x": 0, "y": 0, "z": 0, "w": 1},
    }
    assert world.call(
        "/toaster_simu/set_entity_pose", "SetEntityPose", id="chair", type="object", pose=pose
    )["answer"]
    wait_for(lambda: holds(db, "IsInRoom", "chair", "kitchen"), message="chair placed")
    pose["position"]["x"] = 30.0
    assert world.call(
        "/pdg/set_entity_pose", "SetEntityPose", id="chair", type="object", pose=pose
    )["answer"]
    wait_for(lambda: not holds(db, "IsInRoom", "chair"), message="chair moved out")
    assert world.call("/toaster_simu/remove_entity", "RemoveEntity", id="chair", type="object")[
        "answer"
    ]
    assert not world.call("/toaster_simu/add_entity", "AddEntity", id="x", type="table")["answer"]


def test_database_manager_services(world: RosClient, db: toaster.Database) -> None:
    fact = {
        "subjectId": "cup",
        "property": "IsOn",
        "targetId": "table",
        "stringValue": "true",
        "propertyType": "state",
        "confidence": 0.9,
        "factObservability": 1.0,
    }
    assert world.call(
        "/database_manager/set_info", "SetInfoDB", add=True, infoType="FACT", facts=[fact]
    )["answer"]
    found = world.call(
        "/database_manager/get_info",
        "GetInfoDB",
        type="FACT",
        subType="VALUE",
        reqFact={"subjectId": "cup", "property": "IsOn", "targetId": "table"},
    )
    assert found["boolAnswer"]
    got = found["resFactList"]["factList"][0]
    assert (got["property"], got["confidence"], got["timeEnd"]) == ("IsOn", 0.9, 0)
    assert world.call(
        "/database_manager/execute", "ExecuteDB", command="ARE_IN_TABLE", type="INDIV", facts=[fact]
    )["results"] == ["true"]
    sql = world.call("/database_manager/execute", "ExecuteDB", command="SQL", order="SELECT 1 + 1")
    assert sql["boolAnswer"] and sql["results"] == ["2"]
    ids = world.call("/database_manager/get_info", "GetInfoDB", type="ID", subType="ALL")
    assert {"bob", "cup"} <= {i["id"] for i in ids["resId"]}
    assert world.call(
        "/database_manager/set_info",
        "SetInfoDB",
        add=False,
        infoType="FACT",
        facts=[{"subjectId": "cup", "property": "IsOn", "targetId": "NULL"}],
    )["answer"]
    assert not holds(db, "IsOn", "cup")
    events = world.call(
        "/database_manager/get_info", "GetInfoDB", type="EVENT", subType="ALL", agentId=SELF
    )
    assert "!IsOn" in {e["property"] for e in events["resEventList"]}


def test_plot_facts_writes_the_timeline_under_plot_fact(
    world: RosClient, node: NodeProcess
) -> None:
    """database_manager/plot_facts with the original's fields writes plot_fact/<reqFact>.dat
    (the directory created) holding the fact's level: 1 while bob is in the kitchen."""
    assert world.call(
        "/database_manager/plot_facts",
        "PlotFactsDB",
        subjectID="bob",
        targetID="kitchen",
        fullTime=True,
        reqFact="IsInRoom",
    )["boolAnswer"]
    data = (node.log.parent / "plot_fact" / "IsInRoom.dat").read_text()
    rows = [line.split() for line in data.splitlines() if line and not line.startswith("#")]
    assert rows and rows[0][2] == "1"
    assert (node.log.parent / "plot_fact" / "IsInRoom.gp").exists()
    assert not world.call(
        "/database_manager/plot_facts",
        "PlotFactsDB",
        subjectID="bob",
        targetID="nowhere",
        fullTime=True,
        reqFact="IsInRoom",
    )["boolAnswer"]
    wait_for(
        lambda: "/database_manager/plot_facts: no fact matches" in node.stderr(),
        message="the refusal's warning line",
    )


def test_ros4hri_and_toaster_simu_lists_become_entities(
    world: RosClient, db: toaster.Database
) -> None:
    world.publish(
        "/humans/bodies/tracked",
        "hri_msgs/IdsList",
        {"header": {"stamp": "now"}, "ids": ["h1"]},
        rate=10,
        key="bodies",
    )
    time.sleep(0.5)  # the tracked list first: untracked bodies are then ignored
    world.publish(
        "/tf",
        "tf2_msgs/TFMessage",
        {
            "transforms": [
                transform("map", "body_h1", 1.0, 1.0, 1.0),
                transform("body_h1", "face_h1", 0, 0, 0.6),
                transform("map", "body_ghost", 1.0, 1.0, 1.0),
            ]
        },
        rate=20,
        key="hri",
    )
    human = {
        "meAgent": {
            "meEntity": {
                "id": "alice",
                "name": "Alice",
                "pose": {"position": {"x": 2, "y": 2, "z": 0}, "orientation": {"w": 1}},
            },
            "skeletonNames": ["head"],
            "skeletonJoint": [
                {
                    "jointOwner": "alice",
                    "meEntity": {
                        "id": "head",
                        "pose": {"position": {"x": 2, "y": 2, "z": 1.7}, "orientation": {"w": 1}},
                    },
                }
            ],
        }
    }
    world.publish(
        "/toaster_simu/humanList",
        "HumanListStamped",
        {"header": {"stamp": "now", "frame_id": "map"}, "humanList": [human]},
        rate=20,
        key="simu",
    )
    wait_for(
        lambda: (
            holds(db, "IsInRoom", "h1", "kitchen") and holds(db, "IsInRoom", "alice", "kitchen")
        ),
        message="h1 and alice",
    )
    entities = {e.id: e for e in q.entities(db)}
    assert entities["h1"].kind == "human" and entities["h1/head"].owner_id == "h1"
    assert entities["alice/head"].owner_id == "alice" and "ghost" not in entities
    for key in ("bodies", "hri", "simu"):
        world.stop(key)


@pytest.mark.slow
def test_bad_input_leaves_the_node_running(
    world: RosClient, node: NodeProcess, db: toaster.Database
) -> None:
    # One line per topic and field every 10 s (world.drops): the unknown frame first, its line
    # awaited, then a non-finite pose on the same topic, counted but not logged again.
    world.publish("/mocap/box", "geometry_msgs/PoseStamped", pose_msg(1, 1, frame="nowhere"))
    wait_for(lambda: "nowhere" in node.stderr(), message="the unknown frame's warning")
    world.publish("/mocap/box", "geometry_msgs/PoseStamped", pose_msg(math.nan, 0))
    world.publish(
        "/tf",
        "tf2_msgs/TFMessage",
        {"transforms": [transform("map", "cup_link", math.inf, 0, 0)]},
        key="bad_tf",
    )
    bad = world.call(
        "/area_manager/get_relative_position",
        "GetRelativePosition",
        subjectId="bob",
        targetId="unicorn",
    )
    assert bad["answer"] is False
    assert world.call("/area_manager/remove_area", "RemoveArea", id=999)["answer"] is False
    assert (
        world.call(
            "/pdg/set_entity_pose",
            "SetEntityPose",
            id="box",
            type="object",
            pose={"position": {"x": math.nan, "y": 0, "z": 0}, "orientation": {"w": 1}},
        )["answer"]
        is False
    )
    failed = world.call_raw(
        "/pdg/put_in_hand", "PutInHand", objectId="", agentId="bob", jointName="rightHand"
    )
    assert not failed["ok"] and "object id" in failed["error"]
    world.subscribe("/pdg/factList", "FactList")
    count = world.latest("/pdg/factList")["count"]
    world.latest("/pdg/factList", after=count + 5)  # still ticking
    log = wait_for(lambda: "unicorn" in node.stderr() and node.stderr(), message="warnings")
    for part in ("nowhere", "finite", "unicorn", "999"):
        assert part in log, log[-3000:]
    assert node.alive() and holds(db, "isPresent", "bob")
    assert Path(node.log).exists()
