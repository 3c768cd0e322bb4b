"""The ROS 1 wire format of the messages a crowd makes large, read and written as arrays: the
/tf messages the bridge receives (:func:`tf_edges`) and the FactLists and /tf it publishes
(:func:`fact_list_bytes`, :func:`tf_bytes`), byte for byte what genpy reads and writes.

genpy builds one Python object per field (a TransformStamped is six objects, a Fact fifteen
fields packed one by one): 500 people's /tf took ~10 ms to read and a FactList of 18,000 facts
0.5 s to write. Here strings are length-prefixed once (ids per world version, frame names per
message layout) and a message is laid out with one gather over its bytes. The bytes go out
through ``rospy.AnyMsg`` (:func:`as_message`), which rospy publishes on any topic as they are.
"""

from __future__ import annotations

import struct
from collections.abc import Mapping, Sequence
from typing import Any, NamedTuple

import numpy as np

from toaster.model import Fact
from toaster.producers.batch import FactBatch
from toaster.world.factmsg import ORIGINAL_VALUES, ValueFields, fact_fields
from toaster.world.tftree import Edges

_U32 = struct.Struct("<I")
#: valueType, factObservability, doubleValue: between a Fact's targetOwnerId and stringValue
_MIDDLE = np.dtype([("vt", "u1"), ("obs", "<f8"), ("num", "<f8")])
#: confidence, time, timeStart, timeEnd: a Fact's last fields
_TAIL = np.dtype([("conf", "<f8"), ("t", "<u8"), ("t0", "<u8"), ("t1", "<u8")])
#: a TransformStamped's header seq and stamp; its translation and rotation
_HEAD = np.dtype([("seq", "<u4"), ("secs", "<u4"), ("nsecs", "<u4")])
_POSE = np.dtype([("t", "<f8", 3), ("q", "<f8", 4)])


def _piece(text: str) -> bytes:
    data = text.encode("utf-8")
    return _U32.pack(len(data)) + data


class Pieces:
    """Length-prefixed strings laid end to end: each string's offset and length."""

    def __init__(self, texts: Sequence[str] = ()) -> None:
        self._parts: list[bytes] = []
        self._at: dict[str, int] = {}
        self.offsets: list[int] = []
        self.lengths: list[int] = []
        self.size = 0
        for text in texts:
            self.add(text)

    def encode(self, text: str) -> bytes:
        """One string's bytes on the wire (ROS 1: a uint32 length, then UTF-8)."""
        return _piece(text)

    def add(self, text: str) -> int:
        """The index of ``text`` (added on first use)."""
        got = self._at.get(text)
        if got is None:
            piece = self.encode(text)
            got = self._at[text] = len(self._parts)
            self._parts.append(piece)
            self.offsets.append(self.size)
            self.lengths.append(len(piece))
            self.size += len(piece)
        return got

    def blob(self) -> bytes:
        return b"".join(self._parts)


def _assemble(
    count: int, sources: list[bytes], segments: list[tuple[np.ndarray, np.ndarray]]
) -> bytes:
    """``count`` (uint32) and then, per item, its segments in order: ``segments`` holds per
    segment (source offsets, lengths), one entry per item, offsets into the concatenated
    ``sources``."""
    n = len(segments[0][0]) if segments else 0
    if n == 0:
        return _U32.pack(count)
    src = np.column_stack([s for s, _ in segments]).ravel()
    lens = np.column_stack([ln for _, ln in segments]).ravel()
    total = int(lens.sum())
    dst = np.cumsum(lens) - lens
    wide = np.int64 if total + len(src) >= 2**31 else np.int32  # a byte index per output byte
    index = np.repeat((src - dst).astype(wide), lens)
    index += np.arange(total, dtype=wide)
    source = np.frombuffer(b"".join(sources), np.uint8)
    return _U32.pack(count) + source[index].tobytes()


class Columns(NamedTuple):
    """A batch's toaster_msgs/Fact fields as arrays: the strings as pieces of ``ids`` (row i's
    id is piece i) then ``consts`` (piece ``len(ids.offsets) + j``), ``piece`` the 8 string
    fields' piece numbers (property .. targetOwnerId, then stringValue), the rest per fact."""

    ids: Pieces
    consts: Pieces
    piece: list[np.ndarray]
    vt: np.ndarray
    obs: np.ndarray
    num: np.ndarray
    conf: np.ndarray


class FactListWriter:
    """toaster_msgs/FactList bytes of a producer's facts, as genpy serialises
    ``FactList(factList=[Fact(**fact_fields(f, t_ns)) for f in facts])``."""

    #: the string encoding (a subclass writes another wire format: toaster.ros2.cdr)
    pieces: type[Pieces] = Pieces

    def __init__(self) -> None:
        self._ids: tuple[Any, int, Pieces] | None = None

    def _id_pieces(self, world: Any) -> Pieces:
        """Every row's id, piece i for row i (cached until the world has more rows)."""
        if self._ids is None or self._ids[0] is not world or self._ids[1] != world.n:
            self._ids = (world, world.n, self.pieces(world.ids[: world.n]))
        return self._ids[2]

    def write(self, facts: FactBatch | Sequence[Fact], t_ns: int) -> bytes:
        """The message's bytes (a batch as arrays; a list of facts through fact_fields)."""
        if not isinstance(facts, FactBatch):
            return self._write_list(list(facts), t_ns)
        if not facts.n:
            return self._write_list([], t_ns)
        return self._layout(self.columns(facts), facts.n, t_ns)

    def columns(self, batch: FactBatch) -> Columns:
        """The fields of a non-empty batch's facts as arrays."""
        world = batch.world
        ids = self._id_pieces(world)
        row_piece = np.arange(world.n, dtype=np.int64)
        consts = self.pieces()
        base = len(ids.offsets)  # const pieces follow the id pieces
        empty = base + consts.add("")
        owner = world.owner[: world.n]

        def const(text: str) -> int:
            return base + consts.add(text)

        def rows(value: Any, m: int) -> np.ndarray:
            if isinstance(value, np.ndarray):
                return row_piece[value]
            return np.full(m, const(value), np.int64)

        def owners(rows_of: np.ndarray) -> np.ndarray:
            return np.where(rows_of >= 0, row_piece[np.maximum(rows_of, 0)], empty)

        def labelled(value: Any, m: int) -> np.ndarray:
            if isinstance(value, tuple):
                codes, labels = value
                table = np.array([const(str(x)) for x in labels.tolist()], np.int64)
                return table[codes]
            return np.full(m, const(value), np.int64)

        cols: list[list[np.ndarray]] = [[] for _ in range(8)]
        vt, obs, num, conf = [], [], [], []
        for g in batch.groups:
            m = g.size
            kind = ORIGINAL_VALUES.get(g.prop) or ValueFields(g.value_num is not None, True, True)
            cols[0].append(np.full(m, const(g.prop), np.int64))
            cols[1].append(np.full(m, const(g.property_type), np.int64))
            cols[2].append(np.full(m, const(g.sub_property), np.int64))
            cols[3].append(rows(g.subj, m))
            cols[4].append(
                labelled(g.tgt, m) if not isinstance(g.tgt, np.ndarray) else rows(g.tgt, m)
            )
            if isinstance(g.subj, np.ndarray):
                cols[5].append(owners(owner[g.subj]))
            else:
                cols[5].append(np.full(m, const(g.subj_owner), np.int64))
            if isinstance(g.tgt_owner, np.ndarray):
                cols[6].append(owners(g.tgt_owner))
            else:
                cols[6].append(np.full(m, const(g.tgt_owner), np.int64))
            cols[7].append(labelled(g.value_text, m) if kind.text else np.full(m, empty))
            vt.append(np.full(m, int(kind.value_type), np.uint8))
            obs.append(np.full(m, float(g.obs)))
            if kind.number and g.value_num is not None:
                num.append(np.broadcast_to(np.asarray(g.value_num, np.float64), (m,)))
            else:
                num.append(np.zeros(m))
            conf.append(np.broadcast_to(np.asarray(g.conf, np.float64), (m,)))
        piece = [np.concatenate(c) for c in cols]
        return Columns(ids, consts, piece, *(np.concatenate(x) for x in (vt, obs, num, conf)))

    def _layout(self, c: Columns, n: int, t_ns: int) -> bytes:
        """The ROS 1 message of ``n`` facts' columns."""
        ids, consts, piece = c.ids, c.consts, c.piece
        middle = np.empty(n, _MIDDLE)
        middle["vt"], middle["obs"], middle["num"] = c.vt, c.obs, c.num
        tail = np.empty(n, _TAIL)
        tail["conf"], tail["t"], tail["t0"], tail["t1"] = c.conf, t_ns, t_ns, 0
        offsets = np.array(ids.offsets + [ids.size + o for o in consts.offsets], np.int64)
        lengths = np.array(ids.lengths + consts.lengths, np.int64)
        start_mid = ids.size + consts.size
        start_tail = start_mid + n * _MIDDLE.itemsize
        segments = [(offsets[p], lengths[p]) for p in piece[:7]]
        step = np.arange(n, dtype=np.int64)
        segments.append((start_mid + step * _MIDDLE.itemsize, np.full(n, _MIDDLE.itemsize)))
        segments.append((offsets[piece[7]], lengths[piece[7]]))
        segments.append((start_tail + step * _TAIL.itemsize, np.full(n, _TAIL.itemsize)))
        sources = [ids.blob(), consts.blob(), middle.tobytes(), tail.tobytes()]
        return _assemble(n, sources, segments)

    def _write_list(self, facts: list[Fact], t_ns: int) -> bytes:
        parts = [_U32.pack(len(facts))]
        for fact in facts:
            f = fact_fields(fact, t_ns)
            parts.extend(
                _piece(f[k])
                for k in (
                    "property",
                    "propertyType",
                    "subProperty",
                    "subjectId",
                    "targetId",
                    "subjectOwnerId",
                    "targetOwnerId",
                )
            )
            parts.append(
                struct.pack("<Bdd", f["valueType"], f["factObservability"], f["doubleValue"])
            )
            parts.append(_piece(f["stringValue"]))
            parts.append(
                struct.pack("<dQQQ", f["confidence"], f["time"], f["timeStart"], f["timeEnd"])
            )
        return b"".join(parts)


def tf_bytes(
    frame_id: str, children: Pieces, child: np.ndarray, pos: np.ndarray, quat: np.ndarray, t_ns: int
) -> bytes:
    """tf2_msgs/TFMessage bytes: one transform per row, all from ``frame_id`` at ``t_ns``
    (seq 0), children as pieces of ``children`` (their indices ``child``), positions (n, 3),
    quaternions (n, 4)."""
    n = len(child)
    head = np.zeros(1, _HEAD)
    head["secs"], head["nsecs"] = t_ns // 1_000_000_000, t_ns % 1_000_000_000
    frame = _piece(frame_id)
    poses = np.empty(n, _POSE)
    poses["t"], poses["q"] = pos, quat
    offsets = np.asarray(children.offsets, np.int64)
    lengths = np.asarray(children.lengths, np.int64)
    start_frame = _HEAD.itemsize
    start_children = start_frame + len(frame)
    start_poses = start_children + children.size
    step = np.arange(n, dtype=np.int64)
    segments = [
        (np.zeros(n, np.int64), np.full(n, _HEAD.itemsize)),
        (np.full(n, start_frame), np.full(n, len(frame))),
        (start_children + offsets[child], lengths[child]),
        (start_poses + step * _POSE.itemsize, np.full(n, _POSE.itemsize)),
    ]
    return _assemble(n, [head.tobytes(), frame, children.blob(), poses.tobytes()], segments)


class TfReader:
    """Reads tf2_msgs/TFMessage bytes into :class:`~toaster.world.tftree.Edges`; a message laid
    out as the previous one (same frames in the same order: a stream) reuses its offsets."""

    def __init__(self) -> None:
        self._layout: (
            tuple[int, np.ndarray, bytes, list[str], list[str], np.ndarray, np.ndarray] | None
        ) = None

    def read(self, data: bytes) -> Edges:
        """The transforms of one message; ValueError when the bytes are not a TFMessage."""
        u8 = np.frombuffer(data, np.uint8)
        layout = self._layout
        if layout is not None and layout[0] == len(data):
            _, text_at, text, parents, children, heads, poses = layout
            if u8[text_at].tobytes() == text:
                return _edges(u8, parents, children, heads, poses)
        try:
            layout = _scan(data)
        except (struct.error, IndexError) as exc:
            msg = f"not a tf2_msgs/TFMessage ({exc})"
            raise ValueError(msg) from None
        self._layout = layout
        _, _, _, parents, children, heads, poses = layout
        return _edges(u8, parents, children, heads, poses)


def _scan(
    data: bytes,
) -> tuple[int, np.ndarray, bytes, list[str], list[str], np.ndarray, np.ndarray]:
    """The layout of a TFMessage: where its strings are (and their bytes), its frame names,
    where each header and pose starts."""
    (count,) = _U32.unpack_from(data, 0)
    at = 4
    parents: list[str] = []
    children: list[str] = []
    heads = np.empty(count, np.int64)
    poses = np.empty(count, np.int64)
    spans: list[tuple[int, int]] = []
    unpack = _U32.unpack_from
    for i in range(count):
        heads[i] = at
        at += 12
        (size,) = unpack(data, at)
        parents.append(data[at + 4 : at + 4 + size].decode("utf-8", "replace"))
        spans.append((at, at + 4 + size))
        at += 4 + size
        (size,) = unpack(data, at)
        children.append(data[at + 4 : at + 4 + size].decode("utf-8", "replace"))
        spans.append((at, at + 4 + size))
        at += 4 + size
        poses[i] = at
        at += _POSE.itemsize
    if at != len(data):
        msg = f"{len(data)} bytes where {at} were expected"
        raise struct.error(msg)
    # the count and every string with its length: equal there, a message is laid out alike
    text_at = np.concatenate([np.arange(0, 4), *(np.arange(a, b) for a, b in spans)])
    text = np.frombuffer(data, np.uint8)[text_at].tobytes()
    return (len(data), text_at, text, parents, children, heads, poses)


def _edges(
    u8: np.ndarray, parents: list[str], children: list[str], heads: np.ndarray, poses: np.ndarray
) -> Edges:
    head = u8[heads[:, None] + np.arange(_HEAD.itemsize)].copy().view(_HEAD).reshape(-1)
    pose = u8[poses[:, None] + np.arange(_POSE.itemsize)].copy().view(_POSE).reshape(-1)
    stamps = head["secs"].astype(np.int64) * 1_000_000_000 + head["nsecs"].astype(np.int64)
    return Edges(children, parents, stamps, pose["t"], pose["q"])


def as_message(data: bytes) -> Any:
    """``data`` as a message rospy publishes on any topic as it is (``rospy.AnyMsg``)."""
    from rospy import AnyMsg  # type: ignore[import-not-found]

    msg = AnyMsg()
    msg._buff = data
    return msg


def fact_list_message(
    writer: FactListWriter, facts: Mapping[str, Any], name: str, t_ns: int
) -> Any:
    """The FactList of producer ``name`` (a batch when the tick has one) as a message."""
    raw = getattr(facts, "raw", None)
    found = raw(name) if raw is not None else facts.get(name, [])
    return as_message(writer.write(found if found is not None else [], t_ns))
