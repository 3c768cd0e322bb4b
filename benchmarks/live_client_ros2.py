"""The external side of `bench_live.py --ros2`: live_client.py's scene (H humans with head and right
hand, N objects, /tf at 30 Hz, each human into and out of its zone once a second) published as
a ROS 2 node does, over DDS with cyclonedds (no toaster, no ROS 2 install), listening to
/area_manager/factList (reliable, depth 10 as rclcpp's default).

As a ROS 2 node spends its time (rclpy on rmw_cyclonedds converts and serializes in C): the
messages go through rosbags' generated codec, about as fast as genpy in the ROS 1 client (0.9
against 0.4 ms for a /tf of 350 transforms; cyclonedds' own Python codec took 5.6 ms, inside
the measured latency), and the fact lists are taken on an executor thread blocked in a DDS
WaitSet, as rclpy's executor waits (not on cyclonedds' receive thread). The bytes go in and
out through cyclonedds' private ``_clayer`` calls, as toaster's bridge does (toaster.ros2.dds;
tests/ros2/test_wire.py fails if the binding changes them).

    ROS_DOMAIN_ID=N python benchmarks/live_client_ros2.py HUMANS OBJECTS SECONDS [CYCLE]

Prints one JSON object as live_client.py does: ``toggles`` and ``seen``.
"""

import json
import os
import sys
import threading
import time
from dataclasses import dataclass, field

from cyclonedds._clayer import ddspy_take, ddspy_write
from cyclonedds.core import (
    InstanceState,
    Policy,
    Qos,
    ReadCondition,
    SampleState,
    ViewState,
    WaitSet,
)
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as t
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration
from rosbags.typesys import Stores, get_types_from_msg, get_typestore

from live_scene import human_pose, joint_offsets, object_pose

#: toaster_msgs/Fact with ROS 2 field names (a ROS 2 workspace's toaster_msgs)
FACT_MSG = """string property
string property_type
string sub_property
string subject_id
string target_id
string subject_owner_id
string target_owner_id
bool value_type
float64 fact_observability
float64 double_value
string string_value
float64 confidence
uint64 time
uint64 time_start
uint64 time_end
"""
TF, FACT_LIST = "tf2_msgs/msg/TFMessage", "toaster_msgs/msg/FactList"
ANY = SampleState.Any | ViewState.Any | InstanceState.Any

# The DDS topics' types (their names and layout, as rmw_cyclonedds declares them); samples are
# not built from these classes.


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


def typestore():
    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(get_types_from_msg(FACT_MSG, "toaster_msgs/msg/Fact"))
    store.register(get_types_from_msg("toaster_msgs/Fact[] fact_list\n", FACT_LIST))
    return store


def write(writer: DataWriter, data: bytes) -> None:
    """A sample's CDR bytes, padded to 4 bytes as cyclonedds' DataWriter.write pads them."""
    ret = ddspy_write(writer._ref, bytes(data) + b"\0" * (-len(data) % 4))
    if ret < 0:
        msg = f"DDS write failed ({ret})"
        raise OSError(msg)


def executor(reader: DataReader, on_data, stop: threading.Event) -> threading.Thread:
    """rclpy's single-threaded executor in short: a thread blocked in a WaitSet on the reader's
    data, taking what came (the DDS call gives the interpreter away while it waits)."""
    waitset = WaitSet(reader.participant)
    waitset.attach(ReadCondition(reader, ANY))

    def spin() -> None:
        while not stop.is_set():
            if waitset.wait(duration(milliseconds=100)):
                for data, info in ddspy_take(reader._ref, ANY, 100):
                    if info.valid_data:
                        on_data(data)

    thread = threading.Thread(target=spin, daemon=True)
    thread.start()
    return thread


def main() -> None:
    humans, objects, seconds = int(sys.argv[1]), int(sys.argv[2]), float(sys.argv[3])
    cycle = float(sys.argv[4]) if len(sys.argv) > 4 else 1.0
    sys.setswitchinterval(0.001)  # as live_client.py: the executor is not kept waiting
    store = typestore()
    types = store.types
    stamp_t, header_t = types["builtin_interfaces/msg/Time"], types["std_msgs/msg/Header"]
    vector, quaternion = types["geometry_msgs/msg/Vector3"], types["geometry_msgs/msg/Quaternion"]
    stamped, transform_t = (
        types["geometry_msgs/msg/TransformStamped"],
        types["geometry_msgs/msg/Transform"],
    )
    tf_message = types[TF]
    identity = quaternion(x=0.0, y=0.0, z=0.0, w=1.0)

    def transform(child: str, x: float, y: float, z: float, header):
        move = transform_t(translation=vector(x=x, y=y, z=z), rotation=identity)
        return stamped(header=header, child_frame_id=child, transform=move)

    dp = DomainParticipant(int(os.environ.get("ROS_DOMAIN_ID", "0")))
    pub = DataWriter(dp, Topic(dp, "rt/tf", TFMessage), qos=reliable(100))
    seen: list[list] = []
    inside_now: set[str] = set()
    lock = threading.Lock()

    def on_facts(data: bytes) -> None:
        msg = store.deserialize_cdr(data, FACT_LIST)
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
    reader = DataReader(dp, facts, qos=reliable(10))
    stop = threading.Event()
    spinner = executor(reader, on_facts, stop)
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
        header = header_t(
            stamp=stamp_t(sec=wall // 1_000_000_000, nanosec=wall % 1_000_000_000),
            frame_id="map",
        )
        transforms = []
        for i in range(humans):
            want, x, y = human_pose(i, humans, elapsed, cycle)
            if want != inside[i]:
                inside[i] = want
                toggles.append([f"h{i}", want, wall])
            transforms.append(transform(f"h{i}_base", x, y, 0.0, header))
            transforms += [
                transform(f"h{i}_{joint}", x + dx, y + dy, dz, header)
                for joint, (dx, dy, dz) in joint_offsets().items()
            ]
        transforms += [transform(f"o{j}", *object_pose(j), header) for j in range(objects)]
        write(pub, store.serialize_cdr(tf_message(transforms=transforms), TF))
        tick += 1
        time.sleep(max(0.0, start + tick / 30 - time.monotonic()))
    time.sleep(1.0)
    stop.set()
    spinner.join(5)
    with lock:
        print(json.dumps({"toggles": toggles, "seen": seen}), flush=True)


if __name__ == "__main__":
    main()
