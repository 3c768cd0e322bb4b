"""``toaster beliefs``: replay a scenario, then ask who believes what."""

from __future__ import annotations

import json
from importlib import resources

import pytest
from click.testing import CliRunner

from toaster.cli import cli

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)


@pytest.fixture
def sally_anne(db_url: str):
    """The shipped Sally-Anne scenario replayed with its expectations checked."""
    runner = CliRunner()
    path = resources.files("toaster") / "examples" / "beliefs_sally_anne.yaml"

    def invoke(*args: str):
        return runner.invoke(cli, ["--db", db_url, *args])

    result = invoke("beliefs", "replay", str(path), "--check")
    assert result.exit_code == 0, result.output
    return invoke


def test_false_belief_while_sally_is_away(sally_anne) -> None:
    """At 4 s Sally (away) still thinks the marble is in the basket; the robot knows the box."""
    diff = sally_anne("beliefs", "diff", "SALLY", "--at", "4s", "--json")
    rows = [json.loads(line) for line in diff.output.splitlines()]
    marble = [r for r in rows if r["subject_id"] == "MARBLE" and r["property"] == "IsIn"]
    assert {(r["target_id"], r["value_a"], r["value_b"]) for r in marble} == {
        ("BASKET", "true", None),
        ("BOX", None, "true"),
    }
    second = sally_anne(
        "beliefs",
        "value",
        "ANNE",
        "--about",
        "SALLY",
        "--subject",
        "MARBLE",
        "--property",
        "IsIn",
        "--target",
        "BASKET",
        "--at",
        "4s",
        "--json",
    )
    assert json.loads(second.output)["agent_id"] == "ANNE>SALLY"


def test_holders_history_and_config(sally_anne) -> None:
    """Nested holders are listed; the history spans holders; settings round-trip."""
    assert sally_anne("beliefs", "holders").output.split() == [  # piped: under a header
        "holder",
        "ANNE",
        "SALLY",
        "ANNE>SALLY",
        "SALLY>ANNE",
    ]
    history = sally_anne(
        "beliefs", "history", "--subject", "MARBLE", "--property", "IsIn", "--json"
    ).output.splitlines()
    assert {json.loads(x)["agent_id"] for x in history} >= {"ROBOT", "SALLY", "ANNE"}
    assert sally_anne("beliefs", "config", "depth", "1").exit_code == 0
    assert sally_anne("beliefs", "config", "depth").output.strip() == "1"
    bad = sally_anne("beliefs", "config", "depth", "99")
    assert bad.exit_code == 1
    assert "depth" in bad.output
    assert "Traceback" not in bad.output


def test_with_several_robots_commands_say_how_to_name_one(sally_anne) -> None:
    """A second robot in the database: `beliefs diff` without naming one stops with one line
    listing both, and names the option; naming it works."""
    added = sally_anne("set-info", "ENTITY", "--id", "R2", "--type", "robot", "--self")
    assert added.exit_code == 0, added.output
    diff = sally_anne("beliefs", "diff", "SALLY", "--at", "4s")
    assert diff.exit_code == 1
    assert "('R2', 'ROBOT')" in diff.output and "--other ID" in diff.output
    assert len(diff.output.strip().splitlines()) == 1
    named = sally_anne("beliefs", "diff", "SALLY", "--at", "4s", "--other", "ROBOT", "--json")
    assert named.exit_code == 0 and "BASKET" in named.output


def test_diff_names_the_two_agents_in_its_header(sally_anne) -> None:
    """The columns of `beliefs diff` name whose value each is (they read value_a / value_b,
    leaving the reader to guess which agent is a); JSON lines name them in agent_a/agent_b."""
    piped = sally_anne("beliefs", "diff", "SALLY", "--at", "4s").output.splitlines()
    header = piped[0].split("\t")
    assert header[4:] == [
        "value (SALLY)",
        "confidence (SALLY)",
        "value (ROBOT)",
        "confidence (ROBOT)",
    ]
    assert any(line.split("\t")[:3] == ["MARBLE", "IsIn", "BASKET"] for line in piped[1:])
    nested = sally_anne(
        "beliefs", "diff", "ANNE", "--about", "SALLY", "--at", "4s", "--other", "SALLY"
    )
    assert "value (ANNE>SALLY)" in nested.output.splitlines()[0]
    rows = [
        json.loads(x)
        for x in sally_anne("beliefs", "diff", "SALLY", "--at", "4s", "--json").output.splitlines()
    ]
    assert {(r["agent_a"], r["agent_b"]) for r in rows} == {("SALLY", "ROBOT")}
    csv = sally_anne("beliefs", "diff", "SALLY", "--at", "4s", "--csv").output.splitlines()
    assert csv[0].startswith("agent_a,agent_b,subject_id")
