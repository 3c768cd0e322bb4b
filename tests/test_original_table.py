"""docs/original.md: every difference from the original names tests that exist."""

from __future__ import annotations

import ast
import re
from pathlib import Path

ROOT = Path(__file__).resolve().parents[1]


def test_every_row_names_existing_tests() -> None:
    text = (ROOT / "docs" / "original.md").read_text()
    table = text.split("## Differences from the original", 1)[1].split("\nElsewhere", 1)[0]
    rows = [line for line in table.splitlines() if line.startswith("| ") and "---" not in line]
    assert len(rows) > 20
    for row in rows[1:]:  # the header first
        cells = [c.strip() for c in row.strip("|").split(" | ")]
        assert len(cells) == 4, row
        names = re.findall(r"`([\w/]+\.py)(?:::(\w+))?`|`::(\w+)`", cells[3])
        assert names, row
        path = None
        for file, name, more in names:
            path = ROOT / "tests" / file if file else path
            assert path is not None and path.is_file(), row
            tests = {n.name for n in ast.parse(path.read_text()).body if hasattr(n, "name")}
            for wanted in (name, more):
                assert not wanted or wanted in tests, f"{wanted} not in {path}"
