"""Fixtures of the ROS 2 bridge tests: ``toaster serve --ros2`` in a process of its own on a
SQLite file, and a ROS 2 peer process (``peer.py``: cyclonedds and rosbags, no toaster), both
on a random ROS_DOMAIN_ID with DDS on the loopback interface only (unicast discovery: a
container may have no multicast), so that tests running at once never see each other.

Without cyclonedds (``toaster[ros2]``) the tests skip; under CI (``CI`` set) they fail.
"""

from __future__ import annotations

import os
import random
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import toaster
from tests.processes import LineClient, NodeProcess

HERE = Path(__file__).resolve().parent
LOOPBACK = """<CycloneDDS><Domain Id="any"><General>
<Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces>
<AllowMulticast>false</AllowMulticast></General>
<Discovery><ParticipantIndex>auto</ParticipantIndex>
<MaxAutoParticipantIndex>40</MaxAutoParticipantIndex>
<Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>
"""


def require_cyclonedds() -> None:
    try:
        import cyclonedds.domain  # noqa: F401
    except ImportError as exc:
        message = f"cyclonedds is not installed ({exc}): pip install 'toaster[ros2]'"
        if os.environ.get("CI"):
            pytest.fail(message + "; CI installs it with the test extra")
        pytest.skip(message)


@pytest.fixture(scope="module")
def dds_env(tmp_path_factory: pytest.TempPathFactory) -> dict[str, str]:
    """The environment of both processes: a domain of their own, loopback DDS."""
    require_cyclonedds()
    config = tmp_path_factory.mktemp("dds") / "cyclonedds.xml"
    config.write_text(LOOPBACK)
    env = dict(os.environ)
    env["ROS_DOMAIN_ID"] = str(random.randint(1, 230))
    env["CYCLONEDDS_URI"] = config.as_uri()
    src = str(Path(toaster.__file__).resolve().parents[1])
    env["PYTHONPATH"] = os.pathsep.join(p for p in (src, env.get("PYTHONPATH")) if p)
    return env


class Peer(LineClient):
    """The ROS 2 peer process (``peer.py``): publish, read topics, call services."""

    def __init__(self, env: dict[str, str]) -> None:
        peer_env = dict(env)
        peer_env.pop("PYTHONPATH", None)  # no toaster in the peer
        argv = [sys.executable, str(HERE / "peer.py"), env["ROS_DOMAIN_ID"]]
        super().__init__(argv, peer_env, "ROS 2 peer")

    def send(self, op: str, **fields: Any) -> dict[str, Any]:
        """Its answer; fails the test when the peer answered an error."""
        answer = super().send(op, **fields)
        assert "error" not in answer, answer
        return answer


@pytest.fixture(scope="module")
def node_args() -> list[str]:
    """The options of the module's node after ``serve --ros2`` (a module overrides it)."""
    return []


@pytest.fixture(scope="module")
def node(
    dds_env: dict[str, str], node_args: list[str], tmp_path_factory: pytest.TempPathFactory
) -> Iterator[NodeProcess]:
    """The module's ``toaster serve --ros2``, stopped at the end; it must stop cleanly."""
    tmp = tmp_path_factory.mktemp("ros2_node")
    url = f"sqlite:///{tmp / 'toaster.db'}"
    proc = NodeProcess(dds_env, url, "--ros2", node_args, tmp / "node.log")
    yield proc
    out = proc.close()
    assert "stopped after" in out, out[-2000:]
    assert "Traceback" not in out, out[-3000:]


@pytest.fixture(scope="module")
def peer(dds_env: dict[str, str]) -> Iterator[Peer]:
    proc = Peer(dds_env)
    yield proc
    proc.close()


@pytest.fixture(scope="module")
def db(node: NodeProcess) -> Iterator[toaster.Database]:
    database = toaster.connect(node.url)
    yield database
    database.close()
