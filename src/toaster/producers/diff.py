"""In-memory snapshot diff: what a store would write for a snapshot (for stats and benchmarks).

Snapshots given as a :class:`~toaster.producers.batch.FactBatch` are diffed on integer keys
with numpy (no Python object per fact); lists of facts on their identity tuples.
"""

from __future__ import annotations

from collections.abc import Iterable
from typing import Any, NamedTuple

import numpy as np

from toaster.model import Fact, fact_key
from toaster.producers.batch import FactBatch


class Changes(NamedTuple):
    """Counts of one snapshot's changes."""

    appeared: int
    changed: int
    ended: int


class KeySnapshot:
    """A batch snapshot reduced to sorted unique keys and their value_text codes."""

    __slots__ = ("codes", "keys", "world")

    def __init__(self, world: Any, keys: np.ndarray, codes: np.ndarray) -> None:
        self.world, self.keys, self.codes = world, keys, codes

    def __len__(self) -> int:
        return len(self.keys)

    def __eq__(self, other: object) -> bool:
        return (
            isinstance(other, KeySnapshot)
            and np.array_equal(self.keys, other.keys)
            and np.array_equal(self.codes, other.codes)
        )

    __hash__ = None  # type: ignore[assignment]

    @classmethod
    def of(cls, batch: FactBatch) -> KeySnapshot:
        keys, codes = batch.keys()
        if len(keys) > 1:
            order = np.argsort(keys, kind="stable")
            keys, codes = keys[order], codes[order]
            last = np.ones(len(keys), bool)  # a repeated key keeps its last fact (dict rule)
            last[:-1] = keys[1:] != keys[:-1]
            if not last.all():
                keys, codes = keys[last], codes[last]
        return cls(batch.world, keys, codes)


class SnapshotDiff:
    """Keeps the last snapshot per source and counts appeared / changed / ended facts."""

    def __init__(self) -> None:
        self._last: dict[str, Any] = {}

    def apply(self, source: str, facts: FactBatch | Iterable[Fact]) -> Changes:
        """Diff a complete snapshot against the source's previous one (value_text changes)."""
        old = self._last.get(source)
        if isinstance(old, KeySnapshot):
            if not (isinstance(facts, FactBatch) and facts.world is old.world):
                msg = (
                    f"source {source!r} switched from fact batches of one world to another "
                    "kind of snapshot: use one kind per source and diff"
                )
                raise TypeError(msg)
            snap = KeySnapshot.of(facts)
            self._last[source] = snap
            return _diff_keys(old, snap)
        if isinstance(facts, FactBatch):
            if old is None:
                snap = KeySnapshot.of(facts)
                self._last[source] = snap
                return Changes(len(snap), 0, 0)
            facts = facts.facts()
        new = {fact_key(f): f for f in facts}
        old = old or {}
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


def _diff_keys(old: KeySnapshot, new: KeySnapshot) -> Changes:
    if len(old.keys) == 0:
        return Changes(len(new.keys), 0, 0)
    pos = np.searchsorted(old.keys, new.keys)
    pos_c = np.minimum(pos, len(old.keys) - 1)
    found = old.keys[pos_c] == new.keys
    n_found = int(found.sum())
    changed = int((old.codes[pos_c[found]] != new.codes[found]).sum())
    return Changes(len(new.keys) - n_found, changed, len(old.keys) - n_found)
