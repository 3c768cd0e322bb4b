"""Fixtures of the ROS 2 bridge tests: ``toaster serve --ros2`` in a process of its own on a
SQLite file, and a ROS 2 peer process (``peer.py``: cyclonedds and rosbags, no toaster), both
on a random ROS_DOMAIN_ID with DDS on the loopback interface only (unicast discovery: a
container may have no multicast), so that tests running at once never see each other.

Without cyclonedds (``toaster[ros2]``) the tests skip; under CI (``CI`` set) they fail.
"""

from __future__ import annotations

import json
import os
import random
import signal
import subprocess
import sys
import time
from collections.abc import Callable, Iterator
from pathlib import Path
from typing import Any

import pytest

import toaster

HERE = Path(__file__).resolve().parent
TIMEOUT = 60.0  # generous: conditions are waited for, never a wall-clock window
LOOPBACK = """<CycloneDDS><Domain Id="any"><General>
<Interfaces><NetworkInterface address="127.0.0.1"/></Interfaces>
<AllowMulticast>false</AllowMulticast></General>
<Discovery><ParticipantIndex>auto</ParticipantIndex>
<MaxAutoParticipantIndex>40</MaxAutoParticipantIndex>
<Peers><Peer address="127.0.0.1"/></Peers></Discovery></Domain></CycloneDDS>
"""


def wait_for(what: Callable[[], Any], message: str = "", timeout: float = TIMEOUT) -> Any:
    """``what()`` once it is true, asked every 50 ms; fails the test after ``timeout``."""
    deadline = time.monotonic() + timeout
    while True:
        value = what()
        if value:
            return value
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout:g} s waiting for {message or what}")
        time.sleep(0.05)


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


class NodeProcess:
    """``toaster serve --ros2`` as users run it (its stderr kept for the warning lines)."""

    def __init__(self, env: dict[str, str], url: str, args: list[str], log: Path) -> None:
        self.url, self.log = url, log
        self.err = log.open("w")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "toaster", "--db", url, "serve", "--ros2", *args],
            cwd=log.parent,
            env=env,
            stdout=subprocess.DEVNULL,
            stderr=self.err,
            text=True,
            start_new_session=True,
        )
        deadline = time.monotonic() + TIMEOUT
        while "(Ctrl-C stops)" not in self.stderr():  # printed once the bridge is up
            if self.proc.poll() is not None or time.monotonic() > deadline:
                self.close()
                pytest.fail(f"the toaster node did not start: {self.stderr()[-2000:]}")
            time.sleep(0.05)

    def stderr(self) -> str:
        self.err.flush()
        return self.log.read_text()

    def close(self) -> str:
        """Stop it (SIGTERM, as a service manager would); its closing summary (stderr)."""
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGTERM)
            try:
                self.proc.wait(20)
            except subprocess.TimeoutExpired:
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(5)
        self.err.close()
        return self.log.read_text()


class Peer:
    """The ROS 2 peer process (``peer.py``): publish, read topics, call services."""

    def __init__(self, env: dict[str, str]) -> None:
        peer_env = dict(env)
        peer_env.pop("PYTHONPATH", None)  # no toaster in the peer
        self.proc = subprocess.Popen(
            [sys.executable, str(HERE / "peer.py"), env["ROS_DOMAIN_ID"]],
            env=peer_env,
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
            start_new_session=True,
        )
        first = self._read()
        assert first.get("ready"), first

    def _read(self) -> dict[str, Any]:
        assert self.proc.stdout is not None
        line = self.proc.stdout.readline()
        if not line:
            err = self.proc.stderr.read() if self.proc.stderr else ""
            pytest.fail(f"the ROS 2 peer died: {err[-2000:]}")
        return json.loads(line)

    def send(self, op: str, **fields: Any) -> dict[str, Any]:
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps({"op": op, **fields}) + "\n")
        self.proc.stdin.flush()
        answer = self._read()
        assert "error" not in answer, answer
        return answer

    def close(self) -> None:
        if self.proc.poll() is None:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(5)
        for stream in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
            if stream is not None:
                stream.close()


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
    proc = NodeProcess(dds_env, f"sqlite:///{tmp / 'toaster.db'}", node_args, tmp / "node.log")
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
