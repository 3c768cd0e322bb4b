"""``toaster serve --ros1 --foxglove 0``: a pose published on ROS 1 reaches the independent
Foxglove client (tests/foxglove/client.py, a process of its own) as a scene entity, a frame
and facts, while the ROS bridge runs."""

from __future__ import annotations

import json
import re
import subprocess
import sys
from pathlib import Path

import pytest

from tests.processes import NodeProcess, wait_for
from tests.ros1.conftest import RosClient
from tests.ros1.test_bridge import pose_msg

pytest.importorskip("foxglove")
pytest.importorskip("websockets")
pytest.importorskip("google.protobuf")
pytest.importorskip("jsonschema")

CLIENT = Path(__file__).resolve().parents[1] / "foxglove" / "client.py"


@pytest.fixture(scope="module")
def node_args() -> list[str]:
    return ["--foxglove", "0", "--pose-topic", "/mocap/bob=bob:human"]


@pytest.mark.slow
def test_a_ros_pose_reaches_the_foxglove_client(node: NodeProcess, client: RosClient) -> None:
    port = wait_for(
        lambda: re.search(r"Foxglove on ws://127.0.0.1:(\d+)", node.stderr()), "the port"
    )[1]
    client.publish("/mocap/bob", "geometry_msgs/PoseStamped", pose_msg(1.0, 2.0), rate=20)

    def seen() -> dict | None:
        done = subprocess.run(
            [sys.executable, str(CLIENT), f"ws://127.0.0.1:{port}", "listen", "2"],
            capture_output=True,
            text=True,
            timeout=120,
        )
        assert done.returncode == 0, done.stderr
        out = json.loads(done.stdout)
        scene = out["last"].get("/toaster/scene", {}).get("entities", [])
        return out if any(e["id"] == "bob" for e in scene) else None

    out = wait_for(seen, "bob in the Foxglove scene")
    frames = {t["childFrameId"]: t for t in out["last"]["/tf"]["transforms"]}
    assert frames["bob/base"]["translation"] == {"x": 1.0, "y": 2.0}  # protobuf omits z = 0
    facts = out["last"]["/toaster/facts"]
    assert facts["agent"] == "toaster"
    client.stop("/mocap/bob")
