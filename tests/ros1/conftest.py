"""Fixtures of the ROS 1 bridge tests: a real roscore on a free port, the toaster node in a
process of its own (``toaster serve --ros1``) and a rospy client under Debian's Python
(``client.py``), all on 127.0.0.1 with ROS_HOME in a temporary folder.

Without roscore or rospy the tests skip with the reason; under CI (``CI`` set) they fail.
"""

from __future__ import annotations

import os
import subprocess
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import toaster
from tests.processes import TIMEOUT, LineClient, NodeProcess
from toaster.ros1 import RosUnavailableError
from toaster.ros1.core import RosCore, stop_group

HERE = Path(__file__).resolve().parent
ROSCORE = "/usr/bin/roscore"
SYSTEM_PYTHON = "/usr/bin/python3"


def ros_unavailable() -> str | None:
    """None when roscore and rospy are there, else what is missing."""
    if not Path(ROSCORE).exists():
        return f"{ROSCORE} is missing"
    if not Path(SYSTEM_PYTHON).exists():
        return f"{SYSTEM_PYTHON} is missing"
    probe = subprocess.run(
        [
            SYSTEM_PYTHON,
            "-c",
            "import rospy, genpy, tf2_msgs.msg, visualization_msgs.msg, geometry_msgs.msg",
        ],
        capture_output=True,
        text=True,
        check=False,
    )
    if probe.returncode != 0:
        lines = probe.stderr.strip().splitlines()
        return f"rospy is not importable ({lines[-1] if lines else 'unknown error'})"
    return None


def require_ros() -> None:
    """Skip (or fail under CI) when ROS 1 is not installed."""
    reason = ros_unavailable()
    if reason is None:
        return
    message = (
        f"ROS 1 is not installed: {reason} (apt-get install --no-install-recommends "
        "ros-core python3-rospy python3-tf2-msgs python3-visualization-msgs ...)"
    )
    if os.environ.get("CI"):
        pytest.fail(message + "; CI must install it (.ci/run)")
    pytest.skip(message)


stop = stop_group


@pytest.fixture(scope="session")
def ros_env(tmp_path_factory: pytest.TempPathFactory) -> Iterator[dict[str, str]]:
    """A running roscore; the environment that points processes at it."""
    require_ros()
    home = tmp_path_factory.mktemp("ros_home")
    try:
        with RosCore(home) as env:
            yield env
    except RosUnavailableError as exc:
        pytest.fail(str(exc))


@pytest.fixture(scope="module")
def node_args() -> list[str]:
    """The options of the module's node after ``serve --ros1`` (a module overrides it)."""
    return []


@pytest.fixture(scope="module")
def node(
    ros_env: dict[str, str], node_args: list[str], tmp_path_factory: pytest.TempPathFactory
) -> Iterator[NodeProcess]:
    """The module's ``toaster serve --ros1`` on a SQLite file in a folder of its own (its log
    there too), stopped at the end; it must have stopped cleanly, with no traceback."""
    tmp = tmp_path_factory.mktemp("ros1_node")
    url = f"sqlite:///{tmp / 'toaster.db'}"
    proc = NodeProcess(ros_env, url, "--ros1", node_args, tmp / "node.log")
    yield proc
    out = proc.close()
    assert "stopped after" in out, out[-2000:]
    assert "Traceback" not in out, out[-3000:]


@pytest.fixture(scope="module")
def db(node: NodeProcess) -> Iterator[toaster.Database]:
    """The module's node's database, read by the tests."""
    database = toaster.connect(node.url)
    yield database
    database.close()


class RosClient(LineClient):
    """The rospy client process: call services, publish, read topics."""

    def __init__(self, env: dict[str, str]) -> None:
        super().__init__([SYSTEM_PYTHON, str(HERE / "client.py")], env, "ROS client")

    def call(self, service: str, srv_type: str, **request: Any) -> dict[str, Any]:
        """The response fields; fails the test when the service answered an error."""
        answer = self.send("call", service=service, type=srv_type, request=request)
        assert answer["ok"], answer
        return answer["response"]

    def call_raw(self, service: str, srv_type: str, **request: Any) -> dict[str, Any]:
        return self.send("call", service=service, type=srv_type, request=request)

    def publish(
        self,
        topic: str,
        msg_type: str,
        msg: dict[str, Any],
        *,
        rate: float = 0.0,
        key: str | None = None,
    ) -> None:
        answer = self.send(
            "publish", topic=topic, type=msg_type, msg=msg, rate=rate, key=key or topic
        )
        assert answer["ok"], answer

    def stop(self, key: str) -> None:
        self.send("stop", key=key)

    def subscribe(self, topic: str, msg_type: str, *, connected: bool = False) -> None:
        """Subscribe; ``connected``: return once a publisher is connected (what it sends
        next is received)."""
        answer = self.send(
            "subscribe", topic=topic, type=msg_type, connected=TIMEOUT if connected else 0
        )
        assert answer["ok"], answer

    def latest(self, topic: str, *, after: int = 0) -> dict[str, Any]:
        """The newest message on ``topic`` once more than ``after`` came (waits TIMEOUT)."""
        answer = self.send("latest", topic=topic, after=after, timeout=TIMEOUT)
        assert answer["ok"], answer
        return answer


@pytest.fixture(scope="module")
def client(ros_env: dict[str, str]) -> Iterator[RosClient]:
    """A rospy client connected to the test roscore."""
    ros = RosClient(ros_env)
    try:
        yield ros
    finally:
        ros.close()
