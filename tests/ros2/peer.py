"""A ROS 2 peer of the toaster node, as a ROS 2 node's DDS traffic looks: written without
toaster (cyclonedds directly, its own IDL types, payloads built and read by rosbags' ROS 2 CDR
codec as raw bytes). JSON lines on stdin, one JSON answer line per command on stdout:

* ``{"op": "publish", "topic": "/tf", "type": "tf2_msgs/msg/TFMessage", "msg": {...},
  "rate": 20, "qos": "reliable"|"latched"|"sensor"}``: publish (again at ``rate`` Hz);
* ``{"op": "latest", "topic": ..., "type": ..., "after": N}``: the newest sample once more than
  ``after`` came (subscribing on first use), as ``{"count": N, "msg": {...}}``;
* ``{"op": "call", "service": ..., "type": "std_srvs/srv/Trigger", "request": {...}}``: a
  service call over ``rq/<name>Request`` / ``rr/<name>Reply`` with rmw_cyclonedds' header.
"""

import json
import random
import struct
import sys
import threading
import time
from dataclasses import dataclass, field
from typing import Any

import numpy as np
from cyclonedds._clayer import ddspy_take, ddspy_write  # the raw bytes, not the IDL codec
from cyclonedds.core import InstanceState, Policy, Qos, SampleState, ViewState
from cyclonedds.domain import DomainParticipant
from cyclonedds.idl import IdlStruct
from cyclonedds.idl import types as t
from cyclonedds.pub import DataWriter
from cyclonedds.sub import DataReader
from cyclonedds.topic import Topic
from cyclonedds.util import duration
from rosbags.typesys import Stores, get_types_from_msg, get_typestore


# -- the IDL of the ROS 2 types used, written from the ROS 2 (Humble) .msg definitions --------
@dataclass
class Time(IdlStruct, typename="builtin_interfaces::msg::dds_::Time_"):
    sec: t.int32 = 0
    nanosec: t.uint32 = 0


@dataclass
class Duration(IdlStruct, typename="builtin_interfaces::msg::dds_::Duration_"):
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
class Point(IdlStruct, typename="geometry_msgs::msg::dds_::Point_"):
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
class Pose(IdlStruct, typename="geometry_msgs::msg::dds_::Pose_"):
    position: Point = field(default_factory=Point)
    orientation: Quaternion = field(default_factory=Quaternion)


@dataclass
class PoseStamped(IdlStruct, typename="geometry_msgs::msg::dds_::PoseStamped_"):
    header: Header = field(default_factory=Header)
    pose: Pose = field(default_factory=Pose)


@dataclass
class ColorRGBA(IdlStruct, typename="std_msgs::msg::dds_::ColorRGBA_"):
    r: t.float32 = 0.0
    g: t.float32 = 0.0
    b: t.float32 = 0.0
    a: t.float32 = 0.0


@dataclass
class CompressedImage(IdlStruct, typename="sensor_msgs::msg::dds_::CompressedImage_"):
    header: Header = field(default_factory=Header)
    format: str = ""
    data: t.sequence[t.uint8] = field(default_factory=list)


@dataclass
class UVCoordinate(IdlStruct, typename="visualization_msgs::msg::dds_::UVCoordinate_"):
    u: t.float32 = 0.0
    v: t.float32 = 0.0


@dataclass
class MeshFile(IdlStruct, typename="visualization_msgs::msg::dds_::MeshFile_"):
    filename: str = ""
    data: t.sequence[t.uint8] = field(default_factory=list)


@dataclass
class Marker(IdlStruct, typename="visualization_msgs::msg::dds_::Marker_"):
    header: Header = field(default_factory=Header)
    ns: str = ""
    id: t.int32 = 0
    type: t.int32 = 0
    action: t.int32 = 0
    pose: Pose = field(default_factory=Pose)
    scale: Vector3 = field(default_factory=Vector3)
    color: ColorRGBA = field(default_factory=ColorRGBA)
    lifetime: Duration = field(default_factory=Duration)
    frame_locked: bool = False
    points: t.sequence[Point] = field(default_factory=list)
    colors: t.sequence[ColorRGBA] = field(default_factory=list)
    texture_resource: str = ""
    texture: CompressedImage = field(default_factory=CompressedImage)
    uv_coordinates: t.sequence[UVCoordinate] = field(default_factory=list)
    text: str = ""
    mesh_resource: str = ""
    mesh_file: MeshFile = field(default_factory=MeshFile)
    mesh_use_embedded_materials: bool = False


@dataclass
class MarkerArray(IdlStruct, typename="visualization_msgs::msg::dds_::MarkerArray_"):
    markers: t.sequence[Marker] = field(default_factory=list)


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


@dataclass
class IdsList(IdlStruct, typename="hri_msgs::msg::dds_::IdsList_"):
    header: Header = field(default_factory=Header)
    ids: t.sequence[str] = field(default_factory=list)


@dataclass
class String(IdlStruct, typename="std_msgs::msg::dds_::String_"):
    data: str = ""


# rmw_cyclonedds' services: the sample identity (uint64 guid, int64 seq) before the fields
@dataclass
class TriggerRequestBody(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Request_body_"):
    structure_needs_at_least_one_member: t.uint8 = 0


@dataclass
class TriggerRequest(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Request_"):
    guid: t.uint64 = 0
    seq: t.int64 = 0
    body: TriggerRequestBody = field(default_factory=TriggerRequestBody)


@dataclass
class TriggerResponseBody(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Response_body_"):
    success: bool = False
    message: str = ""


@dataclass
class TriggerResponse(IdlStruct, typename="std_srvs::srv::dds_::Trigger_Response_"):
    guid: t.uint64 = 0
    seq: t.int64 = 0
    body: TriggerResponseBody = field(default_factory=TriggerResponseBody)


@dataclass
class RelativeRequestBody(
    IdlStruct, typename="toaster_msgs::srv::dds_::GetRelativePosition_Request_body_"
):
    subject_id: str = ""
    target_id: str = ""


@dataclass
class RelativeRequest(IdlStruct, typename="toaster_msgs::srv::dds_::GetRelativePosition_Request_"):
    guid: t.uint64 = 0
    seq: t.int64 = 0
    body: RelativeRequestBody = field(default_factory=RelativeRequestBody)


@dataclass
class RelativeResponseBody(
    IdlStruct, typename="toaster_msgs::srv::dds_::GetRelativePosition_Response_body_"
):
    direction: str = ""
    angle_value: t.float64 = 0.0
    answer: bool = False


@dataclass
class RelativeResponse(
    IdlStruct, typename="toaster_msgs::srv::dds_::GetRelativePosition_Response_"
):
    guid: t.uint64 = 0
    seq: t.int64 = 0
    body: RelativeResponseBody = field(default_factory=RelativeResponseBody)


@dataclass
class Clock(IdlStruct, typename="rosgraph_msgs::msg::dds_::Clock_"):
    clock: Time = field(default_factory=Time)


IDL = {
    "rosgraph_msgs/msg/Clock": Clock,
    "tf2_msgs/msg/TFMessage": TFMessage,
    "geometry_msgs/msg/PoseStamped": PoseStamped,
    "visualization_msgs/msg/MarkerArray": MarkerArray,
    "toaster_msgs/msg/FactList": FactList,
    "hri_msgs/msg/IdsList": IdsList,
    "std_msgs/msg/String": String,
}
SERVICES = {
    "std_srvs/srv/Trigger": (TriggerRequest, TriggerResponse),
    "toaster_msgs/srv/GetRelativePosition": (RelativeRequest, RelativeResponse),
}
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
CDR_LE = b"\x00\x01\x00\x00"  # the encapsulation: plain CDR, little endian


def typestore() -> Any:
    store = get_typestore(Stores.ROS2_HUMBLE)
    types: dict[str, Any] = {}
    types |= get_types_from_msg(FACT_MSG, "toaster_msgs/msg/Fact")
    types |= get_types_from_msg("toaster_msgs/Fact[] fact_list", "toaster_msgs/msg/FactList")
    types |= get_types_from_msg("std_msgs/Header header\nstring[] ids", "hri_msgs/msg/IdsList")
    types |= get_types_from_msg(
        "uint8 structure_needs_at_least_one_member", "std_srvs/msg/Trigger_Request"
    )
    types |= get_types_from_msg("bool success\nstring message", "std_srvs/msg/Trigger_Response")
    relative = "toaster_msgs/msg/GetRelativePosition"
    types |= get_types_from_msg("string subject_id\nstring target_id", f"{relative}_Request")
    types |= get_types_from_msg(
        "string direction\nfloat64 angle_value\nbool answer", f"{relative}_Response"
    )
    store.register(types)
    return store


STORE = typestore()


def qos(kind: str, depth: int = 10) -> Qos:
    reliability = (
        Policy.Reliability.BestEffort
        if kind == "sensor"
        else Policy.Reliability.Reliable(max_blocking_time=duration(milliseconds=100))
    )
    durability = (
        Policy.Durability.TransientLocal if kind == "latched" else Policy.Durability.Volatile
    )
    return Qos(
        reliability,
        durability,
        Policy.History.KeepLast(depth),
        Policy.TypeConsistency.AllowTypeCoercion(ignore_member_names=True),
    )


def build(msgtype: str, value: Any) -> Any:
    """A rosbags message from nested dicts (missing fields zero; "now" stamps)."""
    fields = STORE.fielddefs[msgtype][1]
    args = {}
    for name, (node, spec) in fields:
        given = value.get(name) if isinstance(value, dict) else None
        kind = getattr(node, "name", node)
        if kind == "NAME":
            if spec == "builtin_interfaces/msg/Time" and (given is None or given == "now"):
                ns = time.time_ns() if given == "now" else 0
                args[name] = STORE.types[spec](sec=ns // 10**9, nanosec=ns % 10**9)
            else:
                args[name] = build(spec, given or {})
        elif kind == "BASE":
            zero: Any = "" if spec[0] == "string" else 0
            raw = zero if given is None else given
            args[name] = float(raw) if spec[0].startswith("float") else raw
        else:
            (inner, inner_spec), _ = spec
            items = given or []
            if getattr(inner, "name", inner) == "NAME":
                args[name] = [build(inner_spec, i) for i in items]
            elif inner_spec[0] == "string":
                args[name] = list(items)
            else:
                args[name] = np.asarray(items, dtype=inner_spec[0])
    return STORE.types[msgtype](**args)


def plain(msg: Any) -> Any:
    if hasattr(msg, "__msgtype__"):
        return {k: plain(getattr(msg, k)) for k in msg.__dataclass_fields__ if k != "__msgtype__"}
    if isinstance(msg, list):
        return [plain(m) for m in msg]
    if isinstance(msg, np.ndarray):
        return msg.tolist()
    return msg


class Peer:
    def __init__(self, domain: int) -> None:
        self.dp = DomainParticipant(domain)
        self.topics: dict[str, Topic] = {}
        self.writers: dict[tuple[str, str], DataWriter] = {}
        self.readers: dict[str, DataReader] = {}
        self.latest: dict[str, tuple[int, bytes]] = {}
        self.lock = threading.Lock()
        self.guid = random.getrandbits(63)
        self.seq = 0

    def topic(self, name: str, cls: Any) -> Topic:
        if name not in self.topics:
            self.topics[name] = Topic(self.dp, name, cls)
        return self.topics[name]

    def publish(self, ros_topic: str, msgtype: str, msg: Any, rate: float, kind: str) -> None:
        key = (ros_topic, kind)
        if key not in self.writers:
            depth = 1 if kind == "latched" else 100
            topic = self.topic(f"rt{ros_topic}", IDL[msgtype])
            self.writers[key] = DataWriter(self.dp, topic, qos=qos(kind, depth))
        writer = self.writers[key]

        def send() -> None:
            data = STORE.serialize_cdr(build(msgtype, msg), msgtype)
            assert data[:4] == CDR_LE
            ddspy_write(writer._ref, data)

        send()
        if rate > 0:

            def loop() -> None:
                while True:
                    time.sleep(1.0 / rate)
                    send()

            threading.Thread(target=loop, daemon=True).start()

    def take(self, ros_topic: str) -> None:
        reader = self.readers[ros_topic]
        mask = SampleState.Any | ViewState.Any | InstanceState.Any
        for data, info in ddspy_take(reader._ref, mask, 64):
            if info.valid_data:
                with self.lock:
                    count = self.latest.get(ros_topic, (0, b""))[0]
                    self.latest[ros_topic] = (count + 1, data)

    def get_latest(self, ros_topic: str, msgtype: str, after: int, timeout: float) -> Any:
        if ros_topic not in self.readers:
            kind = "latched" if ros_topic in ("/toaster/status", "/area_manager/areaList") else ""
            kind = "sensor" if ros_topic == "/clock" else kind  # rclcpp's ClockQoS: best effort
            topic = self.topic(f"rt{ros_topic}", IDL[msgtype])
            profile = Qos(*qos(kind or "reliable"), Policy.IgnoreLocal.Participant)
            self.readers[ros_topic] = DataReader(self.dp, topic, qos=profile)
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            self.take(ros_topic)
            count, data = self.latest.get(ros_topic, (0, b""))
            if count > after:
                return {"count": count, "msg": plain(STORE.deserialize_cdr(data, msgtype))}
            time.sleep(0.02)
        return {"error": f"no {msgtype} on {ros_topic} after {after} in {timeout:g} s"}

    def call(self, service: str, srvtype: str, request: Any, timeout: float) -> Any:
        request_cls, reply_cls = SERVICES[srvtype]
        name = service.lstrip("/")
        key = (f"rq/{name}Request", "call")
        if key not in self.writers:
            self.writers[key] = DataWriter(
                self.dp, self.topic(key[0], request_cls), qos=qos("reliable")
            )
            reply_topic = self.topic(f"rr/{name}Reply", reply_cls)
            self.readers[service] = DataReader(self.dp, reply_topic, qos=qos("reliable"))
        writer, reader = self.writers[key], self.readers[service]
        deadline = time.monotonic() + timeout
        while not writer.get_publication_matched_status().current_count:
            if time.monotonic() > deadline:
                return {"error": f"no server of {service}"}
            time.sleep(0.05)
        time.sleep(0.2)  # the reply reader's match with the server's writer too
        self.seq += 1
        request_type = srvtype.replace("/srv/", "/msg/") + "_Request"
        body = STORE.serialize_cdr(build(request_type, request), request_type)
        # the sample identity at offset 0 of the stream, the fields after it at offset 16
        ddspy_write(writer._ref, CDR_LE + struct.pack("<Qq", self.guid, self.seq) + body[4:])
        mask = SampleState.Any | ViewState.Any | InstanceState.Any
        while time.monotonic() < deadline:
            for data, info in ddspy_take(reader._ref, mask, 16):
                if not info.valid_data:
                    continue
                guid, seq = struct.unpack_from("<Qq", data, 4)
                if (guid, seq) == (self.guid, self.seq):
                    reply_type = srvtype.replace("/srv/", "/msg/") + "_Response"
                    body = STORE.deserialize_cdr(CDR_LE + data[20:], reply_type)
                    return {"msg": plain(body)}
            time.sleep(0.02)
        return {"error": f"no reply from {service}"}


def main() -> None:
    peer = Peer(int(sys.argv[1]))
    print(json.dumps({"ready": True}), flush=True)
    for line in sys.stdin:
        cmd = json.loads(line)
        try:
            if cmd["op"] == "publish":
                peer.publish(
                    cmd["topic"],
                    cmd["type"],
                    cmd["msg"],
                    cmd.get("rate", 0),
                    cmd.get("qos", "reliable"),
                )
                out: Any = {"ok": True}
            elif cmd["op"] == "latest":
                out = peer.get_latest(
                    cmd["topic"], cmd["type"], cmd.get("after", 0), cmd.get("timeout", 60)
                )
            else:
                out = peer.call(
                    cmd["service"], cmd["type"], cmd.get("request", {}), cmd.get("timeout", 60)
                )
        except Exception as exc:  # report, keep serving
            out = {"error": f"{type(exc).__name__}: {exc}"}
        print(json.dumps(out), flush=True)


if __name__ == "__main__":
    main()
