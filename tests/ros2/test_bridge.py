"""The ROS 2 bridge end to end: ``toaster serve --ros2`` in its own process on a SQLite file,
and a ROS 2 peer (cyclonedds and rosbags, no toaster: tests/ros2/peer.py) publishing /tf,
/tf_static, a PoseStamped topic and ROS4HRI's tracked bodies, reading the fact lists, markers,
/tf and the status line, and calling a service. Assertions read the database with toaster's
queries and the peer's payloads as rosbags decoded them."""

from __future__ import annotations

from pathlib import Path
from typing import Any

import pytest

import toaster
from tests.processes import NodeProcess, wait_for
from tests.ros2.conftest import Peer
from toaster import queries as q

pytestmark = pytest.mark.slow
TF_MAP = """frames:
  cup_link: {id: cup, kind: object}
  bob_link: {id: bob, kind: human}
"""
TF = "tf2_msgs/msg/TFMessage"


def transform(parent: str, child: str, x: float, y: float, z: float) -> dict[str, Any]:
    return {
        "header": {"frame_id": parent, "stamp": "now"},
        "child_frame_id": child,
        "transform": {"translation": {"x": x, "y": y, "z": z}, "rotation": {"w": 1.0}},
    }


@pytest.fixture(scope="module")
def node_args(tmp_path_factory: pytest.TempPathFactory) -> list[str]:
    frames = tmp_path_factory.mktemp("ros2_frames") / "frames.yaml"
    frames.write_text(TF_MAP)
    return ["--tf-map", str(frames), "--pose-topic", "/mocap/box=box:object"]


@pytest.fixture(scope="module")
def world(node: NodeProcess, peer: Peer, db: toaster.Database) -> Peer:
    """bob (/tf) at the origin, a cup (/tf_static chain map -> table_link -> cup_link), a box
    (PoseStamped topic), alice (ROS4HRI: tracked body and its body_alice frame)."""
    moving = [transform("map", "bob_link", 0, 0, 0), transform("map", "body_alice", 1, 1, 0)]
    peer.send("publish", topic="/tf", type=TF, msg={"transforms": moving}, rate=20)
    static = [
        transform("map", "table_link", 2.0, 0.0, 0.7),
        transform("table_link", "cup_link", 0.1, 0.0, 0.05),
    ]
    peer.send("publish", topic="/tf_static", type=TF, msg={"transforms": static}, qos="latched")
    box = {
        "header": {"frame_id": "map", "stamp": "now"},
        "pose": {"position": {"x": -1.0, "y": 0.5, "z": 0.0}, "orientation": {"w": 1.0}},
    }
    peer.send("publish", topic="/mocap/box", type="geometry_msgs/msg/PoseStamped", msg=box, rate=10)
    tracked = {"header": {"stamp": "now"}, "ids": ["alice"]}
    peer.send(
        "publish", topic="/humans/bodies/tracked", type="hri_msgs/msg/IdsList", msg=tracked, rate=5
    )
    wanted = {"bob", "cup", "box", "alice"}
    wait_for(
        lambda: wanted <= {e.id for e in q.entities(db)},
        message=f"entities {sorted(wanted)} from /tf, /tf_static, /mocap/box and ROS4HRI",
    )
    return peer


def test_inputs_become_entities_of_their_kind(world: Peer, db: toaster.Database) -> None:
    kinds = {e.id: e.kind for e in q.entities(db)}
    assert (kinds["bob"], kinds["cup"], kinds["box"], kinds["alice"]) == (
        "human",
        "object",
        "object",
        "human",
    )


def test_fact_lists_decode_with_rosbags(world: Peer) -> None:
    """toaster_msgs/FactList with the ROS 2 field names, read by rosbags' CDR codec."""
    answer = wait_for(
        lambda: _has_present(world.send("latest", topic="/pdg/factList", type=FACT_LIST)),
        message="bob isPresent on /pdg/factList",
    )
    fact = next(f for f in answer["msg"]["fact_list"] if f["subject_id"] == "bob")
    assert (fact["property"], fact["string_value"], fact["value_type"]) == (
        "isPresent",
        "true",
        False,
    )
    assert fact["time"] > 0 and 0 < fact["confidence"] <= 1


FACT_LIST = "toaster_msgs/msg/FactList"


def _has_present(answer: dict[str, Any]) -> dict[str, Any] | None:
    facts = answer["msg"]["fact_list"]
    return answer if any(f["subject_id"] == "bob" for f in facts) else None


def test_markers_and_tf_out(world: Peer) -> None:
    markers = world.send(
        "latest",
        topic="/toaster_visualizer/marker_object",
        type="visualization_msgs/msg/MarkerArray",
    )["msg"]["markers"]
    assert markers and all(m["header"]["frame_id"] for m in markers)

    def cup_frame() -> dict[str, Any] | None:
        sent = world.send("latest", topic="/tf", type=TF)["msg"]["transforms"]
        return next((t for t in sent if t["child_frame_id"] == "cup"), None)

    cup = wait_for(cup_frame, message="the cup's frame on toaster's /tf")
    assert cup["header"]["frame_id"] == "map"
    got = cup["transform"]["translation"]
    assert (round(got["x"], 3), round(got["y"], 3), round(got["z"], 3)) == (2.1, 0.0, 0.75)


def test_status_service_and_latched_status(world: Peer) -> None:
    answer = world.send("call", service="/toaster/get_status", type="std_srvs/srv/Trigger")
    assert answer["msg"]["success"] is True and "ticks" in answer["msg"]["message"]
    line = world.send("latest", topic="/toaster/status", type="std_msgs/msg/String")
    assert line["msg"]["data"].startswith("status: up")


def test_toaster_msgs_service_with_ros2_field_names(world: Peer) -> None:
    """GetRelativePosition: the request's ROS 2 fields (subject_id) reach the original's
    handler, its answer comes back in ROS 2 fields (angle_value); a bad request answers false."""
    srv = "toaster_msgs/srv/GetRelativePosition"
    name = "/area_manager/get_relative_position"
    good = world.send(
        "call", service=name, type=srv, request={"subject_id": "bob", "target_id": "cup"}
    )["msg"]
    assert good["answer"] is True and good["direction"], good
    bad = world.send(
        "call", service=name, type=srv, request={"subject_id": "bob", "target_id": "nobody"}
    )["msg"]
    assert bad["answer"] is False


def test_node_log_is_clean(world: Peer, node: NodeProcess) -> None:
    log = node.stderr()
    assert "Traceback" not in log and "reply not sent" not in log, log[-2000:]
    assert Path(node.url.removeprefix("sqlite:///")).exists()
