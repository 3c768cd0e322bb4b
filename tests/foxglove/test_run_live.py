"""``toaster run SCENARIO --foxglove 0 --wait`` against the independent client of
tests/foxglove/client.py (a separate process, no toaster or foxglove-sdk code): the run's
ticks published live as ``toaster serve`` publishes them, on the run's own clock."""

from __future__ import annotations

import json
import subprocess
import sys
from typing import Any

import pytest

from tests.foxglove.test_foxglove import CHANNELS, CLIENT, EXAMPLES, TOASTER

pytest.importorskip("foxglove")
pytest.importorskip("websockets")
pytest.importorskip("google.protobuf")
pytest.importorskip("jsonschema")

pytestmark = pytest.mark.slow  # processes, seconds each


@pytest.fixture(scope="module")
def followed(tmp_path_factory: pytest.TempPathFactory) -> dict[str, Any]:
    """The spatial Sally-Anne run live (it waits for the client, then ticks at the scenario's
    speed); what the client saw until the run ended and the server closed."""
    db = f"sqlite:///{tmp_path_factory.mktemp('runfox') / 'run.db'}"
    scenario = str(EXAMPLES / "scenario_spatial_sally_anne.yaml")
    run = subprocess.Popen(
        [*TOASTER, "--db", db, "run", scenario, "--foxglove", "0", "--wait"],
        stdout=subprocess.PIPE,
        stderr=subprocess.PIPE,
        text=True,
    )
    assert run.stderr is not None
    port = None
    for line in run.stderr:  # the first lines come at once; a dead run ends the loop
        if "Foxglove on ws://127.0.0.1:" in line:
            port = int(line.rsplit(":", 1)[1])
            break
    try:
        assert port is not None, "no port printed"
        done = subprocess.run(
            [sys.executable, str(CLIENT), f"ws://127.0.0.1:{port}", "follow", "300"],
            capture_output=True,
            text=True,
            timeout=400,
        )
        assert done.returncode == 0, done.stderr
        out, err = run.communicate(timeout=120)
    finally:
        if run.poll() is None:
            run.kill()
            run.communicate()
    assert run.returncode == 0, err
    assert "Traceback" not in err and "failed" not in err, err
    assert "76 ticks over 15.0 s of input" in out, out
    return json.loads(done.stdout)


def test_run_publishes_every_channel_without_services(followed: dict[str, Any]) -> None:
    advertised = {topic: name for topic, _, name, _, _ in followed["channels"]}
    assert advertised == CHANNELS
    assert set(followed["counts"]) >= set(CHANNELS) - {"/toaster/log", "/toaster/events"}
    assert followed["services"] == []  # a run's input is its file: nothing to change
    assert followed["closed"]  # the run ended, the server closed


def test_run_clock_is_the_scenarios(followed: dict[str, Any]) -> None:
    """The server's time capability carries the run's stamps: 0 s to 15 s, in order."""
    assert "time" in followed["capabilities"]
    times = followed["times"]
    assert times == sorted(times) and times[-1] == 15_000_000_000
    facts = followed["last"]["/toaster/facts"]["timestamp"]
    assert facts["sec"] <= 15


def test_sally_false_belief_seen_during_the_run(followed: dict[str, Any]) -> None:
    """Sally put the marble in the basket and left; Anne moved it to the box: Sally's belief
    that it is in the basket is marked false, the robot holding none for the basket."""
    false = [
        (f["subject"], f["property"], f["target"], f["self_value"])
        for m in followed["beliefs"]
        if m["holder"] == "SALLY"
        for f in m["facts"]
        if f["false_belief"]
    ]
    assert ("MARBLE", "IsIn", "BASKET", None) in false
