"""A roscore of one's own on a free port of 127.0.0.1 (tests, benchmarks, demos)."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import time
import xmlrpc.client
from pathlib import Path
from typing import Any

from toaster.ros1.available import INSTALL_HINT, RosUnavailableError

ROSCORE = "/usr/bin/roscore"


def free_port() -> int:
    """A TCP port nobody listens on now."""
    with socket.socket() as sock:
        sock.bind(("127.0.0.1", 0))
        return int(sock.getsockname()[1])


def stop_group(proc: subprocess.Popen[Any], timeout: float = 10.0) -> None:
    """SIGINT to a process group (roscore has children), then SIGKILL if it lingers."""
    if proc.poll() is not None:
        return
    os.killpg(proc.pid, signal.SIGINT)
    try:
        proc.wait(timeout)
    except subprocess.TimeoutExpired:
        os.killpg(proc.pid, signal.SIGKILL)
        proc.wait(5)


class RosCore:
    """``with RosCore(home) as env:`` runs roscore; ``env`` points processes at it."""

    def __init__(self, home: str | Path, port: int | None = None) -> None:
        if not Path(ROSCORE).exists():
            raise RosUnavailableError(INSTALL_HINT)
        self.port = port or free_port()
        home = Path(home)
        env = {k: v for k, v in os.environ.items() if not k.startswith("ROS")}
        self.env = env | {
            "ROS_MASTER_URI": f"http://127.0.0.1:{self.port}",
            "ROS_HOME": str(home),
            "ROS_LOG_DIR": str(home / "log"),
            "ROS_HOSTNAME": "127.0.0.1",
            "PYTHONUNBUFFERED": "1",
        }
        self.proc: subprocess.Popen[bytes] | None = None

    def __enter__(self) -> dict[str, str]:
        self.proc = subprocess.Popen(
            [ROSCORE, "-p", str(self.port)],
            env=self.env,
            stdout=subprocess.DEVNULL,
            stderr=subprocess.PIPE,
            start_new_session=True,
        )
        deadline = time.monotonic() + 30
        while True:
            try:
                with xmlrpc.client.ServerProxy(self.env["ROS_MASTER_URI"]) as master:
                    master.getSystemState("/probe")
                return self.env
            except OSError:
                if self.proc.poll() is not None or time.monotonic() > deadline:
                    err = self.proc.stderr.read().decode() if self.proc.stderr else ""
                    self.__exit__()
                    msg = f"roscore did not start on port {self.port}: {err.strip()[-500:]}"
                    raise RosUnavailableError(msg) from None
                time.sleep(0.1)

    def __exit__(self, *exc: object) -> None:
        if self.proc is not None:
            stop_group(self.proc)
            if self.proc.stderr is not None:
                self.proc.stderr.close()
            self.proc = None
