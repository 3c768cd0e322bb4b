"""The shipped RViz config (``toaster.ros1.RVIZ_CONFIG``) opens with a usable layout and names
only topics toaster publishes: live (``toaster serve --ros1``, its publications as the ROS
master lists them) and recorded (``toaster run --record`` to a ROS 1 ``.bag``, read by Debian's
``rosbag info``, and to an MCAP folder, read by rosbags). Without ROS 1 the live and ``.bag``
tests skip; under CI they fail (``tests/ros1/conftest.py``)."""

from __future__ import annotations

import struct
import subprocess
import xmlrpc.client
from pathlib import Path
from typing import Any

import pytest
import yaml  # type: ignore[import-untyped]
from click.testing import CliRunner

import toaster
from tests.processes import NodeProcess
from tests.ros1.conftest import require_ros
from toaster.cli import cli
from toaster.outputs.markers import AREAS_TOPIC, MARKER_TOPICS
from toaster.ros1 import RVIZ_CONFIG

KITCHEN = Path(toaster.__file__).parent / "examples" / "scenario_spatial_kitchen.yaml"


def _config() -> dict[str, Any]:
    data: dict[str, Any] = yaml.safe_load(RVIZ_CONFIG.read_text())
    return data


def _topics(config: dict[str, Any]) -> set[str]:
    """Every topic the config's displays read: their ``... Topic`` fields, /tf for TF."""
    out: set[str] = set()

    def walk(item: Any) -> None:
        if isinstance(item, dict):
            for key, value in item.items():
                if key.endswith("Topic") and isinstance(value, str):
                    out.add(value)
                walk(value)
        elif isinstance(item, list):
            for value in item:
                walk(value)

    displays = config["Visualization Manager"]["Displays"]
    walk(displays)
    if any(d["Class"] == "rviz/TF" for d in displays):
        out.add("/tf")
    return out


def _docks(state: str) -> tuple[dict[int, tuple[int, list[str]]], int]:
    """A QMainWindow state (Qt 5): the docked areas (0 left, 1 right, 2 top, 3 bottom) with
    their width or height and visible panels, and the central (3D view's) width."""
    data, at = bytes.fromhex(state), 0

    def take(fmt: str) -> Any:
        nonlocal at
        (value,) = struct.unpack_from(fmt, data, at)
        at += struct.calcsize(fmt)
        return value

    assert (take(">i"), take(">i"), take(">B")) == (0xFF, 0, 0xFD)
    areas = {}
    for _ in range(take(">i")):
        area, width, height = take(">i"), take(">i"), take(">i")
        assert take(">B") == 0xFC  # a sequence of panels, none tabbed
        take(">B")
        shown = []
        for _ in range(take(">i")):
            assert take(">B") == 0xFB
            name = data[at + 4 : at + 4 + take(">i")].decode("utf-16-be")
            at += len(name) * 2
            if take(">B") == 1:  # visible, docked
                shown.append(name)
            at += 16
        areas[area] = (width if area < 2 else height, shown)
    return areas, take(">i")


def test_config_layout_and_marker_topics() -> None:
    """The 3D view takes most of the window (the Displays panel left, Time below); a display
    for each marker topic, TF, fixed frame map, the view over the shipped scenes."""
    config = _config()
    manager = config["Visualization Manager"]
    marker_topics = {
        d["Marker Topic"] for d in manager["Displays"] if d["Class"] == "rviz/MarkerArray"
    }
    assert marker_topics == set(MARKER_TOPICS)
    assert _topics(config) == {*MARKER_TOPICS, "/tf"}
    assert manager["Global Options"]["Fixed Frame"] == "map"
    view = manager["Views"]["Current"]
    assert view["Class"] == "rviz/Orbit" and 5 <= view["Distance"] <= 20
    focus = view["Focal Point"]
    assert 0 <= focus["X"] <= 6 and -2 <= focus["Y"] <= 5  # the shipped scenes
    window = config["Window Geometry"]
    areas, central = _docks(window["QMainWindow State"])
    assert areas == {0: (300, ["Displays"]), 3: (62, ["Time"])}
    assert central > 0.7 * window["Width"]
    assert {p["Name"] for p in config["Panels"]} == {"Displays", "Time"}


@pytest.mark.slow
def test_live_node_publishes_every_topic_of_the_config(
    node: NodeProcess, ros_env: dict[str, str]
) -> None:
    """The ROS master lists each topic the config reads as published by the toaster node."""
    with xmlrpc.client.ServerProxy(ros_env["ROS_MASTER_URI"]) as master:
        code, message, (publishers, _, _) = master.getSystemState("/test_rviz")
    assert code == 1, message
    published = {topic for topic, nodes in publishers if "/toaster" in nodes}
    assert _topics(_config()) <= published, sorted(published)


def _record(tmp_path: Path, name: str) -> Path:
    out = tmp_path / name
    done = CliRunner().invoke(
        cli,
        [
            "--db",
            f"sqlite:///{tmp_path / 'run.db'}",
            "run",
            str(KITCHEN),
            "--until",
            "1s",
            "--record",
            str(out),
        ],
    )
    assert done.exit_code == 0, done.output
    return out


@pytest.mark.slow
def test_ros1_bag_carries_every_topic_of_the_config(tmp_path: Path) -> None:
    """`toaster run --record NAME.bag`: Debian's rosbag lists every topic of the config."""
    require_ros()
    bag = _record(tmp_path, "kitchen.bag")
    info = subprocess.run(
        ["/usr/bin/rosbag", "info", "--yaml", "--key", "topics", str(bag)],
        capture_output=True,
        text=True,
        check=False,
    )
    assert info.returncode == 0, info.stderr
    topics = {item["topic"]: item for item in yaml.safe_load(info.stdout)}
    assert _topics(_config()) <= set(topics), sorted(topics)
    assert all(topics[t]["messages"] > 0 for t in _topics(_config()))
    from rosbags.rosbag1 import Reader

    with Reader(bag) as reader:  # the areas are latched: a late RViz still draws them
        latched = {c.topic for c in reader.connections if c.ext.latching == 1}
    assert latched == {AREAS_TOPIC, "/area_manager/areaList"}


@pytest.mark.slow
def test_mcap_recording_carries_every_topic_of_the_config(tmp_path: Path) -> None:
    """`toaster run --record DIR` (rosbag2 / MCAP): the same topics, for RViz 2 and Foxglove."""
    from rosbags.rosbag2 import Reader

    with Reader(_record(tmp_path, "kitchen")) as reader:
        counts = {c.topic: c.msgcount for c in reader.connections}
    assert _topics(_config()) <= set(counts), sorted(counts)
    assert all(counts[t] > 0 for t in _topics(_config()))
