"""The relpos command (tested on the click command itself)."""

from __future__ import annotations

from pathlib import Path

from click.testing import CliRunner

import toaster
from toaster.cli.run import relpos

KITCHEN = Path(toaster.__file__).parent / "examples" / "scenario_spatial_kitchen.yaml"


def test_relpos_flips_when_bob_turns() -> None:
    runner = CliRunner()
    args = [str(KITCHEN), "--viewer", "BOB", "--object", "MUG", "--reference", "BOX"]
    before = runner.invoke(relpos, [*args, "--at", "1s"])
    after = runner.invoke(relpos, [*args, "--at", "3s"])
    assert before.exit_code == 0, before.output
    assert before.output.startswith("MUG: left, in front (relative to BOX, from BOB's viewpoint")
    assert after.output.startswith("MUG: right, behind (relative to BOX")


def test_relpos_relative_to_viewer_and_unknown_entity() -> None:
    runner = CliRunner()
    out = runner.invoke(relpos, [str(KITCHEN), "--viewer", "ROBOT", "--object", "MUG"])
    assert out.exit_code == 0 and "MUG: in front, below, right (relative to ROBOT" in out.output
    bad = runner.invoke(relpos, [str(KITCHEN), "--viewer", "NOBODY", "--object", "MUG"])
    assert bad.exit_code != 0
