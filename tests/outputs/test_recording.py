"""Recordings: an MCAP bag written with rosbags, read back with the independent mcap reader
(standard messages with mcap_ros2; toaster_msgs with a typestore built only from the schemas
stored in the file), and replayed as input by ``toaster run``."""

from __future__ import annotations

import json
import math
from pathlib import Path
from typing import Any

import pytest

import toaster
from tests.outputs.conftest import T0, S, run_scenario
from toaster import Fact
from toaster.errors import InvalidInputError
from toaster.outputs.markers import TOPICS as ENTITY_TOPICS
from toaster.outputs.recording import (
    AREAS_TOPIC,
    CUBE,
    CYLINDER,
    FACTS_TOPIC,
    LINE_STRIP,
    MARKER_TOPICS,
    SPHERE_LIST,
    TEXT,
    EntityPose,
    record,
)
from toaster.world.rosmsg import field, rpy_to_quat

pytest.importorskip("rosbags")
mcap_reader = pytest.importorskip("mcap.reader")
mcap_ros2 = pytest.importorskip("mcap_ros2.decoder")

AREAS = [("kitchen", [(0.0, 0.0), (3.0, 0.0), (3.0, 2.0), (0.0, 2.0)])]
FIXED_TOPICS = {
    ("/tf", "tf2_msgs/msg/TFMessage"),
    *((topic, "visualization_msgs/msg/MarkerArray") for topic in MARKER_TOPICS),
    (FACTS_TOPIC, "rcl_interfaces/msg/Log"),
    ("/pdg/humanList", "toaster_msgs/msg/HumanListStamped"),
    ("/pdg/robotList", "toaster_msgs/msg/RobotListStamped"),
    ("/pdg/objectList", "toaster_msgs/msg/ObjectListStamped"),
    ("/area_manager/areaList", "toaster_msgs/msg/AreaList"),
}


def _frames() -> list[tuple[Any, ...]]:
    """alice walks along x for 5 s; bob leaves after 2 s; the areas come with the first frame."""
    out = []
    for k in range(6):
        entities = [
            ("pr2", "robot", 1.0, 1.0, 0.0, 0.5),
            ("alice", "human", 2 + k, 1, 0, 3.1),
            ("mug", "object", 1.5, 1.5, 0.75, 0.0),
        ]
        if k < 3:
            entities.append(("bob", "human", 0.5, 0.5, 0.0, 0.0))
        out.append((T0 + k * S, entities, AREAS if k == 0 else None))
    return out


def _decoder(factory: Any, encoding: str, schema: Any) -> Any:
    if not schema.name.startswith("toaster_msgs/"):
        return factory.decoder_for(encoding, schema)
    # the original's camelCase field names are not ROS 2 names, which mcap_ros2 refuses
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(schema.data.decode(), schema.name))
    return lambda data: store.deserialize_cdr(data, schema.name)


def _read(path: Path) -> list[tuple[str, str, int, Any]]:
    factory = mcap_ros2.DecoderFactory()
    decoders: dict[int, Any] = {}
    out = []
    with path.open("rb") as handle:
        for schema, channel, message in mcap_reader.make_reader(handle).iter_messages(
            log_time_order=True
        ):
            if schema.id not in decoders:
                decoders[schema.id] = _decoder(factory, channel.message_encoding, schema)
            out.append(
                (channel.topic, schema.name, message.log_time, decoders[schema.id](message.data))
            )
    return out


def _on(messages: list[tuple[str, str, int, Any]], topic: str) -> list[tuple[int, Any]]:
    return [(stamp, msg) for t, _, stamp, msg in messages if t == topic]


def _entities(messages: list[tuple[str, str, int, Any]]) -> list[list[Any]]:
    """The entity markers of each frame: the objects', humans' and robots' arrays joined, each
    starting with its DELETEALL."""
    frames: dict[int, list[Any]] = {}
    for topic in ENTITY_TOPICS.values():
        for stamp, array in _on(messages, topic):
            assert array.markers[0].action == 3  # DELETEALL
            frames.setdefault(stamp, []).extend(array.markers[1:])
    return [frames[stamp] for stamp in sorted(frames)]


@pytest.mark.slow
def test_recording_replays_frames_and_facts(run_db: toaster.Database, tmp_path: Path) -> None:
    """Entities, areas and the database's events come back, typed as ROS tools expect."""
    result = record(tmp_path / "run", _frames(), db=run_db, until=T0 + 20 * S)
    assert result.mcap.suffix == ".mcap"
    assert (result.bag / "metadata.yaml").exists()
    messages = _read(result.mcap)
    # /tf, pdg's lists, the area list and a belief channel per agent joined the three original
    # topics; no factList topic: this database's facts come from "user" and "monitor", none of
    # the four producers
    beliefs = {
        (f"/toaster/beliefs/{a}", "toaster_recording/msg/Beliefs") for a in ("pr2", "alice", "bob")
    }
    assert {(t, s) for t, s, _, _ in messages} == FIXED_TOPICS | beliefs
    assert result.beliefs == sum(t.startswith("/toaster/beliefs/") for t, *_ in messages)

    def mug_on(agent: str, t_ns: int) -> set[str]:
        held = [m for stamp, m in _on(messages, f"/toaster/beliefs/{agent}") if stamp <= t_ns]
        return {
            f.target_id for f in held[-1].facts if (f.subject_id, f.property) == ("mug", "IsOn")
        }

    # the robot saw the mug move to the shelf at 10 s; alice keeps her false belief (table);
    # bob only learns of the shelf at 16 s
    assert [mug_on(a, T0 + 12 * S) for a in ("pr2", "alice", "bob")] == [
        {"shelf"},
        {"table"},
        set(),
    ]
    assert mug_on("bob", T0 + 17 * S) == {"shelf"}
    frames = _entities(messages)
    assert len(frames) == 6
    names = [{m.text for m in f if m.type == TEXT} for f in frames]
    assert names[0] == {"pr2", "alice", "mug", "bob"}
    assert names[5] == {"pr2", "alice", "mug"}  # bob left: DELETEALL first, no bob marker
    # bodies are drawn by toaster.outputs.markers: namespace = entity id, id 0 = the body
    alice = next(m for m in frames[5] if m.ns == "alice" and m.id == 0)
    assert alice.type == CYLINDER and alice.pose.position.x == pytest.approx(7.0)
    outline = [m for _, a in _on(messages, AREAS_TOPIC) for m in a.markers if m.type == LINE_STRIP]
    assert [(p.x, p.y) for p in outline[0].points] == [*AREAS[0][1], AREAS[0][1][0]]
    lines = [(stamp - T0, m.msg) for stamp, m in _on(messages, FACTS_TOPIC)]
    assert (10 * S, "pr2: mug IsOn table ended") in lines
    assert (2 * S, "alice: mug IsOn table appeared = true (confidence 0.8)") in lines
    assert all(0 <= t <= 20 * S for t, _ in lines)


def test_tf_has_pdg_frame_names_and_full_poses(tmp_path: Path) -> None:
    """/tf: objects "<id>", agents "<id>/base", joints "<agent>/<joint>", parent map, no
    leading slash; roll, pitch and yaw all reach the quaternion."""
    entities = [
        EntityPose("alice", "human", 1.0, 2.0, 0.0, 0.5),
        EntityPose(
            "alice/head", "joint", 1.0, 2.0, 1.6, 0.7, 0.1, -0.2, owner="alice", name="head"
        ),
        EntityPose("mug", "object", 3.0, 1.0, 0.8, 1.0, 0.3, 0.2),
        ("pr2", "robot", 0.0, 0.0, 0.0, -1.0),
    ]
    result = record(tmp_path / "tf", [(T0, entities, None)])
    ((stamp, tf),) = _on(_read(result.mcap), "/tf")
    poses = {tr.child_frame_id: tr for tr in tf.transforms}
    assert set(poses) == {"alice/base", "alice/head", "mug", "pr2/base"}
    assert {tr.header.frame_id for tr in tf.transforms} == {"map"}
    assert stamp == T0 and {tr.header.stamp.sec for tr in tf.transforms} == {T0 // S}
    for frame, (x, y, z, roll, pitch, yaw) in {
        "mug": (3.0, 1.0, 0.8, 0.3, 0.2, 1.0),
        "alice/head": (1.0, 2.0, 1.6, 0.1, -0.2, 0.7),
        "pr2/base": (0, 0, 0, 0, 0, -1.0),
    }.items():
        t = poses[frame].transform
        assert (t.translation.x, t.translation.y, t.translation.z) == pytest.approx((x, y, z))
        q = (t.rotation.x, t.rotation.y, t.rotation.z, t.rotation.w)
        assert q == pytest.approx(rpy_to_quat(roll, pitch, yaw))


def test_shapes_use_entity_sizes(tmp_path: Path) -> None:
    """Boxes of the entities' sizes (defaults per kind otherwise), agents with a heading arrow,
    joints as small spheres."""
    entities = [
        EntityPose("table", "object", 2.0, 0.0, 0.0, 0.0, size=(1.2, 0.8, 0.75)),
        EntityPose("ball", "object", 2.0, 0.0, 0.8, 0.0),
        {"id": "pr2", "kind": "robot", "x": 0, "y": 0, "z": 0, "yaw": 0, "size": [0.5, 0.5, 1.3]},
        EntityPose("alice", "human", 1.0, 1.0, 0.0, 0.0),
        EntityPose("alice/head", "joint", 1.0, 1.0, 1.6, 0.0, owner="alice"),
    ]
    result = record(tmp_path / "shapes", [(T0, entities, None)])
    (array,) = _entities(_read(result.mcap))
    body = {m.ns: m for m in array if m.id == 0 and m.ns}
    assert {ns: m.type for ns, m in body.items()} == {
        "table": CUBE,
        "ball": CUBE,
        "pr2": CUBE,
        "alice": CYLINDER,
    }
    scale = {ns: (m.scale.x, m.scale.y, m.scale.z) for ns, m in body.items()}
    assert scale["table"] == pytest.approx((1.2, 0.8, 0.75))
    assert scale["ball"] == pytest.approx((0.2, 0.2, 0.2))  # no size: the object default
    assert scale["pr2"] == pytest.approx((0.5, 0.5, 1.3))
    assert scale["alice"] == pytest.approx((0.5, 0.5, 1.7))  # the human default
    assert body["pr2"].pose.position.z == pytest.approx(0.65)  # agents stand on the floor
    arrows = {m.ns for m in array if m.type == 0}
    assert arrows == {"pr2", "alice"}
    (joints,) = [m for m in array if m.type == SPHERE_LIST]
    assert joints.ns == "alice" and [(p.x, p.y, p.z) for p in joints.points] == [(1, 1, 1.6)]
    assert joints.scale.x < 0.1


def test_circles_and_owner_relative_areas(tmp_path: Path) -> None:
    """Circles as discs, polygons as outlines, areas owned by an entity moved and turned with
    it at every frame, each with its name; the area list carries their specs."""
    areas = [
        ("table_zone", {"shape": "circle", "center": [4.0, 1.0], "radius": 1.5}),
        (
            "front",
            {"shape": "polygon", "owner": "pr2", "points": [[0, -1], [2, -1], [2, 1], [0, 1]]},
        ),
        *AREAS,
    ]
    frames = [
        (
            T0 + k * S,
            [("pr2", "robot", float(k), 0.0, 0.0, k * math.pi / 2)],
            areas if k == 0 else None,
        )
        for k in range(2)
    ]
    messages = _read(record(tmp_path / "areas", frames).mcap)
    drawn = [m for _, m in _on(messages, AREAS_TOPIC)]
    assert len(drawn) == 2  # redrawn as the owner moved
    first = {(m.ns, m.type): m for m in drawn[0].markers}
    disc = first["table_zone", CYLINDER]
    assert (disc.pose.position.x, disc.pose.position.y, disc.scale.x) == (4.0, 1.0, 3.0)
    assert {m.text for m in drawn[0].markers if m.type == TEXT} == {
        "table_zone",
        "front",
        "kitchen",
    }
    outlines = [
        next(m for m in d.markers if m.ns == "front" and m.type == LINE_STRIP) for d in drawn
    ]
    corners = [[(round(p.x, 6), round(p.y, 6)) for p in m.points] for m in outlines]
    assert corners[0][:4] == [(0, -1), (2, -1), (2, 1), (0, 1)]
    assert corners[1][:4] == [(2, 0), (2, 2), (0, 2), (0, 0)]  # moved 1 m, turned 90°
    (_, area_list), *_ = _on(messages, "/area_manager/areaList")
    listed = {a.name: a for a in field(area_list, "areaList")}
    assert field(listed["table_zone"], "isCircle") and listed["table_zone"].ray == 1.5
    assert field(listed["front"], "myOwner") == "pr2" and len(listed["front"].poly.points) == 4


def _facts_db(url: str) -> toaster.Database:
    """pr2 (self) hears pdg and area_manager; a user fact is no producer's."""
    db = toaster.connect(url)
    store = db.store()
    store.add_entity("pr2", "robot", is_self=True, t_ns=T0)
    store.add_entity("alice", "human", t_ns=T0)
    present = [Fact("alice", "isPresent", confidence=0.9), Fact("pr2", "isPresent")]
    room = Fact("alice", "IsInRoom", "kitchen", property_type="position", sub_property="room")
    store.put_area("kitchen", {"shape": "polygon", "points": AREAS[0][1]})
    store.sync_snapshot("pdg", "pr2", T0, present)
    store.sync_snapshot("area_manager", "pr2", T0 + S, [room])
    store.sync_snapshot("pdg", "pr2", T0 + 2 * S, present[1:])
    store.sync_snapshot("area_manager", "pr2", T0 + 3 * S, [])
    store.assert_fact("pr2", Fact("alice", "Likes", "pr2"), t_ns=T0)
    return db


@pytest.mark.slow
def test_fact_lists_hold_the_current_facts(db_url: str, tmp_path: Path) -> None:
    """/<producer>/factList: the self agent's facts of that producer held at each frame time
    where they changed (and at the first frame), as toaster_msgs/FactList."""
    db = _facts_db(db_url)
    try:
        frames = [
            (T0 + k * S // 2, [("pr2", "robot", 0, 0, 0, 0)], AREAS if k == 0 else None)
            for k in range(9)
        ]
        result = record(tmp_path / "facts", frames, db=db)
    finally:
        db.close()
    messages = _read(result.mcap)
    schemas = {s for t, s, _, _ in messages if t.endswith("/factList")}
    assert schemas == {"toaster_msgs/msg/FactList"}

    def held(topic: str) -> list[tuple[int, list[tuple[str, str, str, int]]]]:
        return [
            (
                stamp - T0,
                [
                    (
                        field(f, "subjectId"),
                        f.property,
                        field(f, "targetId"),
                        field(f, "timeStart") - T0,
                    )
                    for f in field(msg, "factList")
                ],
            )
            for stamp, msg in _on(messages, topic)
        ]

    assert held("/pdg/factList") == [
        (0, [("alice", "isPresent", "", 0), ("pr2", "isPresent", "", 0)]),
        (2 * S, [("pr2", "isPresent", "", 0)]),
    ]
    assert held("/area_manager/factList") == [
        (0, []),
        (S, [("alice", "IsInRoom", "kitchen", S)]),
        (3 * S, []),
    ]
    fact = field(_on(messages, "/pdg/factList")[0][1], "factList")[0]
    assert (field(fact, "stringValue"), fact.confidence, fact.time, field(fact, "timeEnd")) == (
        "true",
        0.9,
        T0,
        0,
    )
    assert result.fact_lists == 5
    assert "/user/factList" not in {t for t, *_ in messages}
    # area_manager's facts say who is inside: the area list and the outline's colour follow
    inside = [
        (stamp - T0, list(field(field(m, "areaList")[0], "insideEntities_")))
        for stamp, m in _on(messages, "/area_manager/areaList")
    ]
    assert inside == [(0, []), (S, ["alice"]), (3 * S, [])]
    colours = [
        next(m.color.r for m in a.markers if m.type == LINE_STRIP)
        for _, a in _on(messages, AREAS_TOPIC)
    ]
    assert colours[1] > colours[0] == colours[2]


@pytest.mark.slow
def test_fact_lists_carry_the_number_each_fact_had_then(db_url: str, tmp_path: Path) -> None:
    """A number that moves within one interval (a refresh: no new interval, no event) is
    recorded as it was at each frame, in the self agent's fact list and in every holder's
    beliefs: what toaster.queries.beliefs_at answers for that time."""
    db = toaster.connect(db_url)
    try:
        store = db.store()
        store.add_entity("pr2", "robot", is_self=True, t_ns=T0)
        store.add_entity("alice", "human", t_ns=T0)
        numbers = ((1.0, 0.5), (1.5, 0.6), (1.5, 0.6), (3.0, 0.8), (2.0, 0.9))  # one interval
        for k, (metres, confidence) in enumerate(numbers):
            near = Fact("alice", "Distance", "pr2", value_num=metres, confidence=confidence)
            store.sync_snapshot("agent_monitor", "pr2", T0 + k * S, [near])
        frames = [(T0 + k * S // 2, [("pr2", "robot", 0, 0, 0, 0)], None) for k in range(10)]
        result = record(tmp_path / "numbers", frames, db=db)
        messages = _read(result.mcap)
        lists = [("pr2", _on(messages, "/agent_monitor/factList"), "factList")] + [
            (m.holder, _on(messages, topic), "facts")
            for topic in {t for t, *_ in messages if t.startswith("/toaster/beliefs/")}
            for _, m in _on(messages, topic)[:1]
        ]
        seen = []
        for holder, stamped, name in lists:
            recorded = [
                (t - T0, [(f.property, field(f, "doubleValue"), f.confidence) for f in facts])
                for t, facts in ((t, field(m, name)) for t, m in stamped)
                if any(f.property == "Distance" for f in facts)
            ]
            if not recorded:  # a holder that does not perceive the distance (alice)
                continue
            expected = []
            for t, _ in recorded:
                rows = toaster.queries.beliefs_at(db, holder, T0 + t, property="Distance")
                expected.append((t, [(r.property, r.value_num, r.confidence) for r in rows]))
            assert recorded == expected, holder
            assert [n for _, facts in recorded for *_, n in facts] == pytest.approx(
                [0.5, 0.6, 0.8, 0.9]
            ), holder  # a list at each change of the numbers, none when they stayed
            seen.append((holder, name))
        assert sorted(seen) == [("pr2", "factList"), ("pr2", "facts")]  # list and beliefs
    finally:
        db.close()


def test_ros2_field_names_decode_with_rosidl_rules(tmp_path: Path) -> None:
    """By default (toaster_names="ros2") recordings hold valid ROS 2 interfaces (snake_case
    fields) that mcap_ros2 (rosidl's parser, as Foxglove's) decodes."""
    entities = [
        ("alice", "human", 1.0, 2.0, 0.0, 0.5),
        ("alice/head", "joint", 1.0, 2.0, 1.6, 0.5, 0, 0, None, "alice"),
    ]
    result = record(tmp_path / "ros2", [(T0, entities, AREAS)])
    with result.mcap.open("rb") as handle:
        reader = mcap_reader.make_reader(handle, decoder_factories=[mcap_ros2.DecoderFactory()])
        decoded = {c.topic: m for _, c, _, m in reader.iter_decoded_messages()}
    (human,) = decoded["/pdg/humanList"].human_list
    assert human.me_agent.me_entity.id == "alice"
    assert list(human.me_agent.skeleton_names) == ["head"]
    assert decoded["/area_manager/areaList"].area_list[0].inside_entities == []


@pytest.mark.parametrize(("distro", "version"), [("humble", 5), ("iron", 8), ("jazzy", 9)])
def test_metadata_version_matches_the_distro(tmp_path: Path, distro: str, version: int) -> None:
    """metadata.yaml is the version that distro's rosbag2 writes, with only the fields it knows
    (a Humble bag of version 9 fails `ros2 bag info`: its QoS profiles are a list there)."""
    import yaml  # type: ignore[import-untyped]

    from toaster.world.bags import read_bag

    result = record(tmp_path / distro, _frames(), distro=distro)
    info = yaml.safe_load((result.bag / "metadata.yaml").read_text())["rosbag2_bagfile_information"]
    assert info["version"] == version
    topic = info["topics_with_message_count"][0]["topic_metadata"]
    assert ("ros_distro" in info, "custom_data" in info) == (version >= 8, version >= 6)
    if version >= 8:
        assert info["ros_distro"] == distro
    assert ("type_description_hash" in topic) == (version >= 7)
    assert isinstance(topic["offered_qos_profiles"], str) == (version < 9)
    assert read_bag(result.bag).start_ns == T0  # rosbags reads every one of them back


@pytest.mark.slow
def test_shipped_scenario_records(tmp_path: Path) -> None:
    """A shipped scenario's world and facts record frame by frame."""
    db = toaster.connect(f"sqlite:///{tmp_path / 'flat.db'}")
    try:
        frames = run_scenario(db, "scenario_flat.yaml", 10)
        result = record(tmp_path / "flat", frames, db=db)
    finally:
        db.close()
    messages = _read(result.mcap)
    assert result.frames == len(frames) == 101
    assert sum(t == FACTS_TOPIC for t, *_ in messages) == result.facts > 10
    assert {"/pdg/factList", "/area_manager/factList", "/agent_monitor/factList"} <= {
        t for t, *_ in messages
    }


@pytest.mark.slow
def test_cli_record(run_db: toaster.Database, db_url: str, tmp_path: Path) -> None:
    """``toaster record FRAMES OUT`` reads JSON-lines frames: the old six-field poses and
    polygons, and full poses (named fields) with area specs."""
    from click.testing import CliRunner

    from toaster.cli.export import record as record_cmd

    frames = tmp_path / "frames.jsonl"
    lines = [json.dumps({"t_ns": t, "entities": e, "areas": a}) for t, e, a in _frames()]
    lines.append(
        json.dumps(
            {
                "t_ns": T0 + 6 * S,
                "entities": [
                    {
                        "id": "pr2",
                        "kind": "robot",
                        "x": 1,
                        "y": 1,
                        "z": 0,
                        "yaw": 0.5,
                        "size": [1, 1, 1],
                    },
                    {
                        "id": "pr2/head",
                        "kind": "joint",
                        "x": 1,
                        "y": 1,
                        "z": 1.2,
                        "yaw": 0.5,
                        "owner": "pr2",
                    },
                ],
                "areas": [["disc", {"shape": "circle", "center": [0, 0], "radius": 1}]],
            }
        )
    )
    frames.write_text("\n".join(lines) + "\n")
    out = tmp_path / "bag"
    done = CliRunner().invoke(record_cmd, [str(frames), str(out), "--db", db_url])
    assert done.exit_code == 0, done.output
    assert "wrote 7 frames" in done.output
    (_, tf) = _on(_read(next(out.glob("*.mcap"))), "/tf")[-1]
    assert {tr.child_frame_id for tr in tf.transforms} == {"pr2/base", "pr2/head"}
    # a .bag name is a ROS 1 bag; --agent picks the belief channels (and the events)
    ros1 = tmp_path / "run.bag"
    done = CliRunner().invoke(
        record_cmd, [str(frames), str(ros1), "--db", db_url, "--agent", "alice"]
    )
    assert done.exit_code == 0, done.output
    assert f"to {ros1}" in done.output
    from rosbags.rosbag1 import Reader

    with Reader(ros1) as reader:
        topics = {c.topic: c.msgtype for c in reader.connections}
        names = {
            m.name
            for c, _, raw in reader.messages(
                [c for c in reader.connections if c.topic == FACTS_TOPIC]
            )
            for m in [reader_log(raw, c)]
        }
    assert topics["/toaster/beliefs/alice"] == "toaster_recording/msg/Beliefs"
    assert topics[FACTS_TOPIC] == "rosgraph_msgs/msg/Log"
    assert not any(
        t.startswith("/toaster/beliefs/") and t != "/toaster/beliefs/alice" for t in topics
    )
    assert names == {"toaster.alice"}
    bad = CliRunner().invoke(
        record_cmd, [str(frames), str(tmp_path / "x.bag"), "--distro", "humble", "--db", db_url]
    )
    assert bad.exit_code != 0 and "a .bag file is ROS 1" in bad.output
    assert not (tmp_path / "x.bag").exists()
    typo = CliRunner().invoke(
        record_cmd, [str(frames), str(tmp_path / "y"), "--agent", "alic", "--db", db_url]
    )
    assert typo.exit_code != 0 and "unknown agent 'alic'" in typo.output
    assert not (tmp_path / "y").exists()


def reader_log(raw: bytes, conn: Any) -> Any:
    """A ROS 1 Log message decoded with the definition the bag carries."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    store = get_typestore(Stores.EMPTY)
    store.register(get_types_from_msg(conn.msgdef.data, conn.msgtype))
    return store.deserialize_ros1(raw, conn.msgtype)


def test_bad_frames(tmp_path: Path) -> None:
    """Frames out of order, bad poses, sizes, joints, areas, distros and an existing directory
    give one-line errors, before anything is written."""
    pose = ("pr2", "robot", 0, 0, 0, 0)
    bad: list[tuple[list[Any], dict[str, Any], str]] = [
        ([(2, [], None), (1, [], None)], {}, "frames out of time order"),
        ([(1, [("pr2", "robot", "here")], None)], {}, r"invalid entity pose .*\(id, kind, x, y, z"),
        ([(1, [(*pose, 0, 0, (1, -1, 1))], None)], {}, "invalid entity pose"),
        (
            [(1, [("head", "joint", 0, 0, 1, 0, 0, 0, None, "bob")], None)],
            {},
            "joint owner 'bob' is not a human or robot",
        ),
        ([(1, [pose], [("a", [(0, 0), (1, 1)])])], {}, "a polygon needs at least 3 points"),
        ([(1, [pose], [("a", {"shape": "circle", "center": [0, 0]})])], {}, "radius"),
        ([(1, [pose], None)], {"distro": "foxy"}, "unknown ROS distro 'foxy': use one of humble"),
        ([(1, [pose], None)], {"toaster_names": "ros3"}, "use ros1 or ros2"),
        ([(1, [pose], None)], {"distro": "noetic"}, r"ROS 1 bag .*name the file <name>\.bag"),
    ]
    for k, (frames, options, message) in enumerate(bad):
        with pytest.raises(InvalidInputError, match=message):
            record(tmp_path / f"bad{k}", frames, **options)
        assert not (tmp_path / f"bad{k}").exists()
    for options, message in (
        ({"distro": "jazzy"}, r"a \.bag file is ROS 1"),
        ({"toaster_names": "ros2"}, "original's field names"),
    ):
        with pytest.raises(InvalidInputError, match=message):
            record(tmp_path / "bad.bag", [(1, [pose], None)], **options)
        assert not (tmp_path / "bad.bag").exists()
    (tmp_path / "c").mkdir()
    with pytest.raises(InvalidInputError, match="it exists"):
        record(tmp_path / "c", [(1, [], None)])


@pytest.mark.slow
def test_run_records_what_it_saw(tmp_path: Path) -> None:
    """`toaster run --record DIR` writes the run's frames and the events it stored."""
    from click.testing import CliRunner

    from toaster.cli import cli

    url = f"sqlite:///{tmp_path / 'run.db'}"
    scenario = Path(toaster.__file__).parent / "examples" / "scenario_flat.yaml"
    result = CliRunner().invoke(
        cli, ["--db", url, "run", str(scenario), "--until", "2s", "--record", str(tmp_path / "bag")]
    )
    assert result.exit_code == 0, result.output
    messages = _read(next((tmp_path / "bag").glob("*.mcap")))
    topics = {topic for topic, *_ in messages}
    assert {*MARKER_TOPICS, FACTS_TOPIC} <= topics
    with toaster.connect(url) as db:
        stored = len(toaster.queries.events(db))
    assert sum(topic == FACTS_TOPIC for topic, *_ in messages) == stored
    again = CliRunner().invoke(
        cli, ["--db", url, "run", str(scenario), "--record", str(tmp_path / "bag")]
    )
    assert again.exit_code == 1
    assert "exists" in again.output


def _self_facts(url: str) -> set[tuple[Any, ...]]:
    from toaster import queries

    with toaster.connect(url) as db:
        (me,) = queries.agents(db, only_self=True)
        rows = queries.history(db, me.id)
    return {
        (
            r.source,
            r.subject_id,
            r.property,
            r.target_id,
            r.value_text,
            r.valid_from_ns,
            r.valid_to_ns,
        )
        for r in rows
    }


@pytest.mark.slow
@pytest.mark.parametrize("name", ["bag", "run.bag"])
def test_recording_replays_as_input(tmp_path: Path, name: str) -> None:
    """`toaster run BAG` (no options) replays a `toaster run --record` recording, rosbag2
    folder or ROS 1 .bag, through its recorded world: the same poses at every tick, so the
    same facts."""
    from click.testing import CliRunner

    from toaster.cli import cli
    from toaster.producers import Runner, load_session

    scenario = Path(toaster.__file__).parent / "examples" / "scenario_flat.yaml"
    bag, first, second = tmp_path / name, tmp_path / "a.db", tmp_path / "b.db"
    run = CliRunner().invoke(
        cli,
        [
            "--db",
            f"sqlite:///{first}",
            "run",
            str(scenario),
            "--until",
            "20s",
            "--record",
            str(bag),
        ],
    )
    assert run.exit_code == 0, run.output
    original, replay = load_session(scenario), load_session(bag)
    with toaster.connect(f"sqlite:///{second}") as db:  # the bag has poses, not area specs
        store = db.store()
        for area_id, spec in original.areas.items():
            store.put_area(area_id, spec, spec.get("owner", ""))
    again = CliRunner().invoke(cli, ["--db", f"sqlite:///{second}", "run", str(bag)])
    assert again.exit_code == 0, again.output
    assert "201 ticks" in again.output  # at the scenario's 10 Hz, from its first tick

    ticks = [Runner(s.world, s.sources, []) for s in (original, replay)]
    checked = set()
    for t in range(0, 20 * S + 1, S // 10):
        for runner in ticks:
            runner.tick(t)
        a, b = original.world, replay.world
        for entity_id, row in b.index.items():
            if b.active[row] and b.t_ns[row] == t:  # seen at this tick in the bag
                assert b.pos[row] == pytest.approx(a.pos[a.index[entity_id]]), (t, entity_id)
                assert b.rpy[row] == pytest.approx(a.rpy[a.index[entity_id]]), (t, entity_id)
                checked.add(entity_id)
    assert checked == {
        "pr2",
        "pr2/head",
        "alice",
        "alice/head",
        "alice/rightHand",
        "mug",
        "book",
        "bob",
    }
    # the recorded world holds pdg's put_in_hand too: every fact comes back, IsInHand included
    # (tests/outputs/test_roundtrip.py compares whole databases)
    expected = _self_facts(f"sqlite:///{first}")
    assert {f[2] for f in expected} >= {"isPresent", "IsInRoom", "IsInArea", "IsMoving", "IsAt"}
    assert "IsInHand" in {f[2] for f in expected}
    assert _self_facts(f"sqlite:///{second}") == expected


def test_motion_markers_show_agent_monitors_facts(tmp_path: Path) -> None:
    """marker_motion, as live: at each frame, agent_monitor's last fact list as arrows (IsMoving
    along the heading, IsMovingToward to the target) and lines (IsLookingAt from the head)."""
    from toaster.outputs.recording import MOTION_TOPIC, Recorder

    entities = [
        EntityPose("alice", "human", 1.0, 1.0, 0.0, 0.0),
        EntityPose("alice/head", "joint", 1.0, 1.0, 1.6, 0.0, owner="alice", name="head"),
        EntityPose("mug", "object", 3.0, 1.0, 0.8, 0.0),
    ]
    facts = [
        Fact("alice", "IsMoving", "", value_num=0.5),
        Fact("alice", "IsMovingToward", "mug"),
        Fact("alice", "IsLookingAt", "mug"),
    ]
    with Recorder(tmp_path / "motion") as rec:
        rec.write_frame(T0, entities)
        rec.write_fact_list(T0 + S, "agent_monitor", facts)
        rec.write_frame(T0 + S, entities)
    drawn = [array.markers for _, array in _on(_read(rec.mcap_path), MOTION_TOPIC)]
    assert [[m.action for m in markers] for markers in drawn] == [[3], [3, 0, 0, 0]]
    shapes = {m.ns: m for m in drawn[1][1:]}
    assert shapes["IsMoving"].type == 0 and shapes["IsMoving"].scale.x == pytest.approx(0.5)
    toward = [(p.x, p.y, p.z) for p in shapes["IsMovingToward"].points]
    assert toward == [(1.0, 1.0, 0.0), (3.0, 1.0, 0.8)]
    assert (shapes["IsLookingAt"].points[0].z, shapes["IsLookingAt"].header.frame_id) == (
        1.6,
        "map",
    )
