"""In-memory snapshot diff: what a store would write for a snapshot (for stats and benchmarks)."""

from __future__ import annotations

from collections.abc import Iterable
from typing import NamedTuple

from toaster.model import Fact, fact_key


class Changes(NamedTuple):
    """Counts of one snapshot's changes."""

    appeared: int
    changed: int
    ended: int


class SnapshotDiff:
    """Keeps the last snapshot per source and counts appeared / changed / ended facts."""

    def __init__(self) -> None:
        self._last: dict[str, dict[tuple, Fact]] = {}

    def apply(self, source: str, facts: Iterable[Fact]) -> Changes:
        """Diff a complete snapshot against the source's previous one (value_text changes)."""
        new = {fact_key(f): f for f in facts}
        old = self._last.get(source, {})
        appeared = changed = 0
        for key, fact in new.items():
            before = old.get(key)
            if before is None:
                appeared += 1
            elif before[3] != fact[3]:
                changed += 1
        ended = len(old.keys() - new.keys())
        self._last[source] = new
        return Changes(appeared, changed, ended)
