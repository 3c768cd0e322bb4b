"""``toaster serve`` as users run it: a process, changed and asked from other processes (the
``toaster`` CLI), stopped with SIGTERM, on both backends."""

from __future__ import annotations

import json
import signal
import subprocess
import sys
import time

import pytest

import toaster
from toaster.queries import current_facts

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

ROOM = json.dumps(
    {"shape": "polygon", "points": [[-1, -1], [6, -1], [6, 2], [-1, 2]], "area_type": "room"}
)


def toaster_cli(url: str, *args: str, ok: bool = True) -> subprocess.CompletedProcess[str]:
    result = subprocess.run(
        [sys.executable, "-m", "toaster", "--db", url, *args],
        capture_output=True,
        text=True,
        timeout=60,
    )
    if ok:
        assert result.returncode == 0, result.stderr
    return result


def wait_for(check, timeout: float = 10.0) -> None:
    deadline = time.monotonic() + timeout
    while not check():
        assert time.monotonic() < deadline, "timed out"
        time.sleep(0.05)


def test_serve_applies_cli_commands_answers_queries_and_stops_on_sigterm(db_url):
    node = subprocess.Popen(
        [sys.executable, "-m", "toaster", "--db", db_url, "serve", "--rate", "30"],
        stderr=subprocess.PIPE,
        text=True,
    )
    try:
        toaster_cli(db_url, "entity", "pose", "cup", "3", "0", "0.8")
        toaster_cli(db_url, "entity", "pose", "bob", "0", "0", "--kind", "human")
        toaster_cli(db_url, "area", "add", "kitchen", "--spec", ROOM)
        with toaster.connect(db_url) as db:

            def in_kitchen() -> bool:
                rows = current_facts(db, "toaster", property="IsInRoom")
                return {(r.subject_id, r.target_id) for r in rows} == {
                    ("bob", "kitchen"),
                    ("cup", "kitchen"),
                }

            wait_for(in_kitchen)
        answer = toaster_cli(db_url, "relative-position", "bob", "cup", "--timeout", "10")
        assert json.loads(answer.stdout)["angle"] == pytest.approx(0.0, abs=1e-6)
        bad = toaster_cli(db_url, "relative-position", "bob", "ghost", "--timeout", "10", ok=False)
        assert bad.returncode == 1
        assert "unknown entity 'ghost'" in bad.stderr
        assert "Traceback" not in bad.stderr
        toaster_cli(db_url, "monitor", "clear")
        assert "(nobody)" in toaster_cli(db_url, "monitor", "list").stdout
        assert node.poll() is None  # still running after a bad query
    finally:
        node.send_signal(signal.SIGTERM)
        _, err = node.communicate(timeout=20)
    assert node.returncode == 0, err
    assert "stopped after" in err
    assert "Traceback" not in err


def test_queries_without_a_node_and_bad_options_are_one_line_errors(db_url):
    result = toaster_cli(db_url, "pointing", "bob", "--timeout", "0.2", ok=False)
    assert result.returncode == 1
    assert "no node answered pointing" in result.stderr
    result = toaster_cli(db_url, "serve", "--rate", "0", ok=False)
    assert "--rate 0.0 must be a positive number" in result.stderr
    result = toaster_cli(db_url, "serve", "--pose-topic", "/x=bob", ok=False)
    assert "add --ros1" in result.stderr
    result = toaster_cli(db_url, "entity", "pose", "bob", "1", ok=False)
    assert "give X Y or X Y Z" in result.stderr


def test_serve_reuses_the_databases_self_agent(db_url):
    """A database whose self agent is PR2: `serve` without --self runs as PR2 (it added a
    second self agent, "toaster", and every command defaulting to the self agent then
    stopped with "not exactly one self agent"); another --self is refused in one line."""
    toaster_cli(db_url, "set-info", "ENTITY", "--id", "PR2", "--type", "robot", "--self")
    toaster_cli(db_url, "serve", "--seconds", "0.3")
    with toaster.connect(db_url) as db:
        assert {a: s for a, s in db.store().agents().items() if s} == {"PR2": True}
    for entity in ("cup", "t"):
        toaster_cli(db_url, "set-info", "ENTITY", "--id", entity, "--type", "object")
    toaster_cli(
        db_url, "set-info", "FACT", "--subject", "cup", "--property", "IsOn", "--target", "t"
    )
    assert "cup" in toaster_cli(db_url, "get-info", "FACT", "CURRENT").stdout
    bad = toaster_cli(db_url, "serve", "--seconds", "0.3", "--self", "R2", ok=False)
    assert bad.returncode == 1 and "Traceback" not in bad.stderr
    assert "the database's self agent is PR2" in bad.stderr
    toaster_cli(db_url, "serve", "--seconds", "0.3", "--self", "PR2")
