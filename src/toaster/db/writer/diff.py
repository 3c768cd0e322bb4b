"""The store's memory of a fact-batch source: its stored facts as arrays sorted by batch key.

A producer's :class:`~toaster.producers.batch.FactBatch` names each fact by an integer key
(group signature × subject row × target row) and its value_text by an interned code. Kept
sorted by that key with the stored numbers beside it, a whole snapshot is compared with what
is stored in a few numpy operations: only facts that appeared, changed their text or moved a
number beyond its tolerance become Python tuples, and only they reach the database.

:class:`SourceState` is what the store remembers of every source (the facts it wrote last, and
these arrays for batch sources); :func:`within` is the tolerance test of one fact.
"""

from __future__ import annotations

import operator
from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import NamedTuple, Protocol, runtime_checkable

import numpy as np

from toaster.db import tolerance
from toaster.db.dialects import Key
from toaster.db.tolerance import Tolerance
from toaster.model import Fact

#: fact_key in C: (subject, subject owner, property, sub-property, target, target owner).
key_of = operator.itemgetter(0, 9, 1, 8, 2, 10)


class BatchGroup(Protocol):
    """One run of a batch's facts sharing their property."""

    @property
    def prop(self) -> str: ...
    @property
    def size(self) -> int: ...


@runtime_checkable
class FactArrays(Protocol):
    """What the store reads of a producer's :class:`~toaster.producers.batch.FactBatch`."""

    @property
    def world(self) -> object:
        """The world whose rows the batch names (a new world: the arrays are rebuilt)."""

    @property
    def groups(self) -> Sequence[BatchGroup]: ...
    def facts(self) -> list[Fact]: ...
    def facts_at(self, positions: np.ndarray) -> list[Fact]: ...
    def keys(self) -> tuple[np.ndarray, np.ndarray]: ...
    def plain(self) -> bool:
        """True when every fact passes :func:`toaster.model.check_fact` unchanged."""

    def numbers(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]: ...


class Snapshot(NamedTuple):
    """One batch, deduplicated (a repeated key keeps its last fact) and sorted by key."""

    keys: np.ndarray
    codes: np.ndarray
    numbers: np.ndarray  # (n, 3): value_num (NaN = none), confidence, observability
    tolerance: np.ndarray  # (n, 3): the same parts' tolerances
    order: np.ndarray  # group-order position of each fact in the batch

    @classmethod
    def of(cls, batch: FactArrays, tolerances: dict[str, Tolerance]) -> Snapshot:
        keys, codes = batch.keys()
        numbers = np.column_stack(batch.numbers()) if len(keys) else np.zeros((0, 3))
        default = tolerances["*"]
        per_group = np.array(
            [tolerances.get(g.prop, default) for g in batch.groups] or np.zeros((0, 3)), np.float64
        ).reshape(-1, 3)
        sizes = np.fromiter((g.size for g in batch.groups), np.int64, len(batch.groups))
        tol = np.repeat(per_group, sizes, axis=0)
        order = np.argsort(keys, kind="stable")
        keys = keys[order]
        if len(keys) > 1:
            last = np.ones(len(keys), bool)
            last[:-1] = keys[1:] != keys[:-1]
            if not last.all():
                order, keys = order[last], keys[last]
        return cls(keys, codes[order], numbers[order], tol[order], order)


class BatchState:
    """What a batch source has stored: sorted keys, text codes, numbers, and each batch key's
    fact key (the facts themselves are the source's :attr:`SourceState.facts`)."""

    __slots__ = ("codes", "keys", "numbers", "tkeys", "world")

    def __init__(
        self,
        world: object,
        keys: np.ndarray,
        codes: np.ndarray,
        numbers: np.ndarray,
        tkeys: dict[int, Key],
    ) -> None:
        self.world, self.keys, self.codes, self.numbers = world, keys, codes, numbers
        self.tkeys = tkeys

    @classmethod
    def of(cls, batch: FactArrays, stored: dict[Key, Fact]) -> BatchState:
        """The state after ``batch`` was written through the list path (``stored``: the
        source's facts as stored, which may differ from the batch's within tolerance)."""
        snap = Snapshot.of(batch, {"*": Tolerance()})
        facts = batch.facts()
        codes, numbers = snap.codes.copy(), snap.numbers.copy()
        tkeys: dict[int, Key] = {}
        for j, (i, batch_key) in enumerate(
            zip(snap.order.tolist(), snap.keys.tolist(), strict=True)
        ):
            given = facts[i]
            key = key_of(given)
            tkeys[batch_key] = key
            held = stored.get(key, given)
            if held is not given:
                numbers[j] = (
                    np.nan if held.value_num is None else held.value_num,
                    held.confidence,
                    held.observability,
                )
                if held.value_text != given.value_text:
                    codes[j] = -1  # compare again next time (the database decides)
        return cls(batch.world, snap.keys, codes, numbers, tkeys)

    def diff(self, new: Snapshot) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """(positions in ``new`` to write, mask of ``new`` facts kept as stored, their
        positions here, positions here of facts gone)."""
        n_old = len(self.keys)
        if n_old == 0:
            nothing = np.zeros(len(new.keys), bool)
            return (
                np.arange(len(new.keys)),
                nothing,
                np.zeros(len(new.keys), np.int64),
                np.zeros(0, np.int64),
            )
        pos = np.minimum(np.searchsorted(self.keys, new.keys), n_old - 1)
        found = self.keys[pos] == new.keys
        held = self.numbers[pos]
        with np.errstate(invalid="ignore"):
            moved = ~(np.abs(new.numbers - held) <= new.tolerance)
        moved &= ~(np.isnan(new.numbers) & np.isnan(held))
        keep = found & (self.codes[pos] == new.codes) & ~moved.any(axis=1)
        matched = np.zeros(n_old, bool)
        matched[pos[found]] = True
        return np.flatnonzero(~keep), keep, pos, np.flatnonzero(~matched)

    def gone(self, positions: np.ndarray) -> list[Key]:
        """The fact keys of the stored facts at ``positions``."""
        return list(map(self.tkeys.__getitem__, self.keys[positions].tolist()))

    def updated(
        self,
        new: Snapshot,
        touched: np.ndarray,
        keep: np.ndarray,
        pos: np.ndarray,
        keys: list[Key],
        gone: np.ndarray,
    ) -> BatchState:
        """The state once the facts of ``keys`` (at ``touched``) were written, those at
        ``gone`` ended and the rest kept (this state's key map is moved to the new one)."""
        numbers = new.numbers.copy()
        if len(self.keys):
            numbers[keep] = self.numbers[pos[keep]]
        tkeys = self.tkeys
        for batch_key in self.keys[gone].tolist():
            del tkeys[batch_key]
        tkeys.update(zip(new.keys[touched].tolist(), keys, strict=True))
        return BatchState(self.world, new.keys, new.codes, numbers, tkeys)


@dataclass
class SourceState:
    """What the store remembers of one source for one agent: the facts it wrote last."""

    facts: dict[Key, Fact] = field(default_factory=dict)  # as stored (within tolerance)
    last_list: list[Fact] | None = None  # the last snapshot as given: equal lists skip the diff
    last_t: int = -(2**63)
    arrays: BatchState | None = None  # the same facts as arrays, for fact-batch sources


def within(table: dict[str, Tolerance], new: Fact, held: Fact | None) -> bool:
    """``new`` only moved ``held``'s numbers within their tolerance (nothing to write)."""
    if held is None or new[:4] != held[:4] or new[7:] != held[7:]:
        return False
    return not tolerance.beyond(table.get(new[1]) or table["*"], new[4:7], held[4:7])
