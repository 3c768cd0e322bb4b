"""toaster_msgs (and hri_msgs/IdsList) classes built at run time from the shipped .msg/.srv text.

No catkin build: the text files under ``msgs/<package>/{msg,srv}`` are parsed with genmsg,
completed with the text of the standard types they use (taken from Debian's generated classes,
e.g. ``geometry_msgs/Pose``), and turned into classes by ``genpy.dynamic.generate_dynamic`` in
one go. Service classes carry ``_type``, ``_md5sum``, ``_request_class`` and
``_response_class`` as genpy's generated ones do; the md5 sums are genmsg's, so they match
the original's compiled toaster_msgs when the fields match.

This module imports nothing from toaster (the ROS test clients load it by file path under the
system Python) and imports genpy/genmsg only when :func:`load` runs.
"""

from __future__ import annotations

import hashlib
import importlib
import sys
import threading
from pathlib import Path
from typing import Any

DEBIAN_DIST = "/usr/lib/python3/dist-packages"
MSG_ROOT = Path(__file__).resolve().parent / "msgs"
SEPARATOR = "=" * 80 + "\n"
#: standard types whose text comes from Debian's generated classes: type -> (module, class)
STANDARD = {
    "std_msgs/Header": ("std_msgs.msg", "Header"),
    "geometry_msgs/Pose": ("geometry_msgs.msg", "Pose"),
    "geometry_msgs/Point": ("geometry_msgs.msg", "Point"),
    "geometry_msgs/Point32": ("geometry_msgs.msg", "Point32"),
    "geometry_msgs/Quaternion": ("geometry_msgs.msg", "Quaternion"),
    "geometry_msgs/Polygon": ("geometry_msgs.msg", "Polygon"),
}


def ros_path() -> None:
    """Make Debian's ROS 1 Python packages importable (appended once, at the end)."""
    if DEBIAN_DIST not in sys.path and Path(DEBIAN_DIST).is_dir():
        sys.path.append(DEBIAN_DIST)


class Registry:
    """Message classes by type ("toaster_msgs/Fact") and service classes ("toaster_msgs/AddArea");
    short names ("Fact", "AddArea") work for toaster_msgs."""

    def __init__(self, messages: dict[str, Any], services: dict[str, Any]) -> None:
        self.messages = messages
        self.services = services

    def msg(self, name: str) -> Any:
        """The message class of ``name``."""
        return self.messages[name if "/" in name else f"toaster_msgs/{name}"]

    def srv(self, name: str) -> Any:
        """The service class of ``name``."""
        return self.services[name if "/" in name else f"toaster_msgs/{name}"]


def standard_texts() -> dict[str, str]:
    """Own text of each standard type (and of the types they embed), from Debian's classes."""
    texts: dict[str, str] = {}
    for full, (module, cls) in STANDARD.items():
        parts = getattr(importlib.import_module(module), cls)._full_text.split("\n" + SEPARATOR)
        texts.setdefault(full, parts[0])
        for part in parts[1:]:
            head, _, body = part.partition("\n")
            texts.setdefault(head.removeprefix("MSG: ").strip(), body)
    return texts


def _shipped(root: Path) -> tuple[dict[str, str], dict[str, tuple[str, str]]]:
    """Message texts and service (request, response) texts under ``root``."""
    messages: dict[str, str] = {}
    services: dict[str, tuple[str, str]] = {}
    for path in sorted(root.glob("*/msg/*.msg")):
        messages[f"{path.parents[1].name}/{path.stem}"] = path.read_text()
    for path in sorted(root.glob("*/srv/*.srv")):
        lines = path.read_text().splitlines()
        cut = next(i for i, line in enumerate(lines) if line.strip() == "---")
        services[f"{path.parents[1].name}/{path.stem}"] = (
            "\n".join(lines[:cut]) + "\n",
            "\n".join(lines[cut + 1 :]) + "\n",
        )
    return messages, services


def _full_text(name: str, texts: dict[str, str], specs: dict[str, Any]) -> str:
    """``gendeps --cat`` text of a type: its own text, then each embedded type once."""
    import genmsg  # type: ignore[import-not-found]

    order: list[str] = []

    def walk(type_name: str) -> None:
        for field_type in specs[type_name].types:
            base = genmsg.msgs.bare_msg_type(field_type)
            if base in specs:
                order.append(base)
                walk(base)

    walk(name)
    unique = list(dict.fromkeys(order))
    out = texts[name] + "\n"
    for dep in unique:
        out += SEPARATOR + f"MSG: {dep}\n" + texts[dep] + "\n"
    return out[:-1]


def _build(root: Path) -> Registry:
    ros_path()
    import genmsg  # type: ignore[import-not-found]
    import genmsg.gentools  # type: ignore[import-not-found]
    import genmsg.msg_loader  # type: ignore[import-not-found]
    import genpy.dynamic  # type: ignore[import-not-found]

    shipped, services = _shipped(root)
    texts = standard_texts()
    texts.update(shipped)
    for name, (request, response) in services.items():
        texts[f"{name}Request"], texts[f"{name}Response"] = request, response
    context = genmsg.MsgContext.create_default()
    specs = {
        name: genmsg.msg_loader.load_msg_from_string(context, text, name)
        for name, text in texts.items()
    }
    for name, spec in specs.items():
        context.register(name, spec)
    wanted = [*shipped, *(f"{n}{part}" for n in services for part in ("Request", "Response"))]
    bundle = _full_text(wanted[0], texts, specs)
    for name in [*wanted[1:], *(n for n in texts if n not in wanted)]:
        bundle += "\n" + SEPARATOR + f"MSG: {name}\n" + texts[name]
    classes = genpy.dynamic.generate_dynamic(wanted[0], bundle)
    messages = {name: classes[name] for name in wanted}
    for name in wanted:
        messages[name]._full_text = _full_text(name, texts, specs)
    service_classes: dict[str, Any] = {}
    for name in services:
        request, response = specs[f"{name}Request"], specs[f"{name}Response"]
        digest = hashlib.md5()
        digest.update(genmsg.gentools.compute_md5_text(context, request).encode())
        digest.update(genmsg.gentools.compute_md5_text(context, response).encode())
        service_classes[name] = type(
            name.split("/")[1],
            (),
            {
                "_type": name,
                "_md5sum": digest.hexdigest(),
                "_request_class": messages[f"{name}Request"],
                "_response_class": messages[f"{name}Response"],
            },
        )
    return Registry(messages, service_classes)


_lock = threading.Lock()
_cache: dict[Path, Registry] = {}


def load(root: Path = MSG_ROOT) -> Registry:
    """The classes of every .msg/.srv under ``root`` (built once per process)."""
    with _lock:
        if root not in _cache:
            _cache[root] = _build(root)
        return _cache[root]


# -- plain values <-> messages ------------------------------------------------------------------
def message_class(type_name: str, registry: Registry | None = None) -> Any:
    """The class of a message type: a shipped one, else Debian's generated one."""
    if type_name == "Header":
        type_name = "std_msgs/Header"
    if registry is not None and type_name in registry.messages:
        return registry.messages[type_name]
    package, _, name = type_name.partition("/")
    return getattr(importlib.import_module(f"{package}.msg"), name)


def _value(slot_type: str, value: Any, registry: Registry | None) -> Any:
    import genmsg.msgs  # type: ignore[import-not-found]
    import genpy  # type: ignore[import-not-found]

    base, is_array, _ = genmsg.msgs.parse_type(slot_type)
    if is_array:
        if base in ("uint8", "char"):
            return bytes(value)
        return [_value(base, item, registry) for item in value]
    if base in ("time", "duration") and isinstance(value, int):
        cls = genpy.Time if base == "time" else genpy.Duration
        return cls(value // 1_000_000_000, value % 1_000_000_000)
    if base in genmsg.msgs.BUILTIN_TYPES or not isinstance(value, dict):
        return value
    return to_msg(message_class(base, registry), value, registry)


def to_msg(cls: Any, data: dict[str, Any], registry: Registry | None = None) -> Any:
    """A message of class ``cls`` from a dict of its fields (nested dicts and lists; times as
    int ns); fields left out keep their defaults."""
    msg = cls()
    for name, slot_type in zip(cls.__slots__, cls._slot_types, strict=True):
        if name in data:
            setattr(msg, name, _value(slot_type, data[name], registry))
    return msg


def from_msg(value: Any) -> Any:
    """Plain JSON-able values of a message (times as int ns)."""
    if hasattr(value, "_slot_types"):
        return {name: from_msg(getattr(value, name)) for name in value.__slots__}
    if isinstance(value, list | tuple):
        return [from_msg(v) for v in value]
    if isinstance(value, bytes):
        return list(value)
    if hasattr(value, "to_nsec"):
        return int(value.to_nsec())
    return value
