"""The external side of `bench_live.py --ros2`: live_client.py's scene (H humans with head and right
hand, N objects, /tf at 30 Hz, each human into and out of its zone once a second) published as
a ROS 2 node does, over DDS with cyclonedds (no toaster, no ROS 2 install), listening to
/area_manager/factList (reliable, depth 10 as rclcpp's default).

    ROS_DOMAIN_ID=N python benchmarks/live_client_ros2.py HUMANS OBJECTS SECONDS [CYCLE]

Prints one JSON object as live_client.py does: ``toggles`` and ``seen``.
"""

import json
import os
import sys
import threading
import time
from dataclasses import dataclass, field

from cyclonedds.core import Listener, Policy, Qos
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as t
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration

from live_scene import human_pose, joint_offsets, object_pose


@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: t.int32 = 0
    nanosec: t.uint32 = 0


@dataclass
class Header(IdlStruct, typename="std_msgs::msg::dds_::Header_"):
    stamp: Time = field(default_factory=Time)
    frame_id: str = ""


@dataclass
class Vector3(IdlStruct, typename="geometry_msgs::msg::dds_::Vector3_"):
    x: t.float64 = 0.0
    y: t.float64 = 0.0
    z: t.float64 = 0.0


@dataclass
class Quaternion(IdlStruct, typename="geometry_msgs::msg::dds_::Quaternion_"):
    x: t.float64 = 0.0
    y: t.float64 = 0.0
    z: t.float64 = 0.0
    w: t.float64 = 1.0


@dataclass
class Transform(IdlStruct, typename="geometry_msgs::msg::dds_::Transform_"):
    translation: Vector3 = field(default_factory=Vector3)
    rotation: Quaternion = field(default_factory=Quaternion)


@dataclass
class TransformStamped(IdlStruct, typename="geometry_msgs::msg::dds_::TransformStamped_"):
    header: Header = field(default_factory=Header)
    child_frame_id: str = ""
    transform: Transform = field(default_factory=Transform)


@dataclass
class TFMessage(IdlStruct, typename="tf2_msgs::msg::dds_::TFMessage_"):
    transforms: t.sequence[TransformStamped] = field(default_factory=list)


@dataclass
class Fact(IdlStruct, typename="toaster_msgs::msg::dds_::Fact_"):
    property: str = ""
    property_type: str = ""
    sub_property: str = ""
    subject_id: str = ""
    target_id: str = ""
    subject_owner_id: str = ""
    target_owner_id: str = ""
    value_type: bool = False
    fact_observability: t.float64 = 0.0
    double_value: t.float64 = 0.0
    string_value: str = ""
    confidence: t.float64 = 0.0
    time: t.uint64 = 0
    time_start: t.uint64 = 0
    time_end: t.uint64 = 0


@dataclass
class FactList(IdlStruct, typename="toaster_msgs::msg::dds_::FactList_"):
    fact_list: t.sequence[Fact] = field(default_factory=list)


def reliable(depth: int) -> Qos:
    return Qos(
        Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100)),
        Policy.Durability.Volatile,
        Policy.History.KeepLast(depth),
    )


def transform(child: str, x: float, y: float, z: float, stamp: Time) -> TransformStamped:
    return TransformStamped(
        header=Header(stamp=stamp, frame_id="map"),
        child_frame_id=child,
        transform=Transform(translation=Vector3(x, y, z)),
    )


def main() -> None:
    humans, objects, seconds = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
    cycle = float(sys.argv[4]) if len(sys.argv) > 4 else 1.0
    sys.setswitchinterval(0.001)  # as live_client.py: the receive thread is not kept waiting
    dp = DomainParticipant(int(os.environ.get("ROS_DOMAIN_ID", "0")))
    pub = DataWriter(dp, Topic(dp, "rt/tf", TFMessage), qos=reliable(100))
    seen: list[list] = []
    inside_now: set[str] = set()
    lock = threading.Lock()

    def on_facts(reader: DataReader) -> None:
        for msg in reader.take(N=100):
            now = time.time_ns()
            current = {
                f.subject_id
                for f in msg.fact_list
                if f.property == "IsInArea" and f.target_id == f"zone_{f.subject_id}"
            }
            with lock:
                for human in current ^ inside_now:
                    seen.append([human, human in current, now])
                inside_now.clear()
                inside_now.update(current)

    facts = Topic(dp, "rt/area_manager/factList", FactList)
    reader = DataReader(dp, facts, qos=reliable(10), listener=Listener(on_data_available=on_facts))
    while not pub.get_publication_matched_status().current_count:
        time.sleep(0.05)
    time.sleep(1.0)
    inside = [False] * humans
    toggles: list[list] = []
    start = time.monotonic()
    tick = 0
    while time.monotonic() - start < seconds:
        elapsed = time.monotonic() - start
        wall = time.time_ns()
        stamp = Time(sec=wall // 1_000_000_000, nanosec=wall % 1_000_000_000)
        transforms = []
        for i in range(humans):
            want, x, y = human_pose(i, humans, elapsed, cycle)
            if want != inside[i]:
                inside[i] = want
                toggles.append([f"h{i}", want, wall])
            transforms.append(transform(f"h{i}_base", x, y, 0.0, stamp))
            transforms += [
                transform(f"h{i}_{joint}", x + dx, y + dy, dz, stamp)
                for joint, (dx, dy, dz) in joint_offsets().items()
            ]
        transforms += [transform(f"o{j}", *object_pose(j), stamp) for j in range(objects)]
        pub.write(TFMessage(transforms=transforms))
        tick += 1
        time.sleep(max(0.0, start + tick / 30 - time.monotonic()))
    time.sleep(1.0)
    with lock:
        print(json.dumps({"toggles": toggles, "seen": seen}), flush=True)
    del reader


if __name__ == "__main__":
    main()
