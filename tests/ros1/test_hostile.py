"""Hostile ROS input against a real roscore and a real ``toaster serve --ros1``: ids the store
refuses (300 characters, NUL, 1 MB, '>' in an agent's id), NaN / infinite poses, bad
quaternions, unknown ids in services. The node keeps running, answers, drops each bad input
with a warning line naming the topic, field and value, and counts it (status service)."""

from __future__ import annotations

import math
import re
import time
from typing import Any

import pytest

import toaster
from tests.processes import NodeProcess, wait_for
from tests.ros1.conftest import RosClient
from toaster import queries as q

SELF = "toaster"
LONG = "x" * 300
NUL = "cup\x00evil"
HUGE = "h" * 1_000_000
IDENTITY = {"x": 0, "y": 0, "z": 0, "w": 1}
ROOM = {
    "id": 0,
    "name": "room",
    "areaType": "room",
    "entityType": "entities",
    "poly": {
        "points": [{"x": -1, "y": -1}, {"x": 5, "y": -1}, {"x": 5, "y": 3}, {"x": -1, "y": 3}]
    },
}


def entity(
    entity_id: str, x: float, y: float = 0.0, orientation: dict[str, float] | None = None
) -> dict[str, Any]:
    return {
        "meEntity": {
            "id": entity_id,
            "name": entity_id[:20],
            "pose": {
                "position": {"x": x, "y": y, "z": 0.0},
                "orientation": orientation or IDENTITY,
            },
        }
    }


def pose(x: float, y: float = 0.0) -> dict[str, Any]:
    return {"position": {"x": x, "y": y, "z": 0.0}, "orientation": IDENTITY}


def relative_position(client: RosClient, subject: str, target: str) -> Any:
    """The answer of /area_manager/get_relative_position."""
    return client.call(
        "/area_manager/get_relative_position",
        "GetRelativePosition",
        subjectId=subject,
        targetId=target,
    )["answer"]


def status(client: RosClient) -> str:
    answer = client.call("/toaster/get_status", "std_srvs/Trigger")
    assert answer["success"], answer
    return str(answer["message"])


def dropped(client: RosClient, key: str) -> int:
    """The count of ``key`` ("topic field") in the status line's drops, 0 when absent."""
    found = re.search(re.escape(key) + r" (\d+)", status(client))
    return int(found.group(1)) if found else 0


def known(db: toaster.Database, entity_id: str) -> bool:
    return any(e.id == entity_id for e in q.entities(db, entity_id))


@pytest.mark.slow
def test_bad_ids_and_poses_in_an_object_list_are_dropped_the_rest_is_taken(
    node: NodeProcess, client: RosClient, db: toaster.Database
) -> None:
    """One objectList with a 300-character id and a NUL id killed the node (exit 1)."""
    client.publish(
        "/toaster_simu/objectList",
        "ObjectListStamped",
        {
            "header": {"stamp": "now", "frame_id": "map"},
            "objectList": [
                entity(LONG, 1.0),
                entity(NUL, 2.0),
                entity("nan_box", math.nan),
                entity("bad_quat", 1.0, orientation={"x": math.nan, "w": 1}),
                entity("far_box", 1e12),
                entity("cup", 1.0),
            ],
        },
        rate=10,
        key="objects",
    )
    client.publish(
        "/toaster_simu/humanList",
        "HumanListStamped",
        {
            "header": {"stamp": "now", "frame_id": "map"},
            "humanList": [{"meAgent": entity("BOB>ANNE", 0.0)}, {"meAgent": entity("bob", 0.0)}],
        },
        rate=10,
        key="humans",
    )
    wait_for(lambda: known(db, "cup") and known(db, "bob"), "cup and bob registered")
    wait_for(
        lambda: (
            dropped(client, "/toaster_simu/objectList id") >= 2
            and dropped(client, "/toaster_simu/objectList pose") >= 2
            and dropped(client, "/toaster_simu/objectList position") >= 1
            and dropped(client, "/toaster_simu/humanList id") >= 1
        ),
        "the drops counted",
    )
    client.stop("objects")
    client.stop("humans")
    assert node.alive()
    ids = {e.id for e in q.entities(db)}
    assert not {LONG, NUL, "nan_box", "bad_quat", "far_box", "BOB>ANNE"} & ids
    log = wait_for(
        lambda: "(dropped: id" in node.stderr() and node.stderr(), "the warning line of a bad id"
    )
    assert "\x00" not in log  # escaped (one_line), never written raw
    lines = [line for line in log.splitlines() if "/toaster_simu/objectList" in line]
    assert any(
        "(dropped: id" in line and ("at most 256 bytes" in line or "NUL" in line) for line in lines
    ), lines
    assert any("'far_box'" in line and "(dropped: position" in line for line in lines), lines
    assert all(len(line) < 600 for line in lines)  # values shortened
    # rate-limited: ten messages a second for seconds, one line per topic and field
    assert len([line for line in lines if "(dropped: id" in line]) <= 3


@pytest.mark.slow
def test_a_one_megabyte_id_and_nan_poses_through_services_are_refused(
    node: NodeProcess, client: RosClient, db: toaster.Database
) -> None:
    """set_entity_pose with a 1 MB id killed the node (exit 1)."""
    answer = client.call(
        "/toaster_simu/set_entity_pose", "SetEntityPose", id=HUGE, type="object", pose=pose(1.0)
    )
    assert answer["answer"] is False
    for bad in (
        {"position": {"x": math.inf, "y": 0, "z": 0}, "orientation": IDENTITY},
        {"position": {"x": 1, "y": 0, "z": 0}, "orientation": {"x": math.nan}},
    ):
        assert (
            client.call("/pdg/set_entity_pose", "SetEntityPose", id="cup", type="object", pose=bad)[
                "answer"
            ]
            is False
        )
    assert (
        client.call("/toaster_simu/add_entity", "AddEntity", id=HUGE, type="object")["answer"]
        is False
    )
    assert (
        client.call("/toaster_simu/add_entity", "AddEntity", id="EVE>BOB", type="human")["answer"]
        is False
    )
    assert (
        client.call(
            "/toaster_simu/add_entity", "AddEntity", id="hand\x00", type="joint", ownerId="bob"
        )["answer"]
        is False
    )
    assert not client.call_raw(
        "/pdg/put_in_hand", "PutInHand", objectId=HUGE, agentId="bob", jointName="rightHand"
    )["ok"]
    wait_for(
        lambda: (
            dropped(client, "/toaster_simu/set_entity_pose id") >= 1
            and dropped(client, "/pdg/set_entity_pose pose") >= 2
        ),
        "the refusals counted",
    )
    assert node.alive()
    time.sleep(0.5)  # commands would be applied at the next tick: none may have been queued
    assert node.alive() and not known(db, "EVE>BOB")
    assert len(node.stderr()) < 200_000  # no 1 MB id copied into the log


@pytest.fixture
def cup_and_bob(client: RosClient, db: toaster.Database) -> None:
    """A cup and bob on the node's lists, whichever tests of this module ran before."""
    header = {"stamp": "now", "frame_id": "map"}
    client.publish(
        "/toaster_simu/objectList",
        "ObjectListStamped",
        {"header": header, "objectList": [entity("cup", 1.0)]},
        rate=10,
        key="cup",
    )
    client.publish(
        "/toaster_simu/humanList",
        "HumanListStamped",
        {"header": header, "humanList": [{"meAgent": entity("bob", 0.0)}]},
        rate=10,
        key="bob",
    )
    wait_for(lambda: known(db, "cup") and known(db, "bob"), "cup and bob registered")


@pytest.mark.usefixtures("cup_and_bob")
def test_services_answer_false_for_unknown_ids(
    node: NodeProcess, client: RosClient, db: toaster.Database
) -> None:
    """They answered true (set_entity_pose even created the entity)."""
    assert (
        client.call(
            "/toaster_simu/set_entity_pose",
            "SetEntityPose",
            id="ghost",
            type="object",
            pose=pose(3.0),
        )["answer"]
        is False
    )
    assert client.call("/agent_monitor/add_agent", "AddAgent", id="nobody")["answer"] is False
    assert client.call("/agent_monitor/add_agent", "AddAgent", id="cup")["answer"] is False
    assert client.call("/agent_monitor/remove_agent", "RemoveAgent", id="nobody")["answer"] is False
    assert (
        client.call(
            "/agent_monitor/remove_all_joints_to_agent", "RemoveAllJointsToAgent", agentId="nobody"
        )["answer"]
        is False
    )
    refused = client.call_raw(
        "/pdg/put_in_hand", "PutInHand", objectId="ghost", agentId="bob", jointName="rightHand"
    )
    assert not refused["ok"] and "ghost" in refused["error"] and "no known" in refused["error"]
    refused = client.call_raw(
        "/pdg/put_in_hand", "PutInHand", objectId="cup", agentId="nobody", jointName="rightHand"
    )
    assert not refused["ok"] and "nobody" in refused["error"]
    refused = client.call_raw("/pdg/remove_from_hand", "RemoveFromHand", objectId="cup")
    assert not refused["ok"] and "in no hand" in refused["error"]
    assert relative_position(client, "cup", "ghost") is False
    assert (
        client.call("/agent_monitor/pointing", "Pointing", pointingAgentId="nobody")["answer"]
        is False
    )
    assert client.call("/agent_monitor/add_agent", "AddAgent", id="bob")["answer"] is True
    assert client.call("/agent_monitor/remove_agent", "RemoveAgent", id="bob")["answer"] is True
    time.sleep(0.5)  # a queued command would be applied by now
    assert not known(db, "ghost") and node.alive()


@pytest.mark.usefixtures("cup_and_bob")
def test_a_removed_entity_is_found_by_no_query(
    node: NodeProcess, client: RosClient, db: toaster.Database
) -> None:
    assert client.call("/area_manager/add_area", "AddArea", myArea=ROOM)["answer"]
    assert client.call("/toaster_simu/add_entity", "AddEntity", id="stool", type="object")["answer"]
    assert client.call(
        "/toaster_simu/set_entity_pose",
        "SetEntityPose",
        id="stool",
        type="object",
        pose=pose(0.5, 0.5),
    )["answer"]
    wait_for(lambda: known(db, "stool"), "stool registered")
    wait_for(lambda: q.current_facts(db, SELF, subject="stool"), "facts about the stool")
    assert relative_position(client, "cup", "stool") is True
    assert client.call("/toaster_simu/remove_entity", "RemoveEntity", id="stool", type="object")[
        "answer"
    ]
    assert relative_position(client, "cup", "stool") is False
    assert relative_position(client, "stool", "cup") is False
    ids = client.call("/database_manager/get_info", "GetInfoDB", type="ID", subType="ALL")
    assert "stool" not in {i["id"] for i in ids["resId"]}
    wait_for(lambda: not q.current_facts(db, SELF, subject="stool"), "the stool's facts ended")
    client.subscribe("/area_manager/factList", "FactList")
    after = client.latest("/area_manager/factList")["count"]
    facts = client.latest("/area_manager/factList", after=after)["msg"]
    assert "stool" not in {f["subjectId"] for f in facts["factList"]}
    assert (
        client.call(
            "/toaster_simu/set_entity_pose",
            "SetEntityPose",
            id="stool",
            type="object",
            pose=pose(0.5, 0.5),
        )["answer"]
        is False
    )
    assert (
        client.call("/toaster_simu/remove_entity", "RemoveEntity", id="stool", type="object")[
            "answer"
        ]
        is False
    )
    assert node.alive()


@pytest.mark.slow
def test_hostile_tf_frames_are_dropped(node: NodeProcess, client: RosClient) -> None:
    def transform(parent: str, child: str, x: float) -> dict[str, Any]:
        return {
            "header": {"frame_id": parent, "stamp": "now"},
            "child_frame_id": child,
            "transform": {"translation": {"x": x, "y": 0, "z": 0}, "rotation": IDENTITY},
        }

    before = dropped(client, "/tf transform")
    client.publish(
        "/tf",
        "tf2_msgs/TFMessage",
        {
            "transforms": [
                transform("map", "f" * 100_000, 1.0),
                transform("map", "a\x00b", 1.0),
                transform("map", "body_" + LONG, 1.0),
                transform("map", "body_A>B", 1.0),
                transform("map", "body_nan", math.nan),
            ]
        },
        rate=10,
        key="tf",
    )
    wait_for(
        lambda: dropped(client, "/tf transform") >= before + 3 and dropped(client, "/tf id") >= 2,
        "the /tf drops counted",
    )
    client.stop("tf")
    assert node.alive()
