"""ROS bags in: `toaster run BAG` replays ROS 1 and ROS 2 bags through the live bridge's
mapping, deterministically, to the same facts as the recording they were made from."""

from __future__ import annotations

import math
import subprocess
import sys
from pathlib import Path

import numpy as np
import pytest

import toaster
from tests.conftest import shared_data
from toaster.world.bags import typestore
from toaster.world.tracks import read_obsmat

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

pytest.importorskip("rosbags")


def _header(store, t_ns: int, frame: str = "map"):
    time_t = store.types["builtin_interfaces/msg/Time"]
    return store.types["std_msgs/msg/Header"](
        stamp=time_t(sec=t_ns // 10**9, nanosec=t_ns % 10**9), frame_id=frame
    )


def _pose(store, x: float, y: float, z: float, yaw: float):
    t = store.types
    return t["geometry_msgs/msg/Pose"](
        position=t["geometry_msgs/msg/Point"](x=x, y=y, z=z),
        orientation=t["geometry_msgs/msg/Quaternion"](
            x=0.0, y=0.0, z=math.sin(yaw / 2), w=math.cos(yaw / 2)
        ),
    )


def write_eth_bag(obsmat: Path, out: Path, seconds: float) -> None:
    """The ETH tracks as the original pdg publishes them: one HumanListStamped per frame on
    /pdg/humanList, in a ROS 1 bag."""
    from rosbags.rosbag1 import Writer

    store = typestore()
    t = store.types
    source = read_obsmat(obsmat)
    end = source.start_ns + int(seconds * 1e9)
    with Writer(out) as writer:
        conn = writer.add_connection(
            "/pdg/humanList", "toaster_msgs/msg/HumanListStamped", typestore=store
        )
        for stamp in sorted(set(source.t.tolist())):
            if stamp > end:
                break
            humans = []
            for i in range(len(source.t)):
                if source.t[i] != stamp:
                    continue
                x, y, z = source.pos[i]
                entity = t["toaster_msgs/msg/Entity"](
                    id=source.ids[i],
                    name=source.ids[i],
                    time=stamp,
                    pose=_pose(store, float(x), float(y), float(z), float(source.rpy[i][2])),
                    inArea=np.zeros(0, np.uint32),
                )
                agent = t["toaster_msgs/msg/Agent"](
                    meEntity=entity,
                    mobility=0,
                    busyHands=[],
                    hasObjects=[],
                    skeletonNames=[],
                    skeletonJoint=[],
                )
                humans.append(t["toaster_msgs/msg/Human"](meAgent=agent, age=0))
            msg = t["toaster_msgs/msg/HumanListStamped"](
                header=_header(store, stamp), humanList=humans
            )
            writer.write(conn, stamp, store.serialize_ros1(msg, conn.msgtype))


def run(db_path: Path, *args: str) -> subprocess.CompletedProcess[str]:
    result = subprocess.run(
        [sys.executable, "-m", "toaster", "--db", f"sqlite:///{db_path}", "run", *args],
        capture_output=True,
        text=True,
        timeout=300,
    )
    return result


def intervals(db_path: Path) -> set[tuple]:
    with toaster.connect(f"sqlite:///{db_path}") as db, db.transaction() as conn:
        return set(
            conn.exec_driver_sql(
                "SELECT k.subject_id, k.property, k.sub_property, k.target_id, f.value_text, "
                "f.valid_from_ns, f.valid_to_ns FROM facts f JOIN fact_keys k ON k.id = f.key_id"
            ).all()
        )


def test_an_eth_bag_replays_to_the_same_facts_as_the_obsmat_file(tmp_path):
    obsmat = shared_data("eth-ucy-opentraj", "ETH", "seq_hotel", "obsmat.txt")
    bag = tmp_path / "hotel.bag"
    write_eth_bag(obsmat, bag, 60.0)
    first = run(tmp_path / "obsmat.db", str(obsmat), "--until", "60s")
    assert first.returncode == 0, first.stderr
    second = run(tmp_path / "bag.db", str(bag), "--until", "60s")
    assert second.returncode == 0, second.stderr
    from_obsmat, from_bag = intervals(tmp_path / "obsmat.db"), intervals(tmp_path / "bag.db")
    assert len(from_obsmat) > 50
    assert from_bag == from_obsmat


def write_tf_bag(out: Path) -> None:
    """A ROS 2 bag (MCAP): bob walks on /tf (map -> odom -> bob_base), a cup on a PoseStamped
    topic, one NaN pose and an unmapped frame."""
    from rosbags.rosbag2 import StoragePlugin, Writer

    store = typestore()
    t = store.types

    def transform(parent: str, child: str, x: float, stamp: int):
        return t["geometry_msgs/msg/TransformStamped"](
            header=_header(store, stamp, parent),
            child_frame_id=child,
            transform=t["geometry_msgs/msg/Transform"](
                translation=t["geometry_msgs/msg/Vector3"](x=x, y=0.0, z=0.0),
                rotation=t["geometry_msgs/msg/Quaternion"](x=0.0, y=0.0, z=0.0, w=1.0),
            ),
        )

    with Writer(out, version=8, storage_plugin=StoragePlugin.MCAP) as writer:
        tf = writer.add_connection("/tf", "tf2_msgs/msg/TFMessage", typestore=store)
        cup = writer.add_connection("/cup_pose", "geometry_msgs/msg/PoseStamped", typestore=store)
        start = 10**9
        for k in range(90):  # 3 s at 30 Hz, 1 m/s
            stamp = start + k * 33_333_333
            msg = t["tf2_msgs/msg/TFMessage"](
                transforms=[
                    transform("map", "odom", 1.0, stamp),
                    transform("odom", "bob_base", k / 30, stamp),
                    transform("map", "unmapped", 0.0, stamp),
                ]
            )
            writer.write(tf, stamp, store.serialize_cdr(msg, tf.msgtype))
            x = float("nan") if k == 40 else 3.0
            pose = t["geometry_msgs/msg/PoseStamped"](
                header=_header(store, stamp), pose=_pose(store, x, 0.0, 0.8, 0.0)
            )
            writer.write(cup, stamp, store.serialize_cdr(pose, cup.msgtype))


def test_a_ros2_bag_with_tf_and_pose_topics_through_a_frame_map(tmp_path):
    bag = tmp_path / "walk"
    write_tf_bag(bag)
    frames = tmp_path / "frames.yaml"
    frames.write_text("bob_base: {id: bob, kind: human}\n")
    db_path = tmp_path / "t.db"
    result = run(db_path, str(bag), "--tf-map", str(frames), "--pose-topic", "/cup_pose=cup:object")
    assert result.returncode == 0, result.stderr
    with toaster.connect(f"sqlite:///{db_path}") as db:
        from toaster.queries import history

        rows = history(db, "toaster")
        moving = [r for r in rows if r.property == "IsMoving" and r.subject_id == "bob"]
        toward = [r for r in rows if r.property == "IsMovingToward" and r.target_id == "cup"]
    assert moving and toward  # bob (map -> odom -> bob_base) walks toward the cup
    # composed through odom: bob started at x = 1
    assert min(r.valid_from_ns for r in moving) >= 10**9


def test_bags_toaster_cannot_use_fail_with_one_line(tmp_path):
    bag = tmp_path / "walk"
    write_tf_bag(bag)
    result = run(tmp_path / "t.db", str(bag))  # no frame map, no pose topic
    assert result.returncode == 1
    assert "holds no pose toaster can use" in result.stderr
    assert "Traceback" not in result.stderr
    broken = tmp_path / "broken.bag"
    broken.write_bytes(b"#ROSBAG V2.0\nnot a bag")
    result = run(tmp_path / "t.db", str(broken))
    assert result.returncode == 1
    assert "cannot read bag" in result.stderr
    assert "Traceback" not in result.stderr
