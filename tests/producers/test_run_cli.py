"""`toaster run` on a scenario with shapes writes the move3d_facts snapshot to the store."""

from __future__ import annotations

from pathlib import Path

import pytest
from click.testing import CliRunner

import toaster
from toaster.cli.run import run
from toaster.queries import current_facts

pytestmark = pytest.mark.slow  # every test here takes seconds (see pyproject's markers)

KITCHEN = Path(toaster.__file__).parent / "examples" / "scenario_spatial_kitchen.yaml"


def test_run_writes_spatial_facts(tmp_path: Path) -> None:
    url = f"sqlite:///{tmp_path / 'kitchen.db'}"
    result = CliRunner().invoke(run, [str(KITCHEN), "--db", url])
    assert result.exit_code == 0, result.output
    assert "move3d_facts" in result.output
    db = toaster.connect(url)
    try:
        keys = {(f.subject_id, f.property, f.target_id) for f in current_facts(db, "ROBOT")}
    finally:
        db.close()
    assert ("MUG", "IsOn", "TABLE") in keys
    assert ("BALL", "IsVisibleBy", "ROBOT") in keys  # the box was opened at 3 s
    assert ("BOX", "IsClosed", "") not in keys
    assert ("MUG", "IsVisibleBy", "ALICE") not in keys
