"""The database layer imports nothing from the layers above it; ``toaster.connect`` (the
composition root) is what gives every store the belief rule."""

from __future__ import annotations

import ast
from pathlib import Path

import toaster
from toaster import session
from toaster.beliefs.rules import BeliefRule
from toaster.db import open_database

_ABOVE = ("toaster.beliefs", "toaster.queries", "toaster.cli", "toaster.live", "toaster.world",
          "toaster.producers", "toaster.session", "toaster.ros1", "toaster.plotting",
          "toaster.export", "toaster.recording")


def _imports(path: Path) -> list[str]:
    names: list[str] = []
    for node in ast.walk(ast.parse(path.read_text(encoding="utf-8"))):
        if isinstance(node, ast.Import):
            names += [alias.name for alias in node.names]
        elif isinstance(node, ast.ImportFrom) and node.module and not node.level:
            names.append(node.module)
    return names


def test_db_imports_nothing_from_the_layers_above() -> None:
    root = Path(toaster.__file__).parent / "db"
    upward = [f"{path.relative_to(root)}: {name}" for path in sorted(root.rglob("*.py"))
              for name in _imports(path) if name.startswith(_ABOVE)]
    assert upward == []


def test_connect_installs_the_belief_rule_and_the_bare_opener_none(db_url: str) -> None:
    with toaster.connect(db_url) as db:
        assert db.rules == session.RULES
        assert [type(rule) for rule in db.store()._rules] == [BeliefRule]
    with open_database(db_url) as bare:
        assert bare.store()._rules == []
