"""ROS 2's wire conventions as toaster's bridge writes them, checked against the ROS 2 design
documents and rmw_cyclonedds (docs/ros2.md lists the sources), and every message and service
part toaster's IDL types write read back by rosbags' ROS 2 CDR codec (an independent one)."""

from __future__ import annotations

import struct
from typing import Any

import pytest

from tests.ros2.conftest import require_cyclonedds
from toaster.errors import InvalidInputError
from toaster.ros2 import names


@pytest.mark.parametrize(
    ("ros", "dds"),
    [("/tf", "rt/tf"), ("/pdg/factList", "rt/pdg/factList"), ("/a/b/c", "rt/a/b/c")],
)
def test_topic_names(ros: str, dds: str) -> None:
    """design article "Topic and Service name mapping to DDS": the ``rt`` prefix."""
    assert names.topic(ros) == dds


def test_service_names() -> None:
    """The same article: ``rq/<name>Request`` and ``rr/<name>Reply``."""
    assert names.request_topic("/area_manager/add_area") == "rq/area_manager/add_areaRequest"
    assert names.reply_topic("/area_manager/add_area") == "rr/area_manager/add_areaReply"


def test_type_names() -> None:
    """rosidl's DDS IDL: ``pkg::msg::dds_::T_``, a service's parts under ``srv``."""
    assert names.dds_type("tf2_msgs/msg/TFMessage") == "tf2_msgs::msg::dds_::TFMessage_"
    assert names.dds_type("std_srvs/srv/Trigger_Request") == "std_srvs::srv::dds_::Trigger_Request_"


@pytest.mark.parametrize("bad", ["tf", "/tf/", "/a//b", ""])
def test_relative_names_are_refused(bad: str) -> None:
    with pytest.raises(InvalidInputError, match="must be absolute"):
        names.topic(bad)


def test_domain_id(monkeypatch: pytest.MonkeyPatch) -> None:
    monkeypatch.delenv("ROS_DOMAIN_ID", raising=False)
    assert names.domain_id() == 0
    monkeypatch.setenv("ROS_DOMAIN_ID", "42")
    assert names.domain_id() == 42
    assert names.domain_id(7) == 7
    for bad in ("x", "233", "-1"):
        monkeypatch.setenv("ROS_DOMAIN_ID", bad)
        with pytest.raises(InvalidInputError, match="ROS_DOMAIN_ID"):
            names.domain_id()


@pytest.fixture(scope="module")
def types() -> Any:
    require_cyclonedds()
    from toaster.ros2.idl import Types

    return Types()


@pytest.fixture(scope="module")
def rosbags_store() -> Any:
    """rosbags' ROS 2 Humble types, toaster_msgs parsed by rosbags from the shipped .msg
    texts with ROS 2 field names (what the recordings use)."""
    from rosbags.typesys import Stores, get_typestore

    from toaster.outputs.recording.msgs import toaster_types

    store = get_typestore(Stores.ROS2_HUMBLE)
    store.register(toaster_types("ros2"))
    return store


SAMPLES = {
    "tf2_msgs/msg/TFMessage": {
        "transforms": [
            {
                "header": {"stamp": 1_700_000_000_123_456_789, "frame_id": "map"},
                "child_frame_id": "cup",
                "transform": {
                    "translation": {"x": 1.5, "y": -2.0, "z": 0.25},
                    "rotation": {"x": 0, "y": 0, "z": 0.7071, "w": 0.7071},
                },
            }
        ]
    },
    "toaster_msgs/msg/FactList": {
        "factList": [
            {"property": "IsInRoom", "subjectId": "cup", "targetId": "kitchen", "time": 5},
            {"property": "Distance", "doubleValue": 1.25, "valueType": True, "confidence": 0.5},
        ]
    },
    "visualization_msgs/msg/MarkerArray": {
        "markers": [
            {
                "header": {"stamp": 3, "frame_id": "map"},
                "ns": "objects",
                "id": 4,
                "type": 9,
                "points": [{"x": 1}, {"y": 2}],
                "text": "cup",
                "color": {"r": 1, "a": 0.5},
            }
        ]
    },
    "hri_msgs/msg/IdsList": {"header": {"frame_id": "f"}, "ids": ["alice", "bob"]},
    "geometry_msgs/msg/PoseStamped": {"pose": {"position": {"x": 3}, "orientation": {"w": 1}}},
    "std_msgs/msg/String": {"data": "status: up"},
}


@pytest.mark.parametrize("msgtype", sorted(SAMPLES))
def test_rosbags_reads_what_toaster_writes(types: Any, rosbags_store: Any, msgtype: str) -> None:
    data = types.build(msgtype, SAMPLES[msgtype]).serialize()
    assert data[:4] == b"\x00\x01\x00\x00"  # plain CDR (XCDR1), little endian
    back = rosbags_store.deserialize_cdr(data, msgtype)
    again = rosbags_store.serialize_cdr(back, msgtype)
    assert again == data  # rosbags writes the same bytes: layout, alignment and values


def test_every_toaster_message_has_the_rosbags_layout(types: Any, rosbags_store: Any) -> None:
    """Every toaster_msgs / hri_msgs type, zero-filled, reads back in rosbags."""
    from toaster.outputs.recording.msgs import toaster_types

    for msgtype in toaster_types("ros2"):
        data = types.build(msgtype, {}).serialize()
        assert (
            rosbags_store.serialize_cdr(rosbags_store.deserialize_cdr(data, msgtype), msgtype)
            == data
        )


def test_service_parts_carry_rmw_cyclonedds_sample_identity(types: Any) -> None:
    """rmw_cyclonedds_cpp/src/serdata.hpp: ``cdds_request_header_t {uint64 guid; int64 seq}``
    before the request's own fields; an empty request has rosidl's one uint8 member."""
    request = types.wrapped("std_srvs/Trigger", "Request")
    part = types.service_part("std_srvs/Trigger", "Request")
    body = types.build(part, {}, "std_srvs::srv::dds_::Trigger_Request_body_")
    data = request(guid=0x0102030405060708, seq=9, body=body).serialize()
    assert data == b"\x00\x01\x00\x00" + struct.pack("<Qq", 0x0102030405060708, 9) + b"\x00"
    assert request.__idl_typename__ == "std_srvs::srv::dds_::Trigger_Request_"
    reply = types.wrapped("toaster_msgs/AddArea", "Response")
    assert reply.__idl_typename__ == "toaster_msgs::srv::dds_::AddArea_Response_"


def test_values_read_back(types: Any, rosbags_store: Any) -> None:
    """Original field names fill ROS 2 ones; times in ns become sec/nanosec."""
    facts = types.build("toaster_msgs/msg/FactList", SAMPLES["toaster_msgs/msg/FactList"])
    back = rosbags_store.deserialize_cdr(facts.serialize(), "toaster_msgs/msg/FactList")
    first, second = back.fact_list
    assert (first.subject_id, first.target_id, first.time) == ("cup", "kitchen", 5)
    assert (second.double_value, second.value_type, second.confidence) == (1.25, True, 0.5)
    tf = types.build("tf2_msgs/msg/TFMessage", SAMPLES["tf2_msgs/msg/TFMessage"])
    item = rosbags_store.deserialize_cdr(tf.serialize(), "tf2_msgs/msg/TFMessage").transforms[0]
    assert (item.header.stamp.sec, item.header.stamp.nanosec) == (1_700_000_000, 123_456_789)
    assert (item.child_frame_id, item.transform.translation.x) == ("cup", 1.5)


def test_tf_bytes_written_by_rosbags_read_as_arrays(rosbags_store: Any) -> None:
    """toaster.ros2.cdr.read_tf against rosbags' serializer, in both byte orders."""
    require_cyclonedds()
    from toaster.ros2.cdr import read_tf

    types = rosbags_store.types
    msg = types["tf2_msgs/msg/TFMessage"](
        transforms=[
            types["geometry_msgs/msg/TransformStamped"](
                header=types["std_msgs/msg/Header"](
                    stamp=types["builtin_interfaces/msg/Time"](sec=17 + i, nanosec=5),
                    frame_id="map" if i else "a_longer_parent_frame",
                ),
                child_frame_id=f"frame{i}" * (i + 1),
                transform=types["geometry_msgs/msg/Transform"](
                    translation=types["geometry_msgs/msg/Vector3"](x=i, y=0.5, z=-1.0),
                    rotation=types["geometry_msgs/msg/Quaternion"](x=0, y=0, z=0.6, w=0.8),
                ),
            )
            for i in range(3)
        ]
    )
    for little in (True, False):
        data = rosbags_store.serialize_cdr(msg, "tf2_msgs/msg/TFMessage", little_endian=little)
        edges = read_tf(data)
        assert edges.parents == ["a_longer_parent_frame", "map", "map"]
        assert edges.children == ["frame0", "frame1" * 2, "frame2" * 3]
        assert edges.stamps.tolist() == [17_000_000_005, 18_000_000_005, 19_000_000_005]
        assert edges.t.tolist() == [[0, 0.5, -1.0], [1, 0.5, -1.0], [2, 0.5, -1.0]]
        assert edges.q.tolist() == [[0, 0, 0.6, 0.8]] * 3
    for bad in (b"", b"\x00\x01\x00\x00\xff\xff\xff\xff", b"\x07\x07\x00\x00\x00\x00\x00\x00"):
        with pytest.raises(ValueError, match="not a|cannot fit"):
            read_tf(bad)


def test_fact_list_bytes_are_the_codecs_bytes(types: Any, rosbags_store: Any) -> None:
    """toaster.ros2.cdr.fact_list_bytes writes what cyclonedds' codec writes, and rosbags
    reads it."""
    from toaster.model import Fact
    from toaster.ros2.cdr import fact_list_bytes
    from toaster.world.factmsg import fact_fields

    facts = [
        Fact("cup", "IsInRoom", "kitchen"),
        Fact("bob", "Distance", "cup", value_num=1.25, value_text="near", confidence=0.5),
        Fact("h\u00e9l\u00e8ne", "isPresent", ""),
    ]
    items = [fact_fields(f, 7_000_000_000) for f in facts]
    data = fact_list_bytes(items)
    assert data == types.build("toaster_msgs/msg/FactList", {"factList": items}).serialize()
    back = rosbags_store.deserialize_cdr(data, "toaster_msgs/msg/FactList").fact_list
    assert [f.subject_id for f in back] == ["cup", "bob", "h\u00e9l\u00e8ne"]
    assert (back[1].double_value, back[1].time, back[1].confidence) == (1.25, 7_000_000_000, 0.5)
    assert fact_list_bytes([]) == b"\x00\x01\x00\x00\x00\x00\x00\x00"


@pytest.mark.parametrize("seed", range(30))
def test_fact_lists_from_arrays_are_the_codecs_bytes(
    types: Any, rosbags_store: Any, seed: int
) -> None:
    """toaster.ros2.cdr.FactListCdr writes a batch from its arrays as cyclonedds' codec writes
    its facts' fields (random batches: unicode ids, labels, owners, 0-7 bytes of padding),
    and rosbags reads it back."""
    import numpy as np

    from tests.ros1.test_wire import random_batch
    from toaster.ros2.cdr import FactListCdr
    from toaster.world.factmsg import fact_fields

    rng = np.random.default_rng(seed)
    batch = random_batch(rng)
    t_ns = int(rng.integers(0, 2**62))
    items = [fact_fields(f, t_ns) for f in batch.facts()]
    want = types.build("toaster_msgs/msg/FactList", {"factList": items}).serialize()
    writer = FactListCdr()
    assert writer.write(batch, t_ns) == want
    assert writer.write(batch.facts(), t_ns) == want  # a list goes through fact_fields
    back = rosbags_store.deserialize_cdr(want, "toaster_msgs/msg/FactList").fact_list
    assert [f.subject_id for f in back] == [i["subjectId"] for i in items]


def test_a_crowd_s_fact_lists_from_arrays_are_the_codecs_bytes(types: Any) -> None:
    from toaster.node import LiveNode
    from toaster.ros2.cdr import FactListCdr
    from toaster.world.factmsg import fact_fields

    node = LiveNode(None)
    node.areas.set_area("zone", {"shape": "circle", "center": [1.0, 0.0], "radius": 1.0})
    t = 10**18
    for k in range(12):
        t += 33_333_333
        for i in range(30):
            x, y = i % 6 + 0.04 * k * (i % 2), i // 6
            node.api.push(f"h{i}", (x, y, 0.0), yaw=0.1 * i, t_ns=t)
            node.api.push(
                f"h{i}/head", (x, y, 1.7), kind="joint", owner_id=f"h{i}", joint="head", t_ns=t
            )
        node.api.push("cup", (2.0, 2.0, 0.8), kind="object", t_ns=t)
        facts = node.tick(t)
    writer = FactListCdr()
    assert sum(len(f) for f in facts.values()) > 100
    for name in facts:
        items = [fact_fields(f, t) for f in facts[name]]
        want = types.build("toaster_msgs/msg/FactList", {"factList": items}).serialize()
        assert writer.write(facts.raw(name), t) == want, name


def test_a_tf_stream_is_read_with_its_layout_kept(rosbags_store: Any) -> None:
    """toaster.ros2.cdr.TfReader: messages laid out alike (a stream) are read from the kept
    layout, a message laid out otherwise (other frames, a longer name, big endian) anew; each
    one as read_tf reads it."""
    import numpy as np

    from toaster.ros2.cdr import TfReader, read_tf

    types = rosbags_store.types
    rng = np.random.default_rng(5)

    def message(frames: list[str], little: bool = True) -> bytes:
        msg = types["tf2_msgs/msg/TFMessage"](
            transforms=[
                types["geometry_msgs/msg/TransformStamped"](
                    header=types["std_msgs/msg/Header"](
                        stamp=types["builtin_interfaces/msg/Time"](
                            sec=int(rng.integers(0, 2**31)), nanosec=int(rng.integers(0, 10**9))
                        ),
                        frame_id="map",
                    ),
                    child_frame_id=child,
                    transform=types["geometry_msgs/msg/Transform"](
                        translation=types["geometry_msgs/msg/Vector3"](*rng.normal(size=3)),
                        rotation=types["geometry_msgs/msg/Quaternion"](*rng.normal(size=4)),
                    ),
                )
                for child in frames
            ]
        )
        return bytes(
            rosbags_store.serialize_cdr(msg, "tf2_msgs/msg/TFMessage", little_endian=little)
        )

    reader = TfReader()
    streams = [["a", "bb", "ccc"]] * 3 + [["a", "bb", "ccd"], ["a", "bbb", "cc"], ["x"] * 5]
    for frames in [*streams, ["a", "bb", "ccc"]]:
        for little in (True, True, False):
            data = message(frames, little)
            got, want = reader.read(data), read_tf(data)
            assert got.children == want.children == frames
            assert got.parents == want.parents
            assert got.stamps.tolist() == want.stamps.tolist()
            assert got.t.tolist() == want.t.tolist()
            assert got.q.tolist() == want.q.tolist()
    assert reader.read(message([])).children == []


def test_the_binding_s_raw_calls(types: Any, monkeypatch: pytest.MonkeyPatch) -> None:
    """The bridge writes and takes CDR bytes through cyclonedds' private ``_clayer`` calls
    (toaster.ros2.dds.raw_calls): a sample written as bytes arrives as those bytes, at a
    raw reader's listener and at :meth:`Dds.take_raw`, and reads back with the codec. A
    binding that renames or changes them fails here, not in a running node."""
    import random

    from cyclonedds.sub import DataReader

    from tests.processes import wait_for
    from tests.ros2.conftest import LOOPBACK
    from toaster.ros2.dds import Dds, raw_calls, reader_qos

    write, take = raw_calls()
    assert callable(write) and callable(take)
    monkeypatch.setenv("CYCLONEDDS_URI", LOOPBACK)  # this domain stays on the loopback
    dds = Dds(random.randint(1, 230), types)
    try:
        msgtype, topic = "std_msgs/msg/String", "/toaster_raw_check"
        heard: list[bytes] = []
        writer = dds.writer(topic, msgtype, "latched", 4)
        dds.reader(topic, msgtype, heard.append, "reliable", raw=True)
        plain = DataReader(
            dds.participant, dds.topic("rt" + topic, types.cls(msgtype)), qos=reader_qos("latched")
        )
        wait_for(lambda: writer.get_publication_matched_status().current_count == 2, "readers")
        sent = [types.build(msgtype, {"data": text}).serialize() for text in ("one", "twenty")]
        for data in sent:
            Dds.write_raw(writer, data)
        wait_for(lambda: len(heard) == 2, "the listener's samples")
        taken: list[bytes] = []
        wait_for(lambda: taken.extend(Dds.take_raw(plain)) or len(taken) == 2, "take_raw")
        for got in (heard, taken):
            assert [bytes(g)[: len(s)] for g, s in zip(got, sent, strict=True)] == sent
            assert [types.cls(msgtype).deserialize(bytes(g)).data for g in got] == ["one", "twenty"]
    finally:
        dds.close()
