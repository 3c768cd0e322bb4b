"""The two messages of every tick written and read as CDR bytes directly (the ROS 2 analogue of
:mod:`toaster.ros1.wire`): cyclonedds' Python codec walks a message field by field, ~5 ms for a
/tf of 60 transforms and ~10 ms for a fact list of 60 facts, which a 30 Hz node cannot spend.

Plain CDR (XCDR1), as ROS 2 writes it: a 4-byte encapsulation (``00 01`` little endian,
``00 00`` big endian, two option bytes), then each field aligned to its size (8 for float64 and
uint64) counted from the end of the encapsulation; strings are a uint32 length with the NUL,
sequences a uint32 count. Fact lists are laid out from the tick's arrays (:class:`FactListCdr`,
the ROS 1 writer's columns: ~2 ms per 100 facts through one dict per fact before); a /tf stream
is read with its layout kept (:class:`TfReader`).
``tests/ros2/test_wire.py`` checks these bytes against cyclonedds' and rosbags' codecs.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Mapping
from typing import Any, NamedTuple

import numpy as np

from toaster.model import Fact
from toaster.ros1.wire import Columns, FactListWriter, Pieces, _assemble
from toaster.world.factmsg import fact_fields
from toaster.world.tftree import Edges

CDR_LE = b"\x00\x01\x00\x00"
#: toaster_msgs/Fact in order: (field as fact_fields names it, CDR kind)
FACT = (
    ("property", "string"),
    ("propertyType", "string"),
    ("subProperty", "string"),
    ("subjectId", "string"),
    ("targetId", "string"),
    ("subjectOwnerId", "string"),
    ("targetOwnerId", "string"),
    ("valueType", "bool"),
    ("factObservability", "float64"),
    ("doubleValue", "float64"),
    ("stringValue", "string"),
    ("confidence", "float64"),
    ("time", "uint64"),
    ("timeStart", "uint64"),
    ("timeEnd", "uint64"),
)
_PACK = {"bool": ("<?", 1), "float64": ("<d", 8), "uint64": ("<Q", 8)}


def fact_list_bytes(items: Iterable[Mapping[str, Any]]) -> bytes:
    """toaster_msgs/FactList CDR (little endian) of Fact field dicts (:func:`fact_fields`)."""
    items = list(items)
    out = bytearray(CDR_LE)
    out += struct.pack("<I", len(items))
    for item in items:
        for name, kind in FACT:
            value = item[name]
            if kind == "string":
                out += b"\x00" * (-(len(out) - 4) % 4)
                text = str(value).encode() + b"\x00"
                out += struct.pack("<I", len(text))
                out += text
            else:
                fmt, size = _PACK[kind]
                out += b"\x00" * (-(len(out) - 4) % size)
                out += struct.pack(fmt, value)
    return bytes(out)


#: a Fact's valueType, then up to 7 bytes of padding, factObservability and doubleValue
_MIDDLE = np.dtype([("vt", "u1"), ("pad", "u1", 7), ("obs", "<f8"), ("num", "<f8")])
#: up to 8 bytes of padding, then confidence, time, timeStart, timeEnd
_TAIL = np.dtype([("pad", "u1", 8), ("conf", "<f8"), ("t", "<u8"), ("t0", "<u8"), ("t1", "<u8")])
_U32 = struct.Struct("<I")


class CdrPieces(Pieces):
    """CDR strings (a uint32 length counting the NUL, UTF-8, NUL), each padded to 4 bytes;
    :attr:`unpadded` their lengths without the padding."""

    def __init__(self, texts: Iterable[str] = ()) -> None:
        self.unpadded: list[int] = []
        super().__init__(list(texts))

    def encode(self, text: str) -> bytes:
        data = text.encode("utf-8") + b"\x00"
        self.unpadded.append(4 + len(data))
        return _U32.pack(len(data)) + data + b"\x00" * (-len(data) % 4)


class FactListCdr(FactListWriter):
    """toaster_msgs/FactList CDR bytes of a producer's facts, from a batch's arrays (the ROS 1
    writer's :class:`~toaster.ros1.wire.Columns` laid out as CDR): what
    :func:`fact_list_bytes` writes of their :func:`fact_fields`.

    Every Fact ends 8-aligned (timeEnd, a uint64), so each one after the first starts at an
    8-aligned offset and the first at 4 (after the count): a fact's padding depends only on its
    own strings. A string is followed by another string (padded pieces), by valueType (the
    7th, unpadded), or by 8-aligned fields (stringValue, unpadded, then 0-7 zero bytes)."""

    pieces = CdrPieces

    def _write_list(self, facts: list[Fact], t_ns: int) -> bytes:
        return fact_list_bytes(fact_fields(f, t_ns) for f in facts)

    def _layout(self, c: Columns, n: int, t_ns: int) -> bytes:
        ids, consts, piece = c.ids, c.consts, c.piece
        assert isinstance(ids, CdrPieces)
        assert isinstance(consts, CdrPieces)
        offsets = np.array(ids.offsets + [ids.size + o for o in consts.offsets], np.int64)
        padded = np.array(ids.lengths + consts.lengths, np.int64)
        unpadded = np.array(ids.unpadded + consts.unpadded, np.int64)
        start = np.zeros(n, np.int64)
        start[0] = 4
        before_vt = start + sum(padded[p] for p in piece[:6]) + unpadded[piece[6]]
        pad_mid = -(before_vt + 1) % 8
        pad_tail = -unpadded[piece[7]] % 8  # stringValue starts 8-aligned
        middle = np.zeros(n, _MIDDLE)
        middle["vt"], middle["obs"], middle["num"] = c.vt, c.obs, c.num
        tail = np.zeros(n, _TAIL)
        tail["conf"], tail["t"], tail["t0"], tail["t1"] = c.conf, t_ns, t_ns, 0
        at_mid = ids.size + consts.size + np.arange(n, dtype=np.int64) * _MIDDLE.itemsize
        at_tail = at_mid[-1] + _MIDDLE.itemsize + np.arange(n, dtype=np.int64) * _TAIL.itemsize
        segments = [(offsets[p], padded[p]) for p in piece[:6]]
        segments.append((offsets[piece[6]], unpadded[piece[6]]))
        segments.append((at_mid, np.ones(n, np.int64)))
        segments.append((at_mid + 8 - pad_mid, pad_mid + 16))
        segments.append((offsets[piece[7]], unpadded[piece[7]]))
        segments.append((at_tail + 8 - pad_tail, pad_tail + 32))
        sources = [ids.blob(), consts.blob(), middle.tobytes(), tail.tobytes()]
        return CDR_LE + _assemble(n, sources, segments)


_STAMP = np.dtype([("sec", "<i4"), ("nsec", "<u4")])


class _Layout(NamedTuple):
    """Where a little-endian TFMessage's strings (with the count: ``text_at``, their bytes
    ``text``), stamps and poses are."""

    size: int
    text_at: np.ndarray
    text: bytes
    parents: list[str]
    children: list[str]
    stamp_at: np.ndarray
    pose_at: np.ndarray

    def edges(self, u8: np.ndarray) -> Edges:
        stamp = u8[self.stamp_at[:, None] + np.arange(8)].copy().view(_STAMP).reshape(-1)
        pose = u8[self.pose_at[:, None] + np.arange(56)].copy().view("<f8").reshape(-1, 7)
        stamps = stamp["sec"].astype(np.int64) * 1_000_000_000 + stamp["nsec"]
        return Edges(self.children, self.parents, stamps, pose[:, :3], pose[:, 3:])


class TfReader:
    """Reads tf2_msgs/TFMessage CDR as :func:`read_tf` does; a little-endian message laid out
    as the previous one (the same frames in the same order: a stream) reuses its offsets and
    is read with two gathers (:class:`toaster.ros1.wire.TfReader`'s way), not a Python loop
    over its transforms on the receive thread."""

    def __init__(self) -> None:
        self._layout: _Layout | None = None

    def read(self, data: bytes) -> Edges:
        """The transforms of one message; ValueError when the bytes are not one."""
        data = bytes(data)
        u8 = np.frombuffer(data, np.uint8)
        layout = self._layout
        same = layout is not None and layout.size == len(data)
        if same and u8[layout.text_at].tobytes() == layout.text:  # type: ignore[union-attr]
            return layout.edges(u8)  # type: ignore[union-attr]
        edges, self._layout = _read_tf(data)
        return edges


def read_tf(data: bytes) -> Edges:
    """A tf2_msgs/TFMessage's transforms as :class:`~toaster.world.tftree.Edges`;
    ValueError when the bytes are not one."""
    return _read_tf(bytes(data))[0]


def _read_tf(data: bytes) -> tuple[Edges, _Layout | None]:
    """:func:`read_tf`, and the message's layout when it is little endian with transforms."""
    if len(data) < 8 or data[0] != 0 or data[1] not in (0, 1):
        msg = f"not a plain CDR sample (encapsulation {data[:4].hex()})"
        raise ValueError(msg)
    end = "<" if data[1] == 1 else ">"
    u32, stamp, f64x7 = (
        struct.Struct(end + "I"),
        struct.Struct(end + "iI"),
        struct.Struct(end + "7d"),
    )
    try:
        (count,) = u32.unpack_from(data, 4)
        if count > (len(data) - 8) // 64:  # a transform takes at least 64 bytes
            msg = f"{count} transforms cannot fit in {len(data)} bytes"
            raise ValueError(msg)
        at = 8
        parents: list[str] = []
        children: list[str] = []
        stamps = np.empty(count, np.int64)
        numbers = np.empty((count, 7))
        stamp_at = np.empty(count, np.int64)
        pose_at = np.empty(count, np.int64)
        spans: list[np.ndarray] = [np.arange(8)]
        for i in range(count):
            at += -(at - 4) % 4
            sec, nanosec = stamp.unpack_from(data, at)
            stamps[i], stamp_at[i] = sec * 1_000_000_000 + nanosec, at
            at += 8
            for names in (parents, children):
                at += -(at - 4) % 4
                (size,) = u32.unpack_from(data, at)
                if size < 1 or at + 4 + size > len(data):
                    msg = f"a frame name of {size} bytes at offset {at}"
                    raise ValueError(msg)
                names.append(data[at + 4 : at + 3 + size].decode())
                spans.append(np.arange(at, at + 4 + size))
                at += 4 + size
            at += -(at - 4) % 8
            numbers[i], pose_at[i] = f64x7.unpack_from(data, at), at
            at += 56
    except (struct.error, UnicodeDecodeError) as exc:
        msg = f"not a tf2_msgs/TFMessage ({exc})"
        raise ValueError(msg) from None
    edges = Edges(children, parents, stamps, numbers[:, :3], numbers[:, 3:])
    if end == ">" or not count or at != len(data):
        return edges, None
    text_at = np.concatenate(spans)
    text = np.frombuffer(data, np.uint8)[text_at].tobytes()
    return edges, _Layout(len(data), text_at, text, parents, children, stamp_at, pose_at)
