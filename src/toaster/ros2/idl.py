"""ROS 2 messages as cyclonedds IDL types (``IdlStruct`` with the ROS 2 DDS type name).

The definitions are rosbags' ROS 2 ones (ROS 2 Humble's standard types: builtin_interfaces,
std_msgs, geometry_msgs, tf2_msgs, visualization_msgs...) and toaster's shipped toaster_msgs /
hri_msgs with the ROS 2 field names the recordings use (``subject_id``;
:func:`toaster.outputs.recording.msgs.toaster_types`). Each becomes a final struct, so it is
written as plain CDR (XCDR1) as rosidl's types are. A service ``pkg/srv/S`` is two structs
``pkg::srv::dds_::S_Request_`` / ``S_Response_`` with rmw_cyclonedds' sample identity in front
(:data:`toaster.ros2.names.REQUEST_HEADER`): :meth:`Types.request` / :meth:`Types.reply`.
"""

from __future__ import annotations

import functools
import threading
from collections.abc import Mapping
from typing import Any

from toaster.ros2.names import REQUEST_HEADER, dds_type

TIME = "builtin_interfaces/msg/Time"
#: rosidl gives an empty message one member (an empty struct is not valid IDL)
EMPTY_MEMBER = "structure_needs_at_least_one_member"


def _base_types() -> dict[str, Any]:
    from cyclonedds.idl import types as t

    return {
        "bool": bool,
        "byte": t.uint8,
        "octet": t.uint8,
        "char": t.uint8,
        "int8": t.int8,
        "uint8": t.uint8,
        "int16": t.int16,
        "uint16": t.uint16,
        "int32": t.int32,
        "uint32": t.uint32,
        "int64": t.int64,
        "uint64": t.uint64,
        "float32": t.float32,
        "float64": t.float64,
        "string": str,
    }


def _service_texts() -> dict[str, tuple[str, str]]:
    """{"pkg/S": (request text, response text)} of every shipped .srv."""
    from toaster.world.bags import MSG_DIR

    out: dict[str, tuple[str, str]] = {}
    for path in sorted(MSG_DIR.glob("*/srv/*.srv")):
        lines = path.read_text().splitlines()
        cut = next(i for i, line in enumerate(lines) if line.strip() == "---")
        out[f"{path.parents[1].name}/{path.stem}"] = (
            "\n".join(lines[:cut]) + "\n",
            "\n".join(lines[cut + 1 :]) + "\n",
        )
    return out


def typestore() -> Any:
    """A rosbags typestore: ROS 2 Humble's types, toaster_msgs and hri_msgs with ROS 2 field
    names, and each shipped service's parts as ``pkg/msg/S_Request`` / ``S_Response``."""
    from rosbags.typesys import Stores, get_types_from_msg, get_typestore

    from toaster.outputs.recording.msgs import snake, toaster_types

    store = get_typestore(Stores.ROS2_HUMBLE)
    types = dict(toaster_types("ros2"))
    for name, (request, response) in _service_texts().items():
        package, stem = name.split("/")
        for part, text in (("Request", request), ("Response", response)):
            found = get_types_from_msg(text, f"{package}/msg/{stem}_{part}")
            for key, (consts, fields) in found.items():
                if package == "toaster_msgs":
                    fields = [(snake(f), spec) for f, spec in fields]
                types[key] = (consts, fields)
    store.register(types)
    return store


class Types:
    """IDL classes by ROS 2 type (``geometry_msgs/msg/PoseStamped``), made on first use; and
    :meth:`build` to make a message from nested dicts (missing fields zero, times as int ns,
    toaster_msgs fields under their original names too: ``subjectId``)."""

    def __init__(self) -> None:
        self.store = typestore()
        self._classes: dict[str, Any] = {}
        self._wrapped: dict[tuple[str, str], Any] = {}
        self._lock = threading.RLock()
        self._base = _base_types()

    def service_part(self, service_type: str, part: str) -> str:
        """The typestore name of a service's part: ``toaster_msgs/AddArea``, "Request" ->
        ``toaster_msgs/msg/AddArea_Request``."""
        package, _, name = service_type.partition("/")
        if not name:
            package, name = "toaster_msgs", service_type
        return f"{package}/msg/{name}_{part}"

    def fields(self, msgtype: str) -> list[tuple[str, Any]]:
        """(name, rosbags field spec) of ``msgtype``; an empty message has rosidl's member."""
        from rosbags.typesys.store import Nodetype  # type: ignore[attr-defined]

        found = list(self.store.fielddefs[msgtype][1])
        return found or [(EMPTY_MEMBER, (Nodetype.BASE, ("uint8", 0)))]

    def cls(self, msgtype: str, typename: str | None = None) -> Any:
        """The IDL class of ``msgtype`` (its DDS type name, or ``typename``)."""
        from cyclonedds.idl import make_idl_struct

        key = f"{msgtype}@{typename}" if typename else msgtype
        with self._lock:
            if key not in self._classes:
                annotations = {name: self._annotation(spec) for name, spec in self.fields(msgtype)}
                self._classes[key] = make_idl_struct(
                    msgtype.rsplit("/", 1)[1], typename or dds_type(msgtype), annotations
                )
            return self._classes[key]

    def _annotation(self, spec: Any) -> Any:
        from cyclonedds.idl import types

        t: Any = types  # its generics are classes with __class_getitem__ mypy does not see

        node, detail = spec
        kind = getattr(node, "name", node)
        if kind == "BASE":
            name, bound = detail
            return t.bounded_str[bound] if name == "string" and bound else self._base[name]
        if kind == "NAME":
            return self.cls(detail)
        inner, count = detail
        item = self._annotation(inner)
        if kind == "ARRAY":
            return t.array[item, count]
        return t.sequence[item, count] if count else t.sequence[item]

    def wrapped(self, service_type: str, part: str) -> Any:
        """A service part with rmw_cyclonedds' sample identity in front, under its DDS name
        (``pkg::srv::dds_::S_Request_``): fields ``guid``, ``seq``, ``body``."""
        from cyclonedds.idl import make_idl_struct
        from cyclonedds.idl import types as t

        with self._lock:
            if (service_type, part) not in self._wrapped:
                msgtype = self.service_part(service_type, part)
                package, _, stem = msgtype.split("/")
                body = self.cls(msgtype, f"{package}::srv::dds_::{stem}_body_")
                header = {name: getattr(t, kind) for name, kind in REQUEST_HEADER}
                self._wrapped[service_type, part] = make_idl_struct(
                    f"{stem}_", f"{package}::srv::dds_::{stem}_", {**header, "body": body}
                )
            return self._wrapped[service_type, part]

    # -- values ---------------------------------------------------------------------------------
    def build(self, msgtype: str, value: Any, typename: str | None = None) -> Any:
        """A ``msgtype`` message from ``value`` (a dict; a message passes through)."""
        if not isinstance(value, Mapping):
            if msgtype == TIME and isinstance(value, int):
                return self.cls(TIME)(sec=value // 1_000_000_000, nanosec=value % 1_000_000_000)
            return value
        plan = self.fields(msgtype)
        if msgtype.startswith("toaster_msgs/") and any(name not in value for name, _ in plan):
            value = {_snake(key): item for key, item in value.items()} | dict(value)
        return self.cls(msgtype, typename)(
            **{
                name: self._convert(spec, value[name]) if name in value else self._zero(spec)
                for name, spec in plan
            }
        )

    def _convert(self, spec: Any, value: Any) -> Any:
        node, detail = spec
        kind = getattr(node, "name", node)
        if kind == "NAME":
            return self.build(detail, value)
        if kind == "BASE":
            return _base(detail[0], value)
        inner, _ = detail
        if isinstance(value, bytes | bytearray):
            value = list(value)
        return [self._convert(inner, v) for v in value]

    def _zero(self, spec: Any) -> Any:
        node, detail = spec
        kind = getattr(node, "name", node)
        if kind == "NAME":
            return self.build(detail, {})
        if kind == "BASE":
            return _base(detail[0], "" if detail[0] == "string" else 0)
        inner, count = detail
        return [self._zero(inner) for _ in range(count if kind == "ARRAY" else 0)]


def _base(kind: str, value: Any) -> Any:
    if kind == "string":
        return str(value)
    if kind == "bool":
        return bool(value)
    return float(value) if kind.startswith("float") else int(value)


@functools.cache
def _snake(name: str) -> str:
    from toaster.outputs.recording.msgs import snake

    return snake(name)


def plain(value: Any) -> Any:
    """A message's fields as nested dicts and lists (times stay messages with sec/nanosec)."""
    fields = getattr(value, "__dataclass_fields__", None)
    if fields is not None:
        return {name: plain(getattr(value, name)) for name in fields}
    if isinstance(value, list | tuple):
        return [plain(v) for v in value]
    return value
