"""The wire format written and read as arrays (toaster.ros1.wire) is byte for byte genpy's:
FactLists of random fact batches and of a crowd's producers, /tf written by the bridge, /tf
read from random messages (a stream laid out alike reuses its offsets, one laid out otherwise
is read anew)."""

from __future__ import annotations

import io
from typing import Any

import numpy as np
import pytest

from toaster.producers.batch import FactBatch
from toaster.world.factmsg import fact_fields
from toaster.world.state import World


@pytest.fixture(scope="module")
def reg() -> Any:
    """The toaster_msgs classes (needs Debian's genpy; skips without it, fails under CI)."""
    from tests.ros1.conftest import require_ros
    from toaster.ros1 import RosUnavailableError, import_rospy, messages

    try:
        import_rospy()
    except RosUnavailableError as exc:
        require_ros()
        pytest.fail(f"ROS 1 is installed but the venv cannot import it: {exc}")
    return messages.load()


def genpy_bytes(msg: Any) -> bytes:
    buf = io.BytesIO()
    msg.serialize(buf)
    return buf.getvalue()


def genpy_fact_list(reg: Any, facts: list, t_ns: int) -> bytes:
    fact, fact_list = reg.msg("Fact"), reg.msg("FactList")
    return genpy_bytes(fact_list(factList=[fact(**fact_fields(f, t_ns)) for f in facts]))


PROPS = ["IsMoving", "Distance", "IsInArea", "IsLookingToward", "isPresent", "Own", "IsNextTo"]


def random_batch(rng: np.random.Generator) -> FactBatch:
    world = World()
    for i in range(12):
        kind = ("human", "object", "robot")[i % 3]
        world.add_entity(f"e{i}é" if i % 5 == 0 else f"e{i}", kind)
    for i in range(4):
        world.add_entity(
            f"e{3 * i}/j", "joint", owner_id=f"e{3 * i}é" if i % 5 == 0 else f"e{3 * i}", name="j"
        )
    batch = FactBatch(world)
    for _ in range(int(rng.integers(0, 8))):
        m = int(rng.integers(1, 9))
        rows = rng.integers(0, world.n, m)
        subj = rows if rng.random() < 0.8 else "AREA_ü"
        tgt: Any = rng.integers(0, world.n, m) if rng.random() < 0.5 else "t"
        if rng.random() < 0.3:
            tgt = (rng.integers(0, 3, m), np.array(["a", "bé", ""], dtype=object))
        if not isinstance(subj, np.ndarray) and not isinstance(tgt, np.ndarray):
            tgt = rng.integers(0, world.n, m)
        text: Any = (
            "true"
            if rng.random() < 0.6
            else (rng.integers(0, 2, m), np.array(["near", "far"], dtype=object))
        )
        num = rng.choice([None, 0.25, "array"])
        value_num = rng.normal(size=m) if num == "array" else num
        conf = rng.random(m) if rng.random() < 0.5 else 0.9
        owner: Any = rng.integers(-1, world.n, m) if rng.random() < 0.3 else ""
        batch.add(
            str(rng.choice(PROPS)),
            subj,
            tgt,
            value_text=text,
            value_num=value_num,
            conf=conf,
            obs=float(rng.random()),
            property_type="position",
            sub_property=str(rng.choice(["", "agent", "3D"])),
            tgt_owner=owner,
            subj_owner="" if isinstance(subj, np.ndarray) else "bob",
        )
    return batch


@pytest.mark.parametrize("seed", range(30))
def test_fact_lists_are_genpy_s_bytes(reg, seed):
    from toaster.ros1.wire import FactListWriter

    rng = np.random.default_rng(seed)
    batch = random_batch(rng)
    writer = FactListWriter()
    t_ns = int(rng.integers(0, 2**62))
    want = genpy_fact_list(reg, batch.facts(), t_ns)
    assert writer.write(batch, t_ns) == want
    assert writer.write(batch.facts(), t_ns) == want  # a list goes through fact_fields


def test_a_crowd_s_fact_lists_are_genpy_s_bytes(reg):
    from toaster.node import LiveNode
    from toaster.ros1.wire import FactListWriter

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
    writer = FactListWriter()
    assert sum(len(f) for f in facts.values()) > 100
    for name in facts:
        assert writer.write(facts.raw(name), t) == genpy_fact_list(reg, facts[name], t), name


def tf_message(rng: np.random.Generator, frames: list[tuple[str, str]]) -> Any:
    from geometry_msgs.msg import TransformStamped  # type: ignore[import-not-found]
    from tf2_msgs.msg import TFMessage  # type: ignore[import-not-found]

    out = []
    for parent, child in frames:
        tr = TransformStamped()
        tr.header.seq = int(rng.integers(0, 2**32))
        tr.header.frame_id, tr.child_frame_id = parent, child
        tr.header.stamp.secs, tr.header.stamp.nsecs = (
            int(rng.integers(0, 2**32)),
            int(rng.integers(0, 10**9)),
        )
        t, q = tr.transform.translation, tr.transform.rotation
        t.x, t.y, t.z = rng.normal(size=3).tolist()
        q.x, q.y, q.z, q.w = rng.normal(size=4).tolist()
        out.append(tr)
    return TFMessage(transforms=out)


def test_tf_is_read_as_genpy_reads_it(reg):
    from toaster.ros1.wire import TfReader
    from toaster.world.tftree import edges_of

    rng = np.random.default_rng(3)
    reader = TfReader()
    frames = [("map", f"h{i}_base") for i in range(20)] + [("h3_base", "/h3_head"), ("ödom", "x")]
    layouts = [frames, frames, [*frames[:-1], ("odom", "x")], frames[::-1], [], frames]
    for layout in layouts:
        msg = tf_message(rng, layout)
        got, want = reader.read(genpy_bytes(msg)), edges_of(msg)
        assert list(got.children) == want.children and list(got.parents) == want.parents
        assert got.stamps.tolist() == want.stamps.tolist()
        assert got.t.tolist() == want.t.tolist() and got.q.tolist() == want.q.tolist()
    with pytest.raises(ValueError, match="TFMessage"):
        reader.read(b"\x05\x00\x00\x00abc")


def test_the_bridge_s_tf_is_genpy_s_bytes(reg):
    import genpy  # type: ignore[import-not-found]
    from geometry_msgs.msg import TransformStamped  # type: ignore[import-not-found]
    from tf2_msgs.msg import TFMessage  # type: ignore[import-not-found]

    from toaster.ros1.wire import Pieces, tf_bytes

    rng = np.random.default_rng(4)
    children = ["a/base", "/b", "/a/héad"]
    child = rng.integers(0, 3, 7)
    pos, quat = rng.normal(size=(7, 3)), rng.normal(size=(7, 4))
    t_ns = 1_700_000_000_123_456_789
    out = []
    for c, p, q in zip(child.tolist(), pos.tolist(), quat.tolist(), strict=True):
        tr = TransformStamped()
        tr.header.frame_id, tr.header.stamp = "map", genpy.Time(t_ns // 10**9, t_ns % 10**9)
        tr.child_frame_id = children[c]
        t, r = tr.transform.translation, tr.transform.rotation
        t.x, t.y, t.z, r.x, r.y, r.z, r.w = *p, *q
        out.append(tr)
    want = genpy_bytes(TFMessage(transforms=out))
    assert tf_bytes("map", Pieces(children), child, pos, quat, t_ns) == want
