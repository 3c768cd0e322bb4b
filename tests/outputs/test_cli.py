"""``toaster plot-facts`` and ``toaster export`` on a real database file."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

import toaster
from tests.outputs.conftest import T0, S
from toaster.cli.export import export
from toaster.cli.plot import plot_facts

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)


def test_plot_facts_command(run_db: toaster.Database, db_url: str, tmp_path: Path) -> None:
    """The command writes the picture and reports the false belief; .dat names the script."""
    run = CliRunner().invoke
    done = run(
        plot_facts,
        [
            str(tmp_path / "mug.png"),
            "-s",
            "mug",
            "-p",
            "IsOn",
            "--to",
            str(T0 + 20 * S),
            "--db",
            db_url,
        ],
    )
    assert done.exit_code == 0, done.output
    assert "1 false-belief spans" in done.output
    assert (tmp_path / "mug.png").stat().st_size > 1000
    done = run(plot_facts, [str(tmp_path / "mug.dat"), "-s", "mug", "--db", db_url])
    assert "gnuplot -p" in done.output


def test_commands_fail_in_one_line(run_db: toaster.Database, db_url: str, tmp_path: Path) -> None:
    """Bad input ends with exit 1 and one line naming it."""
    run = CliRunner().invoke
    done = run(plot_facts, [str(tmp_path / "x.png"), "-a", "carol", "--db", db_url])
    assert done.exit_code == 1
    lines = done.output.strip().splitlines()
    assert len(lines) == 1
    assert lines[0].startswith(
        "Error: unknown agent 'carol': known agents are 'pr2', 'alice', 'bob'"
    )
    done = run(export, ["memory", str(tmp_path / "x.txt"), "--db", db_url])
    assert done.exit_code == 1
    assert "unknown export file suffix" in done.output


def test_export_command(run_db: toaster.Database, db_url: str, tmp_path: Path) -> None:
    """``toaster export history out.jsonl --agent pr2`` writes the agent's intervals."""
    out = tmp_path / "h.jsonl"
    done = CliRunner().invoke(export, ["history", str(out), "-a", "pr2", "--db", db_url])
    assert done.exit_code == 0, done.output
    assert done.output.startswith("wrote 5 history rows")
    assert len(out.read_text().splitlines()) == 5
