"""The two messages of every tick written and read as CDR bytes directly (the ROS 2 analogue of
:mod:`toaster.ros1.wire`): cyclonedds' Python codec walks a message field by field, ~5 ms for a
/tf of 60 transforms and ~10 ms for a fact list of 60 facts, which a 30 Hz node cannot spend.

Plain CDR (XCDR1), as ROS 2 writes it: a 4-byte encapsulation (``00 01`` little endian,
``00 00`` big endian, two option bytes), then each field aligned to its size (8 for float64 and
uint64) counted from the end of the encapsulation; strings are a uint32 length with the NUL,
sequences a uint32 count. ``tests/ros2/test_wire.py`` checks these bytes against cyclonedds'
and rosbags' codecs.
"""

from __future__ import annotations

import struct
from collections.abc import Iterable, Mapping
from typing import Any

import numpy as np

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


def read_tf(data: bytes) -> Edges:
    """A tf2_msgs/TFMessage's transforms as :class:`~toaster.world.tftree.Edges`;
    ValueError when the bytes are not one."""
    data = bytes(data)  # (the same object when it is bytes already)
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
        for i in range(count):
            at += -(at - 4) % 4
            sec, nanosec = stamp.unpack_from(data, at)
            stamps[i] = sec * 1_000_000_000 + nanosec
            at += 8
            for names in (parents, children):
                at += -(at - 4) % 4
                (size,) = u32.unpack_from(data, at)
                if size < 1 or at + 4 + size > len(data):
                    msg = f"a frame name of {size} bytes at offset {at}"
                    raise ValueError(msg)
                names.append(data[at + 4 : at + 3 + size].decode())
                at += 4 + size
            at += -(at - 4) % 8
            numbers[i] = f64x7.unpack_from(data, at)
            at += 56
    except (struct.error, UnicodeDecodeError) as exc:
        msg = f"not a tf2_msgs/TFMessage ({exc})"
        raise ValueError(msg) from None
    return Edges(children, parents, stamps, numbers[:, :3], numbers[:, 3:])
