"""The pure mapping (no ROS process): ROS 1 messages from Debian's classes and the shipped
toaster_msgs, ROS 2 messages from rosbags' type store (the same functions serve both)."""

from __future__ import annotations

import io
import math
import sys
import threading
from pathlib import Path
from typing import Any

import pytest

from toaster.errors import InvalidInputError
from toaster.model import Fact
from toaster.outputs import markers
from toaster.world import geometry
from toaster.world import rosmsg as mapping
from toaster.world.rosmsg import TfTree
from toaster.world.state import World


@pytest.fixture(scope="module")
def reg() -> Any:
    """The toaster_msgs classes (needs Debian's genpy; skips without it, fails under CI)."""
    from tests.ros1.conftest import require_ros
    from toaster.ros1 import RosUnavailableError, import_rospy, messages

    try:
        import_rospy()
    except RosUnavailableError as exc:
        require_ros()  # skips (fails under CI) when ROS 1 is not installed
        pytest.fail(f"ROS 1 is installed but the venv cannot import it: {exc}")
    return messages.load()


def tf_msg(*edges: tuple[str, str, tuple[float, float, float], float, int]) -> Any:
    from geometry_msgs.msg import TransformStamped  # type: ignore[import-not-found]
    from tf2_msgs.msg import TFMessage  # type: ignore[import-not-found]

    out = []
    for parent, child, (x, y, z), yaw, stamp in edges:
        tr = TransformStamped()
        tr.header.frame_id, tr.child_frame_id = parent, child
        tr.header.stamp.secs, tr.header.stamp.nsecs = divmod(stamp, 1_000_000_000)
        tr.transform.translation.x, tr.transform.translation.y = x, y
        tr.transform.translation.z = z
        q = geometry.rpy_to_quat(0.0, 0.0, yaw)
        r = tr.transform.rotation
        r.x, r.y, r.z, r.w = q
        out.append(tr)
    return TFMessage(transforms=out)


@pytest.mark.slow
def test_tf_chain_is_composed_up_to_map(reg: Any) -> None:
    tree = TfTree()
    frames = mapping.read_frame_map(
        {
            "cup_link": {"id": "cup"},
            "hand": {"kind": "joint", "owner": "bob", "joint": "rightHand"},
            "lost": {"id": "ghost", "kind": "human"},
        }
    )
    changed, bad = tree.update(
        tf_msg(
            ("map", "table", (1.0, 0.0, 0.5), math.pi / 2, 5),
            ("/table", "cup_link", (1.0, 0.0, 0.1), 0.0, 7),
            ("map", "hand", (0.0, 0.0, 1.0), 0.0, 0),
            ("odom", "lost", (0.0, 0.0, 0.0), 0.0, 0),
        )
    )
    assert not bad and changed == {"table", "cup_link", "hand", "lost"}
    updates, lost = mapping.tf_updates(tree, frames, changed)
    by_id = {u.entity_id: u for u in updates}
    cup = by_id["cup"]
    assert cup.position == pytest.approx((1.0, 1.0, 0.6)) and cup.t_ns == 7
    assert mapping.quat(type("Q", (), dict(zip("xyzw", cup.quat, strict=True)))()) == (
        pytest.approx(geometry.rpy_to_quat(0.0, 0.0, math.pi / 2))
    )
    hand = by_id["bob/rightHand"]
    assert (hand.kind, hand.owner_id, hand.joint, hand.t_ns) == ("joint", "bob", "rightHand", None)
    assert lost == ["lost"]
    _, bad = tree.update(tf_msg(("map", "x", (math.nan, 0.0, 0.0), 0.0, 0)))
    assert bad and "finite" in bad[0]


@pytest.mark.slow
def test_poses_of_one_call_come_from_the_same_messages(reg: Any) -> None:
    """rospy's thread stores /tf messages while the tick composes poses: every pose of one
    tf_updates call comes from the same message (each moves a human's body and its head
    together), never one from each."""
    tree = TfTree()
    frames = mapping.read_frame_map(
        {f"h{i}": {"id": f"h{i}", "kind": "human"} for i in range(40)}
        | {f"h{i}_head": {"kind": "joint", "owner": f"h{i}", "joint": "head"} for i in range(40)}
    )

    def message(x: float) -> Any:
        return tf_msg(
            *[
                edge
                for i in range(40)
                for edge in (
                    ("map", f"h{i}", (x, float(i), 0.0), 0.0, 1),
                    ("map", f"h{i}_head", (x, float(i), 1.7), 0.0, 1),
                )
            ]
        )

    moves = [message(0.0), message(1.6)]
    tree.update(moves[0])
    stop = threading.Event()

    def publish() -> None:
        n = 0
        while not stop.is_set():
            n += 1
            tree.update(moves[n % 2])

    interval = sys.getswitchinterval()
    sys.setswitchinterval(1e-6)  # switch threads as often as the interpreter can
    publisher = threading.Thread(target=publish)
    publisher.start()
    try:
        seen = [
            {u.position[0] for u in mapping.tf_updates(tree, frames, frames)[0]} for _ in range(300)
        ]
    finally:
        stop.set()
        publisher.join()
        sys.setswitchinterval(interval)
    assert all(len(xs) == 1 for xs in seen), [sorted(xs) for xs in seen if len(xs) > 1][:3]


def test_the_same_functions_read_ros2_messages() -> None:
    from rosbags.typesys import Stores, get_typestore

    types = get_typestore(Stores.ROS2_HUMBLE).types
    time_cls, header_cls = types["builtin_interfaces/msg/Time"], types["std_msgs/msg/Header"]
    stamp = time_cls(sec=3, nanosec=5)
    assert mapping.stamp_ns(stamp) == 3_000_000_005
    tr = types["geometry_msgs/msg/TransformStamped"](
        header=header_cls(stamp=stamp, frame_id="map"),
        child_frame_id="cup_link",
        transform=types["geometry_msgs/msg/Transform"](
            translation=types["geometry_msgs/msg/Vector3"](x=1.0, y=2.0, z=3.0),
            rotation=types["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
        ),
    )
    tree = TfTree()
    changed, _ = tree.update(types["tf2_msgs/msg/TFMessage"](transforms=[tr]))
    updates, _ = mapping.tf_updates(tree, mapping.read_frame_map({"cup_link": "cup"}), changed)
    assert updates[0].position == (1.0, 2.0, 3.0) and updates[0].t_ns == 3_000_000_005


def test_frame_map_files_and_errors(tmp_path: Path) -> None:
    path = tmp_path / "frames.yaml"
    path.write_text(
        "frames:\n  /base_link: {id: pr2, kind: robot}\n  head_cam: {kind: joint, "
        "owner: pr2, joint: head}\n"
    )
    frames = mapping.read_frame_map(path)
    assert frames["base_link"] == mapping.FrameTarget("pr2", "robot")
    assert frames["head_cam"].entity_id == "pr2/head"
    (tmp_path / "f.json").write_text('{"mug_frame": {"id": "mug"}}')
    assert mapping.read_frame_map(tmp_path / "f.json")["mug_frame"].kind == "object"
    for bad in (
        {"f": {"id": "x", "kind": "table"}},
        {"f": {"kind": "joint", "joint": "h"}},
        {"f": {"kind": "human"}},
        ["f"],
    ):
        with pytest.raises(InvalidInputError):
            mapping.read_frame_map(bad)  # type: ignore[arg-type]
    (tmp_path / "bad.yaml").write_text("frames: [unclosed")
    with pytest.raises(InvalidInputError, match="not valid"):
        mapping.read_frame_map(tmp_path / "bad.yaml")
    with pytest.raises(InvalidInputError, match="cannot read"):
        mapping.read_frame_map(tmp_path / "missing.yaml")


def test_pose_stamped_in_another_frame_and_bad_poses(reg: Any) -> None:
    from geometry_msgs.msg import PoseStamped  # type: ignore[import-not-found]

    tree = TfTree()
    tree.update(tf_msg(("map", "cam", (0.0, 0.0, 2.0), math.pi, 0)))
    msg = PoseStamped()
    msg.header.frame_id = "cam"
    msg.pose.position.x = 1.0
    update = mapping.pose_stamped_update(msg, "mug", "object", tree=tree)
    assert update.position == pytest.approx((-1.0, 0.0, 2.0))
    msg.header.frame_id = "nowhere"
    with pytest.raises(ValueError, match="nowhere"):
        mapping.pose_stamped_update(msg, "mug", tree=tree)
    msg.header.frame_id, msg.pose.position.y = "map", math.nan
    with pytest.raises(ValueError, match="finite"):
        mapping.pose_stamped_update(msg, "mug")


def test_entity_lists_hri_frames_and_ids(reg: Any) -> None:
    from toaster.ros1.messages import to_msg

    human = {
        "meAgent": {
            "meEntity": {
                "id": "bob",
                "time": 9,
                "pose": {"position": {"x": 1, "y": 2, "z": 0}, "orientation": {"w": 1}},
            },
            "skeletonNames": ["head"],
            "skeletonJoint": [
                {"meEntity": {"id": "j", "pose": {"position": {"x": 1, "y": 2, "z": 1.7}}}}
            ],
        }
    }
    bad = {"meAgent": {"meEntity": {"id": "nan", "pose": {"position": {"x": math.nan}}}}}
    msg = to_msg(
        reg.msg("HumanListStamped"), {"header": {"stamp": 4}, "humanList": [human, bad]}, reg
    )
    updates, problems = mapping.list_updates(msg)
    assert [(u.entity_id, u.kind, u.owner_id, u.joint, u.t_ns) for u in updates] == [
        ("bob", "human", "", "", 9),
        ("bob/head", "joint", "bob", "head", 4),
    ]
    assert updates[1].quat == geometry.IDENTITY and "nan" in problems[0]
    assert mapping.hri_target("face_7") == mapping.FrameTarget("7/head", "joint", "7", "head")
    assert mapping.hri_target("body_7") == mapping.FrameTarget("7", "human")
    assert mapping.hri_target("map") is None
    ids = to_msg(reg.msg("hri_msgs/IdsList"), {"ids": ["a", "b"]}, reg)
    assert mapping.tracked_ids(ids) == {"a", "b"}


def test_facts_and_areas_survive_the_wire(reg: Any) -> None:
    fact = Fact(
        "bob/rightHand", "Distance", "cup", "close", 0.12, 0.9, 0.0, "position", "3D", "bob", ""
    )
    msg = reg.msg("Fact")(**mapping.fact_fields(fact, 42))
    buf = io.BytesIO()
    msg.serialize(buf)
    back = reg.msg("Fact")()
    back.deserialize(buf.getvalue())
    # the original's Distance: valueType 0, the label in stringValue, metres in doubleValue
    assert (back.valueType, back.stringValue, back.doubleValue) == (False, "close", 0.12)
    assert back.time == 42 and mapping.fact_from_msg(back) == fact
    assert mapping.fact_from_msg(reg.msg("Fact")(subjectId="a", property="p")).value_text == "true"
    from toaster.ros1.messages import to_msg

    area = to_msg(
        reg.msg("Area"),
        {
            "name": "desk",
            "isCircle": True,
            "ray": 0.5,
            "height": 1.0,
            "center": {"x": 1, "y": 2, "z": 0.5},
            "enterHysteresis": 0.1,
            "entityType": "humans",
            "factType": "interaction",
            "myOwner": "pr2",
        },
        reg,
    )
    name, spec = mapping.area_from_msg(area)
    assert (name, spec["shape"], spec["radius"], spec["height"], spec["owner"]) == (
        "desk",
        "circle",
        0.5,
        1.0,
        "pr2",
    )
    assert spec["center"] == [1.0, 2.0, 0.5] and spec["facts"] == ["interaction"]
    fields = mapping.area_fields(name, spec, 3, ["bob"])
    assert (fields["id"], fields["ray"], fields["insideEntities_"]) == (3, 0.5, ["bob"])
    to_msg(reg.msg("Area"), fields, reg)  # every field has the message's type


def test_service_md5_sums_match_genmsg(reg: Any, tmp_path: Path) -> None:
    from roscpp.srv import GetLoggers  # type: ignore[import-not-found]

    from toaster.ros1 import messages

    (tmp_path / "p/msg").mkdir(parents=True)
    (tmp_path / "p/srv").mkdir()
    (tmp_path / "p/msg/Logger.msg").write_text("string name\nstring level\n")
    (tmp_path / "p/srv/GetLoggers.srv").write_text("---\nLogger[] loggers\n")
    assert messages.load(tmp_path).srv("p/GetLoggers")._md5sum == GetLoggers._md5sum
    srv = reg.srv("AddArea")
    assert srv._type == "toaster_msgs/AddArea" and srv._request_class._type.endswith("Request")
    assert len(reg.services) >= 23 and "toaster_msgs/HumanListStamped" in reg.messages


def test_world_as_frames_lists_and_markers() -> None:
    world = World()
    world.add_entity("bob", "human")
    world.add_entity("bob/head", "joint", owner_id="bob", name="head")
    world.add_entity("cup", "object", size=(0.1, 0.1, 0.12))
    for eid, pos in (("bob", (0, 0, 0)), ("bob/head", (0, 0, 1.7)), ("cup", (1, 0, 0.8))):
        world.set_pose(eid, pos, 5)
    world.commit()
    frames = {f for f, *_ in markers.transforms(world)}
    assert frames == {"bob/base", "/bob/head", "/cup"}
    lists = markers.entity_list_fields(world, 5)
    assert lists["human"][0]["meAgent"]["skeletonNames"] == ["head"]
    assert lists["object"][0]["meEntity"]["id"] == "cup"
    arrays = markers.entity_markers(world, 5)
    assert arrays[markers.OBJECTS_TOPIC][0]["action"] == markers.DELETEALL
    cup = next(
        m for m in arrays[markers.OBJECTS_TOPIC] if m["type"] == markers.CUBE and m["ns"] == "cup"
    )
    assert cup["scale"] == {"x": 0.1, "y": 0.1, "z": 0.12}
    assert any(m["type"] == markers.SPHERE_LIST for m in arrays[markers.HUMANS_TOPIC])
    areas = {
        "front": {
            "shape": "polygon",
            "points": [[0, -1], [2, -1], [2, 1], [0, 1]],
            "owner": "bob",
            "z_min": None,
        },
        "mat": {"shape": "circle", "center": [3, 3], "radius": 0.5},
    }
    world.rpy[world.index["bob"], 2] = math.pi / 2
    drawn = markers.area_markers(world, areas, {"mat"}, 5)
    front = next(m for m in drawn if m["ns"] == "front" and m["type"] == markers.LINE_STRIP)
    assert front["points"][1]["x"] == pytest.approx(1.0) and front["points"][1]["y"] == (
        pytest.approx(2.0)
    )
    mat = next(m for m in drawn if m["ns"] == "mat" and m["type"] == markers.CYLINDER)
    assert mat["scale"]["x"] == 1.0 and mat["color"]["a"] == 0.5
    motion = markers.motion_markers(
        world,
        [
            Fact("bob", "IsMoving", "", "true", 1.2, 0.8),
            Fact("bob", "IsLookingAt", "cup", "", 0.1),
            Fact("ghost", "IsMoving", ""),
        ],
        5,
    )
    assert [m["ns"] for m in motion[1:]] == ["IsMoving", "IsLookingAt"]
    assert motion[2]["points"][0]["z"] == pytest.approx(1.7)  # from bob's head
