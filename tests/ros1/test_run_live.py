"""``toaster run SCENARIO --ros1 --wait`` against the rospy client of tests/ros1/client.py (Debian's
Python, a process of its own) on a real roscore: the run's fact lists published live as
``toaster serve --ros1`` publishes them, and /clock at the run's own stamps."""

from __future__ import annotations

import subprocess
import sys
from pathlib import Path

import pytest

import toaster
from tests.processes import TIMEOUT, wait_for
from tests.ros1.conftest import RosClient

pytestmark = pytest.mark.slow
SCENARIO = Path(toaster.__file__).parent / "examples" / "scenario_spatial_sally_anne.yaml"


def test_run_publishes_its_fact_lists_and_clock(
    ros_env: dict[str, str], client: RosClient, tmp_path: Path
) -> None:
    """The run waits for the client's subscription, then ticks at the scenario's speed; the
    client reads move3d_facts' list until the marble is in the box, and /clock at the
    scenario's time (0 to 15 s); the run ends by itself, cleanly."""
    err_path = tmp_path / "run.err"
    with err_path.open("w") as err:
        run = subprocess.Popen(
            [
                *(sys.executable, "-m", "toaster", "--db", f"sqlite:///{tmp_path / 'r.db'}"),
                *("run", str(SCENARIO), "--ros1", "--wait"),
            ],
            env=ros_env,
            stdout=subprocess.PIPE,
            stderr=err,
            text=True,
            cwd=tmp_path,
        )
        try:
            wait_for(lambda: "waiting for a subscriber" in err_path.read_text(), "the wait line")
            client.subscribe("/clock", "rosgraph_msgs/Clock")
            client.subscribe("/move3d_facts/factList", "FactList", connected=True)
            count, seen = 0, set()
            while ("MARBLE", "IsIn", "BOX") not in seen:
                got = client.latest("/move3d_facts/factList", after=count)
                count = got["count"]
                seen = {
                    (f["subjectId"], f["property"], f["targetId"]) for f in got["msg"]["factList"]
                }
            clock = client.latest("/clock")["msg"]["clock"]
            assert 0 <= clock["secs"] <= 15, clock
            out, _ = run.communicate(timeout=TIMEOUT)
        finally:
            if run.poll() is None:
                run.kill()
                run.communicate()
    log = err_path.read_text()
    assert run.returncode == 0, log
    assert "76 ticks over 15.0 s of input" in out, out
    assert "Traceback" not in log, log
