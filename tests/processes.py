"""Processes the bridge tests start: ``toaster serve`` as users run it, and a client process
(rospy, cyclonedds) driven over JSON lines on its stdin/stdout. Conditions are waited for with
a generous time-out, never a wall-clock window."""

from __future__ import annotations

import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from pathlib import Path
from typing import Any

import pytest

TIMEOUT = 60.0  # generous: conditions are waited for, never a wall-clock window


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


class NodeProcess:
    """``toaster --db URL serve BRIDGE ARGS`` as users run it, started once its bridge is up
    (its stderr kept in ``log`` for the warning lines; files it writes land beside it)."""

    def __init__(
        self, env: dict[str, str], url: str, bridge: str, args: list[str], log: Path
    ) -> None:
        self.url, self.log = url, log
        self.err = log.open("w")
        self.proc = subprocess.Popen(
            [sys.executable, "-m", "toaster", "--db", url, "serve", bridge, *args],
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

    def alive(self) -> bool:
        return self.proc.poll() is None

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


class LineClient:
    """A client process answering one JSON line for each JSON line sent; its first line says
    it is ready. ``name`` says which in a failure."""

    def __init__(self, argv: list[str], env: dict[str, str], name: str) -> None:
        self.name = name
        self.proc = subprocess.Popen(
            argv,
            env=env,
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
            pytest.fail(f"the {self.name} died: {err[-2000:]}")
        answer: dict[str, Any] = json.loads(line)
        return answer

    def send(self, op: str, **fields: Any) -> dict[str, Any]:
        assert self.proc.stdin is not None
        self.proc.stdin.write(json.dumps({"op": op, **fields}) + "\n")
        self.proc.stdin.flush()
        return self._read()

    def close(self) -> None:
        """Ask it to quit and end its input (killed if it has not stopped within 10 s)."""
        if self.proc.poll() is None:
            try:
                assert self.proc.stdin is not None
                self.proc.stdin.write(json.dumps({"op": "quit"}) + "\n")
                self.proc.stdin.close()
                self.proc.wait(10)
            except (OSError, subprocess.TimeoutExpired):
                os.killpg(self.proc.pid, signal.SIGKILL)
                self.proc.wait(5)
        for pipe in (self.proc.stdin, self.proc.stdout, self.proc.stderr):
            if pipe is not None:
                pipe.close()
