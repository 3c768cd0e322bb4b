"""Times on the command line read like the data: ``--at 12.5s`` is 12.5 s after the data's
start, ``--at -5m`` five minutes ago; tables show ``+12.500 s`` for simulated data and dates
for real data, ``--time elapsed|date`` (or ``$TOASTER_TIME``) either way; JSON keeps ns."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import pytest
from click.testing import CliRunner

import toaster
from tests.test_timeutil import REAL, S, scenario
from toaster.cli import cli
from toaster.timeutil import now_ns

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)


@pytest.fixture
def run(db_url: str) -> Any:
    """Invoke ``toaster --db URL ...`` and return the result (exit 0 unless ``ok=False``)."""
    runner = CliRunner()

    def invoke(*args: str, ok: bool = True, env: dict[str, str] | None = None) -> Any:
        result = runner.invoke(cli, ["--db", db_url, *args], env=env)
        if ok:
            assert result.exit_code == 0, result.output
        return result

    return invoke


def rows(result: Any) -> list[dict[str, Any]]:
    return [json.loads(line) for line in result.output.splitlines() if line.strip()]


def bob_at(run: Any, at: str) -> list[dict[str, Any]]:
    """What the robot believed about bob at ``at`` (JSON rows)."""
    return rows(run("get-info", "FACT", "CURRENT", "--subject", "bob", "--at", at, "--json"))


def test_at_counts_from_a_scenarios_start(run: Any, db_url: str, tmp_path: Path) -> None:
    """bob enters at 12 s: 12.5 s after the start he is in the room, 11.5 s after he is
    not; the run recorded its start (0)."""
    run("run", str(scenario(tmp_path, start=None, enter="12s", duration="14s")))
    with toaster.connect(db_url) as db:
        assert db.time_frame().start_ns == 0
    facts = bob_at(run, "12.5s")
    assert {f["property"] for f in facts} >= {"isPresent", "IsInRoom"}
    assert {f["valid_from_ns"] for f in facts} == {12 * S}  # JSON: ns
    assert bob_at(run, "11.5s") == []


def test_at_on_real_data_counts_from_its_start(run: Any, db_url: str, tmp_path: Path) -> None:
    """Data recorded on 2026-11-22 from 12:00: ``--at 60s`` is 12:01:00, not 60 s after 1970
    (which found nothing before)."""
    run("run", str(scenario(tmp_path, start="2026-11-22T12:00:00Z", enter="60s", duration="62s")))
    facts = bob_at(run, "60s")
    assert {f["valid_from_ns"] for f in facts} == {REAL + 60 * S}
    assert bob_at(run, "59s") == []
    assert bob_at(run, "2026-11-22T12:01:00Z") == facts  # ISO as before
    assert bob_at(run, str(REAL + 60 * S)) == facts  # and ns


def test_tables_show_elapsed_for_simulated_data(run: Any, tmp_path: Path) -> None:
    run("run", str(scenario(tmp_path, start=None, enter="12.5s", duration="13s")))
    table = run("get-info", "EVENT", "--subject", "bob").output
    assert "+12.500 s" in table and "1970" not in table
    dated = run("--time", "date", "get-info", "EVENT", "--subject", "bob").output
    assert "1970-01-01 00:00:12.500Z" in dated and "+12.500 s" not in dated
    env = run("get-info", "EVENT", "--subject", "bob", env={"TOASTER_TIME": "date"}).output
    assert "1970-01-01 00:00:12.500Z" in env


def test_tables_show_dates_for_real_data(run: Any, tmp_path: Path) -> None:
    run("run", str(scenario(tmp_path, start="2026-11-22T12:00:00Z", enter="60s", duration="61s")))
    table = run("get-info", "FACT", "ALL", "--subject", "bob").output
    assert "2026-11-22 12:01:00Z" in table and "+60.000 s" not in table
    elapsed = run("--time", "elapsed", "get-info", "FACT", "ALL", "--subject", "bob").output
    assert "+60.000 s" in elapsed and "2026" not in elapsed
    events = rows(run("get-info", "EVENT", "--subject", "bob", "--json"))
    assert {e["stamp_ns"] for e in events} == {REAL + 60 * S}  # scripts keep ns


def test_a_negative_duration_is_before_now(run: Any) -> None:
    """A fact set 10 minutes ago is held 5 minutes ago; one set a minute ago is not yet."""
    run("set-info", "ENTITY", "--id", "PR2", "--type", "robot", "--self")
    for name in ("MUG", "TABLE", "SHELF"):
        run("set-info", "ENTITY", "--id", name, "--type", "object")
    before = now_ns()
    run(
        "set-info",
        "FACT",
        "--subject",
        "MUG",
        "--property",
        "IsOn",
        "--target",
        "TABLE",
        "--at",
        "-10m",
    )
    run(
        "set-info",
        "FACT",
        "--subject",
        "MUG",
        "--property",
        "IsNear",
        "--target",
        "SHELF",
        "--at",
        "-1m",
    )
    held = rows(run("get-info", "FACT", "CURRENT", "--at", "-5m", "--json"))
    assert [f["property"] for f in held] == ["IsOn"]
    assert before - 600 * S <= held[0]["valid_from_ns"] <= now_ns() - 600 * S


def test_a_bad_time_is_one_line_naming_it(run: Any) -> None:
    result = run("get-info", "EVENT", "--from", "12 parsecs", ok=False)
    assert result.exit_code != 0
    assert "--from" in result.output and "12 parsecs" in result.output
    assert "Traceback" not in result.output
    style = run("--time", "relative", "get-info", "EVENT", ok=False)
    assert style.exit_code != 0 and "relative" in style.output
