"""Recordings of the shipped scenarios read back by readers toaster does not use to write them:
rosbags' rosbag2 Reader with a typestore built only from the definitions the bag carries, and
Debian's python3-rosbag (under /usr/bin/python3) for ROS 1 bags. The scene (/tf, shapes of
the declared sizes, circles, owner-relative areas) and each agent's beliefs (Sally's false
belief beside the robot's) come back as the scenario declares them."""

from __future__ import annotations

import json
import math
import re
import subprocess
from itertools import pairwise
from pathlib import Path
from typing import Any

import pytest
import yaml  # type: ignore[import-untyped]
from click.testing import CliRunner

import toaster
from tests.outputs.conftest import SYSTEM_PYTHON, require_system_rosbag
from toaster.cli import cli
from toaster.outputs.markers import AREAS_TOPIC, TOPICS
from toaster.outputs.recording import CUBE, CYLINDER, LINE_STRIP, Recorder, record
from toaster.world.rosmsg import rpy_to_quat

pytest.importorskip("rosbags")

S = 1_000_000_000
EXAMPLES = Path(toaster.__file__).parent / "examples"
SALLY = EXAMPLES / "scenario_spatial_sally_anne.yaml"
FLAT = EXAMPLES / "scenario_flat.yaml"
HERE = Path(__file__).resolve().parent


def _run(db_url: str, scenario: Path, out: Path, *extra: str) -> None:
    done = CliRunner().invoke(
        cli, ["--db", db_url, "run", str(scenario), *extra, "--record", str(out)]
    )
    assert done.exit_code == 0, done.output


def _rosbags_read(bag: Path) -> dict[str, list[tuple[int, Any]]]:
    """Every message by topic, decoded by rosbags' rosbag2 reader with types built only from
    the definitions stored in the bag (no toaster code, no installed message packages)."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    out: dict[str, list[tuple[int, Any]]] = {}
    with Reader(bag) as reader:
        for conn in reader.connections:
            store.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
        for conn, stamp, raw in reader.messages():
            out.setdefault(conn.topic, []).append((stamp, store.deserialize_cdr(raw, conn.msgtype)))
    return out


def _scenario(path: Path) -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load(path.read_text())
    return data


def _at(messages: list[tuple[int, Any]], t_ns: int) -> Any:
    """The newest message stamped at or before ``t_ns`` (a channel holds until it changes)."""
    return [msg for stamp, msg in messages if stamp <= t_ns][-1]


def _marble_in(belief: Any) -> set[str]:
    return {f.target_id for f in belief.facts if (f.subject_id, f.property) == ("MARBLE", "IsIn")}


@pytest.mark.slow
def test_sally_anne_scene_and_beliefs(db_url: str, tmp_path: Path) -> None:
    """`toaster run SALLY --record DIR`: a /tf frame per entity under map, the wall (and every
    object) a box of its declared size standing where it is declared, and one typed belief
    channel per holder where Sally's false belief differs from the robot's."""
    bag = tmp_path / "sally"
    _run(db_url, SALLY, bag)
    topics = _rosbags_read(bag)
    declared = {e["id"]: e for e in _scenario(SALLY)["entities"]}
    agents = {i for i, e in declared.items() if e.get("kind") in ("human", "robot")}

    _, tf = topics["/tf"][0]
    frames = {tr.child_frame_id: tr for tr in tf.transforms}
    assert set(frames) == (
        {i for i in declared if i not in agents}
        | {f"{a}/base" for a in agents}
        | {f"{a}/head" for a in agents}
    )
    assert {tr.header.frame_id for tr in tf.transforms} == {"map"}
    wall_tf = frames["WALL"].transform.translation
    assert (wall_tf.x, wall_tf.y, wall_tf.z) == pytest.approx(declared["WALL"]["position"])

    bodies = {
        m.ns: m
        for topic in TOPICS.values()
        for m in topics[topic][0][1].markers
        if m.id == 0 and m.ns
    }
    for entity_id, entity in declared.items():
        if "size" in entity:
            body = bodies[entity_id]
            assert (body.scale.x, body.scale.y, body.scale.z) == pytest.approx(entity["size"])
    wall, (x, y, z), (_, _, height) = (
        bodies["WALL"],
        declared["WALL"]["position"],
        declared["WALL"]["size"],
    )
    assert wall.type == CUBE  # a 4 m wall, not a ball: it hides the door side from the table
    assert (wall.pose.position.x, wall.pose.position.y, wall.pose.position.z) == pytest.approx(
        (x, y, z + height / 2)
    )
    assert bodies["SALLY"].type == CYLINDER

    beliefs = {
        topic.removeprefix("/toaster/beliefs/"): msgs
        for topic, msgs in topics.items()
        if topic.startswith("/toaster/beliefs/")
    }
    assert {"ROBOT", "SALLY", "ANNE", "ANNE/SALLY", "SALLY/ANNE"} <= set(beliefs)
    first = {name: msgs[0][1] for name, msgs in beliefs.items()}
    assert [n for n, m in first.items() if m.is_self] == ["ROBOT"]
    assert (first["ANNE/SALLY"].holder, list(first["ANNE/SALLY"].chain)) == (
        "ANNE>SALLY",
        ["ANNE", "SALLY"],
    )
    assert all(msgs[0][0] == 0 for msgs in beliefs.values())  # every channel from the start
    # 1.5 s: everyone saw the marble go into the basket
    assert {n: _marble_in(_at(beliefs[n], int(1.5 * S))) for n in ("ROBOT", "SALLY")} == {
        "ROBOT": {"BASKET"},
        "SALLY": {"BASKET"},
    }
    # 10 s: Anne moved it into the box while Sally was behind the wall
    held = {
        n: _marble_in(_at(beliefs[n], 10 * S)) for n in ("ROBOT", "ANNE", "SALLY", "ANNE/SALLY")
    }
    assert held == {
        "ROBOT": {"BOX"},
        "ANNE": {"BOX"},
        "SALLY": {"BASKET"},
        "ANNE/SALLY": {"BASKET"},
    }
    fact = next(
        f
        for f in _at(beliefs["SALLY"], 10 * S).facts
        if f.subject_id == "MARBLE" and f.property == "IsIn"
    )
    assert fact.time_start == S and fact.time == _at_stamp(beliefs["SALLY"], 10 * S)
    # the channels change only when the beliefs or their numbers do: no two equal messages in
    # a row
    for msgs in beliefs.values():
        sets = [
            sorted(
                (
                    f.subject_id,
                    f.property,
                    f.target_id,
                    f.string_value,
                    f.time_start,
                    f.double_value,
                    f.confidence,
                )
                for f in m.facts
            )
            for _, m in msgs
        ]
        assert all(a != b for a, b in pairwise(sets))


def _at_stamp(messages: list[tuple[int, Any]], t_ns: int) -> int:
    return [stamp for stamp, _ in messages if stamp <= t_ns][-1]


def _yaw(q: Any) -> float:
    return math.atan2(2 * (q.w * q.z + q.x * q.y), 1 - 2 * (q.y * q.y + q.z * q.z))


@pytest.mark.slow
def test_flat_areas_circles_and_owner_relative(tmp_path: Path) -> None:
    """Circles as discs of the declared centre and radius; the robot's owner-relative area
    drawn where the robot's /tf frame puts it, at every stamp it moved."""
    bag = tmp_path / "flat"
    _run(f"sqlite:///{tmp_path / 'flat.db'}", FLAT, bag, "--until", "20s")
    topics = _rosbags_read(bag)
    areas = _scenario(FLAT)["areas"]
    drawn = topics[AREAS_TOPIC]
    first = {(m.ns, m.type): m for m in drawn[0][1].markers}
    circles = {name: spec for name, spec in areas.items() if spec["shape"] == "circle"}
    assert circles
    for name, spec in circles.items():
        disc = first[name, CYLINDER]
        assert (disc.pose.position.x, disc.pose.position.y) == pytest.approx(spec["center"])
        assert (disc.scale.x, disc.scale.y) == pytest.approx((2 * spec["radius"],) * 2)
    tf_at = {
        stamp: {tr.child_frame_id: tr.transform for tr in msg.transforms}
        for stamp, msg in topics["/tf"]
    }
    front = areas["robot_front"]
    assert len(drawn) >= 2  # redrawn when the robot moved at 17 s
    for stamp, array in drawn:
        outline = next(m for m in array.markers if m.ns == "robot_front" and m.type == LINE_STRIP)
        pose = tf_at[stamp]["pr2/base"]
        c, s = math.cos(_yaw(pose.rotation)), math.sin(_yaw(pose.rotation))
        expected = [
            v
            for px, py in front["points"]
            for v in (pose.translation.x + c * px - s * py, pose.translation.y + s * px + c * py)
        ]
        assert [v for p in outline.points[:-1] for v in (p.x, p.y)] == pytest.approx(expected)
    assert _yaw(tf_at[drawn[-1][0]]["pr2/base"].rotation) == pytest.approx(-1.57)


@pytest.mark.parametrize(
    ("distro", "version"), [("humble", 5), ("iron", 8), ("jazzy", 9), ("kilted", 9)]
)
def test_rosbags_reads_each_distro(tmp_path: Path, distro: str, version: int) -> None:
    """rosbags' reader opens the bag of every distro (it checks the metadata version it
    finds), which is that distro's, and decodes it with that distro's standard types."""
    from rosbags.rosbag2 import Reader
    from rosbags.typesys import Stores, get_typestore

    entities = [("pr2", "robot", 1.0, 2.0, 0.0, 0.5), ("cup", "object", 1, 1, 0.7, 0.0)]
    result = record(tmp_path / distro, [(5 * S, entities, None)], distro=distro)
    info = yaml.safe_load((result.bag / "metadata.yaml").read_text())
    assert info["rosbag2_bagfile_information"]["version"] == version
    store = get_typestore(getattr(Stores, f"ROS2_{distro.upper()}"))
    with Reader(result.bag) as reader:
        assert reader.ros_distro == (distro if version >= 8 else None)
        ((conn, stamp, raw),) = list(
            reader.messages(connections=[c for c in reader.connections if c.topic == "/tf"])
        )
        tf = store.deserialize_cdr(raw, conn.msgtype)
    assert stamp == 5 * S
    assert {tr.child_frame_id for tr in tf.transforms} == {"pr2/base", "cup"}


# -- ROS 1 ----------------------------------------------------------------------------------------
_ROSBAG_SCRIPT = r"""
import json, sys, importlib.util
sys.path.append("/usr/lib/python3/dist-packages")
import rosbag
spec = importlib.util.spec_from_file_location("m", sys.argv[2])
messages = importlib.util.module_from_spec(spec); spec.loader.exec_module(messages)
registry = messages.load()
import tf2_msgs.msg, visualization_msgs.msg, rosgraph_msgs.msg
debian = {"tf2_msgs/TFMessage": tf2_msgs.msg.TFMessage._md5sum,
          "visualization_msgs/MarkerArray": visualization_msgs.msg.MarkerArray._md5sum,
          "rosgraph_msgs/Log": rosgraph_msgs.msg.Log._md5sum}
debian.update({f"toaster_msgs/{n}": registry.msg(n)._md5sum for n in
               ("FactList", "AreaList", "HumanListStamped", "RobotListStamped",
                "ObjectListStamped")})
bag = rosbag.Bag(sys.argv[1])
info = bag.get_type_and_topic_info()
out = {"types": {t: [v.msg_type, info.msg_types[v.msg_type], v.message_count]
                 for t, v in info.topics.items()}, "debian": debian, "beliefs": {}}
for topic, msg, t in bag.read_messages():
    t = t.to_nsec()
    if topic == "/tf" and "tf" not in out:
        out["tf"] = [[tr.header.frame_id, tr.child_frame_id] for tr in msg.transforms]
    elif topic == "/toaster_visualizer/marker_object" and "wall" not in out:
        m = next(m for m in msg.markers if m.ns == "WALL" and m.id == 0)
        out["wall"] = [m.type, m.scale.x, m.scale.y, m.scale.z, m.header.frame_id]
    elif topic.startswith("/toaster/beliefs/") and t <= 10 * 10**9:
        out["beliefs"][topic] = [msg.holder, list(msg.chain), msg.is_self, sorted(
            f.targetId for f in msg.facts if (f.subjectId, f.property) == ("MARBLE", "IsIn"))]
    elif topic == "/toaster/facts":
        out.setdefault("levels", set()).add(msg.level)
out["levels"] = sorted(out["levels"])
print(json.dumps(out))
"""


@pytest.mark.slow
def test_ros1_bag_reads_with_debian_rosbag(tmp_path: Path) -> None:
    """`--record NAME.bag` writes a ROS 1 bag that Debian's rosbag reads: standard types with
    Debian's md5 sums, toaster_msgs with the original's (genmsg's), the wall's box, /tf under
    map, ROS 1 log levels and the belief channels with Sally's false belief."""
    require_system_rosbag()
    bag = tmp_path / "sally.bag"
    _run(f"sqlite:///{tmp_path / 'sally.db'}", SALLY, bag)
    messages_py = Path(toaster.__file__).parent / "ros1" / "messages.py"
    done = subprocess.run(
        [SYSTEM_PYTHON, "-c", _ROSBAG_SCRIPT, str(bag), str(messages_py)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert done.returncode == 0, done.stderr
    out = json.loads(done.stdout)
    types = out["types"]
    for msgtype, md5 in out["debian"].items():
        used = [t for t, (name, _, _) in types.items() if name == msgtype]
        assert used, msgtype
        assert {types[t][1] for t in used} == {md5}, msgtype
    assert types["/toaster/beliefs/SALLY"][0] == "toaster_recording/Beliefs"
    assert {parent for parent, _ in out["tf"]} == {"map"}
    assert "WALL" in {child for _, child in out["tf"]}
    size = {e["id"]: e for e in _scenario(SALLY)["entities"]}["WALL"]["size"]
    assert out["wall"] == [CUBE, *size, "map"]
    assert out["levels"] == [2]  # rosgraph_msgs/Log INFO
    beliefs = out["beliefs"]
    assert beliefs["/toaster/beliefs/ROBOT"] == ["ROBOT", ["ROBOT"], True, ["BOX"]]
    assert beliefs["/toaster/beliefs/SALLY"] == ["SALLY", ["SALLY"], False, ["BASKET"]]
    assert beliefs["/toaster/beliefs/ANNE/SALLY"][1:] == [["ANNE", "SALLY"], False, ["BASKET"]]


def test_holder_topics_are_ros_names(tmp_path: Path) -> None:
    """Holder ids that are not ROS names get a valid, distinct topic by one rule (whatever the
    order they come in); the message keeps the exact id and its chain."""
    from toaster.quoting import ros_id
    from toaster.rules.hook import SEPARATOR

    holders = ["alice", "alice-1", "alice_1", "3po", f"anne{SEPARATOR}sally", "anne/sally"]
    path = tmp_path / "odd"
    with Recorder(path) as rec:
        for holder in holders:
            rec.write_beliefs(S, holder, [toaster.Fact("mug", "IsOn", "table")])
    topics = _rosbags_read(path)
    got = {
        msgs[0][1].holder: (topic, list(msgs[0][1].chain))
        for topic, msgs in topics.items()
        if topic.startswith("/toaster/beliefs/")
    }
    assert set(got) == set(holders)
    names = [topic for topic, _ in got.values()]
    assert len(set(names)) == len(holders)
    token = r"[A-Za-z][A-Za-z0-9]*(_[A-Za-z0-9]+)*"
    assert all(re.fullmatch(rf"(/{token})+", t) for t in names), names
    assert got["alice"][0] == "/toaster/beliefs/alice"
    assert got[f"anne{SEPARATOR}sally"] == ("/toaster/beliefs/anne/sally", ["anne", "sally"])
    assert got["alice-1"][0] == "/toaster/beliefs/x0alice_2d1"
    assert got["anne/sally"][0] == "/toaster/beliefs/x0anne_2fsally"
    assert all(
        ros_id(topic.rsplit("/", 1)[1]) == holder
        for holder, (topic, _) in got.items()
        if SEPARATOR not in holder
    )


def test_failed_recording_leaves_nothing(tmp_path: Path) -> None:
    """A recording that fails half-way (here a bad producer name) is removed, folder or file."""
    from toaster.errors import InvalidInputError

    for path in (tmp_path / "half", tmp_path / "half.bag"):
        with (
            pytest.raises(InvalidInputError, match="a producer name is a ROS name"),
            Recorder(path) as rec,
        ):
            rec.write_frame(S, [("pr2", "robot", 0, 0, 0, 0)])
            rec.write_fact_list(S, "not a name", [])
        assert not path.exists()


def test_tf_rotation_roundtrip_ros1(tmp_path: Path) -> None:
    """ROS 1 bags carry the same full poses as ROS 2 ones (rosbags' ROS 1 reader)."""
    from rosbags.rosbag1 import Reader
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    entities = [("mug", "object", 3.0, 1.0, 0.8, 1.0, 0.3, 0.2)]
    result = record(tmp_path / "pose.bag", [(2 * S, entities, None)])
    assert result.file == result.bag == tmp_path / "pose.bag"
    store = get_typestore(Stores.EMPTY)
    with Reader(result.file) as reader:
        for conn in reader.connections:
            store.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
        ((conn, stamp, raw),) = list(
            reader.messages(connections=[c for c in reader.connections if c.topic == "/tf"])
        )
    (tr,) = store.deserialize_ros1(raw, conn.msgtype).transforms
    q = (
        tr.transform.rotation.x,
        tr.transform.rotation.y,
        tr.transform.rotation.z,
        tr.transform.rotation.w,
    )
    assert stamp == 2 * S and q == pytest.approx(rpy_to_quat(0.3, 0.2, 1.0))
