"""The container of a recording, chosen by ROS distro (helpers of :mod:`toaster.outputs.recording`).

* ROS 2 distros (humble, iron, jazzy, kilted): a rosbag2 directory holding one MCAP file and a
  ``metadata.yaml`` of the version that distro's ``ros2 bag`` writes (and the newest it reads),
  message definitions of that distro;
* ``noetic``: a ROS 1 ``.bag`` file (rosbag format 2.0, what the original TOASTER recorded),
  Noetic's message definitions, toaster_msgs with the original's field names.

:class:`BagWriter` hides the difference: connections by topic, messages serialised as the
container wants them (CDR or ROS 1), log lines in each ROS's Log type.
"""

from __future__ import annotations

from pathlib import Path
from typing import Any, NamedTuple

from toaster.errors import InvalidInputError
from toaster.extras import require

#: rosbag2 metadata version each distro's ``ros2 bag`` writes (and the newest it reads): Humble
#: 5 (``files``), Iron 8 (``custom_data``, ``type_description_hash``, ``ros_distro``), Jazzy 9
#: (QoS profiles as a YAML list); Kilted keeps 9.
METADATA_VERSIONS = {"humble": 5, "iron": 8, "jazzy": 9, "kilted": 9}
ROS1_DISTROS = ("noetic",)
DISTROS = (*METADATA_VERSIONS, *ROS1_DISTROS)
ROS2_LOG, ROS1_LOG = "rcl_interfaces/msg/Log", "rosgraph_msgs/msg/Log"
#: tf2_msgs is not in rosbags' Noetic store: its one message, as tf2_msgs/msg/TFMessage.msg
TF_MESSAGE, TF_MESSAGE_MSG = "tf2_msgs/msg/TFMessage", "geometry_msgs/TransformStamped[] transforms"
#: INFO in each ROS's Log message
INFO_LEVEL = {False: 20, True: 2}


class BagFormat(NamedTuple):
    """A distro and what it implies: ROS 1 or 2, the rosbag2 metadata version (0 for ROS 1)."""

    distro: str
    version: int

    @property
    def ros1(self) -> bool:
        """True for a ROS 1 ``.bag`` file."""
        return self.distro in ROS1_DISTROS


def bag_format(path: str | Path, distro: str | None = None) -> BagFormat:
    """The format of a recording at ``path``: ``distro``, by default noetic for a ``.bag`` name
    and humble otherwise; a one-line error for an unknown distro or a name that does not fit."""
    is_bag = Path(path).suffix.lower() == ".bag"
    name = (distro or ("noetic" if is_bag else "humble")).lower()
    if name not in DISTROS:
        msg = f"unknown ROS distro {distro!r}: use one of {', '.join(DISTROS)}"
        raise InvalidInputError(msg)
    fmt = BagFormat(name, METADATA_VERSIONS.get(name, 0))
    if fmt.ros1 and not is_bag:
        msg = f"cannot record a ROS 1 bag into {str(path)!r}: name the file <name>.bag"
        raise InvalidInputError(msg)
    if is_bag and not fmt.ros1:
        msg = (
            f"cannot record a {name} bag into {str(path)!r}: a .bag file is ROS 1 "
            "(--distro noetic); a rosbag2 recording is a folder: drop the .bag suffix"
        )
        raise InvalidInputError(msg)
    return fmt


def toaster_spelling(fmt: BagFormat, names: str | None) -> str:
    """toaster_msgs field names for ``fmt``: ROS 2 bags default to ``ros2``, ROS 1 bags keep the
    original's (``ros1``; snake_case names would not be the original's messages there)."""
    if names is None:
        return "ros1" if fmt.ros1 else "ros2"
    if names not in ("ros1", "ros2"):
        msg = f"unknown toaster_msgs field names {names!r}: use ros1 or ros2"
        raise InvalidInputError(msg)
    if fmt.ros1 and names == "ros2":
        msg = (
            "a ROS 1 bag holds toaster_msgs with the original's field names: drop "
            "toaster_names='ros2' (--toaster-names ros2)"
        )
        raise InvalidInputError(msg)
    return names


def _rosbags() -> Any:
    require("rosbag", "recording")
    import rosbags.rosbag1
    import rosbags.rosbag2
    import rosbags.typesys

    return rosbags


class BagWriter:
    """A new bag at ``path`` in format ``fmt``, with the standard types of its distro and
    ``types`` (toaster_msgs...) registered; open, connect topics, write, close."""

    def __init__(self, path: str | Path, fmt: BagFormat, types: dict[str, Any]) -> None:
        rosbags = _rosbags()
        self.path, self.fmt = Path(path), fmt
        if self.path.exists():
            what = "file" if fmt.ros1 else "folder"
            msg = f"cannot record into {str(self.path)!r}: it exists; give a new {what} name"
            raise InvalidInputError(msg)
        store = rosbags.typesys.Stores[f"ROS{1 if fmt.ros1 else 2}_{fmt.distro.upper()}"]
        self.types = rosbags.typesys.get_typestore(store)
        if TF_MESSAGE not in self.types.types:
            types = rosbags.typesys.get_types_from_msg(TF_MESSAGE_MSG, TF_MESSAGE) | types
        self.types.register(types)
        if fmt.ros1:
            self._writer = rosbags.rosbag1.Writer(self.path)
            self._serialize = self.types.serialize_ros1
        else:
            # rosbags writes versions 8 and 9; below 9 its QoS profiles are Humble's strings
            plugin = rosbags.rosbag2.StoragePlugin.MCAP
            self._writer = rosbags.rosbag2.Writer(
                self.path, version=min(max(fmt.version, 8), 9), storage_plugin=plugin
            )
            self._writer.version = fmt.version
            self._serialize = self.types.serialize_cdr
        self._conns: dict[str, Any] = {}

    @property
    def log_type(self) -> str:
        """The Log message of this ROS (rcl_interfaces or rosgraph_msgs)."""
        return ROS1_LOG if self.fmt.ros1 else ROS2_LOG

    def log_fields(self, t_ns: int, name: str, text: str) -> dict[str, Any]:
        """An INFO line as this ROS's Log message fields."""
        level = INFO_LEVEL[self.fmt.ros1]
        if self.fmt.ros1:
            return {"header": {"stamp": t_ns}, "level": level, "name": name, "msg": text}
        return {"stamp": t_ns, "level": level, "name": name, "msg": text}

    @property
    def file(self) -> Path:
        """The file a viewer opens: the ``.bag`` itself, or the ``.mcap`` inside the folder."""
        return self.path if self.fmt.ros1 else next(self.path.glob("*.mcap"))

    def open(self) -> None:
        """Create the bag."""
        self._writer.open()

    def close(self, *, discard: bool = False) -> None:
        """Finish the bag (a rosbag2 bag's metadata as its distro writes it); ``discard``
        removes it (a recording that failed half-way is not left behind)."""
        self._writer.close()
        if discard:
            import shutil

            if self.path.is_dir():
                shutil.rmtree(self.path)
            else:
                self.path.unlink(missing_ok=True)
        elif not self.fmt.ros1:
            fit_metadata(self.path, self.fmt.version, self.fmt.distro)

    def has(self, topic: str) -> bool:
        """Whether ``topic`` has a connection."""
        return topic in self._conns

    def connect(self, topic: str, msgtype: str, *, latched: bool = False) -> None:
        """Add ``topic`` of ``msgtype`` (its definition, dependencies included, goes in the bag);
        ``latched``: a ROS 1 bag marks it latched, so ``rosbag play`` hands its last message to
        subscribers that come later (an RViz started after the bag)."""
        extra = {"latching": 1} if latched and self.fmt.ros1 else {}
        self._conns[topic] = self._writer.add_connection(
            topic, msgtype, typestore=self.types, **extra
        )

    def write(self, topic: str, t_ns: int, message: Any, msgtype: str) -> None:
        """Log ``message`` on ``topic`` at ``t_ns``."""
        if t_ns < 0:
            msg = f"cannot record time {t_ns}: ROS times start at 0 (the Unix epoch)"
            raise InvalidInputError(msg)
        self._writer.write(self._conns[topic], t_ns, self._serialize(message, msgtype))


def fit_metadata(bag: Path, version: int, distro: str) -> None:
    """Rewrite ``bag/metadata.yaml`` as ``distro`` writes it: its version, only the fields it
    knows, ``ros_distro`` the distro's name (rosbags writes "rosbags")."""
    import yaml

    path = bag / "metadata.yaml"
    data = yaml.safe_load(path.read_text(encoding="utf-8"))
    info = data["rosbag2_bagfile_information"]
    info["version"] = version
    if version < 8:
        info.pop("ros_distro", None)
    else:
        info["ros_distro"] = distro.lower()
    if version < 6:
        info.pop("custom_data", None)
    if version < 7:
        for topic in info["topics_with_message_count"]:
            topic["topic_metadata"].pop("type_description_hash", None)
    path.write_text(yaml.safe_dump(data, sort_keys=False), encoding="utf-8")
