"""``toaster run SCENARIO --ros2`` against the ROS 2 peer (tests/ros2/peer.py: cyclonedds and
rosbags, no toaster): the run's fact lists published live as ``toaster serve --ros2`` publishes
them, /clock at the run's own stamps, and SIGTERM stopping the run between two ticks."""

from __future__ import annotations

import os
import signal
import subprocess
import sys
from collections.abc import Iterator
from pathlib import Path
from typing import Any

import pytest

import toaster
from tests.processes import TIMEOUT, wait_for
from tests.ros2.conftest import Peer
from tests.ros2.test_bridge import FACT_LIST
from toaster import queries as q

pytestmark = pytest.mark.slow
SCENARIO = Path(toaster.__file__).parent / "examples" / "scenario_spatial_sally_anne.yaml"
TICKS = 76  # 15 s at 5 Hz, both ends


class RunProcess:
    """``toaster run SCENARIO --ros2 ARGS`` in a process of its own (stdout and stderr kept)."""

    def __init__(self, env: dict[str, str], tmp: Path, args: list[str]) -> None:
        self.url = f"sqlite:///{tmp / 'run.db'}"
        self.out_path, self.err_path = tmp / "run.out", tmp / "run.err"
        self.out, self.err = self.out_path.open("w"), self.err_path.open("w")
        command = [sys.executable, "-m", "toaster", "--db", self.url, "run", str(SCENARIO)]
        self.proc = subprocess.Popen(
            [*command, "--ros2", *args],
            env=env,
            stdout=self.out,
            stderr=self.err,
            text=True,
            start_new_session=True,
        )

    def stderr(self) -> str:
        self.err.flush()
        return self.err_path.read_text()

    def finish(self, timeout: float = TIMEOUT) -> tuple[int, str, str]:
        """Wait for it to end (killed after ``timeout``): exit code, stdout, stderr."""
        try:
            self.proc.wait(timeout)
        except subprocess.TimeoutExpired:
            os.killpg(self.proc.pid, signal.SIGKILL)
            self.proc.wait(5)
        self.out.close()
        self.err.close()
        return self.proc.returncode, self.out_path.read_text(), self.err_path.read_text()


@pytest.fixture
def run_factory(dds_env: dict[str, str], tmp_path: Path) -> Iterator[Any]:
    runs: list[RunProcess] = []

    def start(args: list[str]) -> RunProcess:
        runs.append(RunProcess(dds_env, tmp_path, args))
        return runs[-1]

    yield start
    for run in runs:
        if run.proc.poll() is None:
            run.finish(0)


def facts_of(answer: dict[str, Any]) -> set[tuple[str, str, str]]:
    return {(f["subject_id"], f["property"], f["target_id"]) for f in answer["msg"]["fact_list"]}


def test_run_publishes_its_fact_lists_and_clock(run_factory: Any, peer: Peer) -> None:
    """With --wait the run ticks once the peer subscribes; the peer reads move3d_facts'
    and pdg's lists (decoded by rosbags) until the marble is in the box, and /clock at the
    scenario's time (0 to 15 s, not the wall clock)."""
    run = run_factory(["--wait"])
    wait_for(lambda: "waiting for a subscriber" in run.stderr(), "the run's waiting line")
    count, seen = 0, set()
    while ("MARBLE", "IsIn", "BOX") not in seen:
        answer = peer.send("latest", topic="/move3d_facts/factList", type=FACT_LIST, after=count)
        count, seen = answer["count"], facts_of(answer)
        assert run.proc.poll() is None or ("MARBLE", "IsIn", "BOX") in seen, run.stderr()
    pdg = peer.send("latest", topic="/pdg/factList", type=FACT_LIST)
    assert ("SALLY", "isPresent", "") in facts_of(pdg)
    clock = peer.send("latest", topic="/clock", type="rosgraph_msgs/msg/Clock")["msg"]["clock"]
    assert 0 <= clock["sec"] <= 15
    code, out, err = run.finish()
    assert code == 0, err
    assert f"{TICKS} ticks over 15.0 s of input" in out, out
    assert "Traceback" not in err and "failed" not in err, err


def test_sigterm_stops_the_run_between_two_ticks(run_factory: Any, peer: Peer) -> None:
    """SIGTERM once the fact lists flow: the run stops cleanly (exit 0, its summary), and the
    database holds whole ticks, none after the last one it reports."""
    run = run_factory([])
    # a topic of this test only: its first sample is this run's
    peer.send("latest", topic="/agent_monitor/factList", type=FACT_LIST, after=0)
    os.killpg(run.proc.pid, signal.SIGTERM)
    code, out, err = run.finish()
    assert code == 0, err
    assert "Traceback" not in err, err
    ticks = int(out.split(" ticks over ")[0].rsplit(" ", 1)[1])
    assert 0 < ticks <= TICKS
    assert ticks == TICKS or f"stopped after {ticks} of {TICKS} ticks" in out, out
    db = toaster.connect(run.url)
    try:
        last_tick_ns = (ticks - 1) * 200_000_000
        assert all(e.stamp_ns <= last_tick_ns for e in q.events(db))
        assert q.current_facts(db)
    finally:
        db.close()
