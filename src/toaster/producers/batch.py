"""Facts as arrays: a producer's snapshot kept columnar until someone needs Fact tuples.

A :class:`FactBatch` is a list of groups. A group shares its property, sub-property, property
type and observability; subjects and targets are either one text constant or an array of world
rows (targets also text labels: codes into an array of texts, as many areas' memberships in
one group); value_text, value_num and confidence are a constant or an array. Subject owners
are always derived from the subject rows (the owner's id, or "" for a row without owner) or
given with a constant subject; target owners are a constant or an array of rows (-1 = "").

Diffing works on integer keys (group signature × subject row × target row) and interned
value_text codes, so a tick where nothing changed creates no Python object per fact; only
:meth:`FactBatch.facts` builds tuples (in group order, the order the producers always used).
Rule kept by every producer: within one group signature, the target owner rows are a function
of the subject and target rows, and a fact key is never produced both by a constant-subject
(or -target) group and by a row group of the same signature.
"""

from __future__ import annotations

import threading
from collections.abc import Iterator, Mapping
from functools import partial
from itertools import repeat
from typing import Any, NamedTuple

import numpy as np

from toaster.model import MAX_ID_BYTES, Fact

_B = 1 << 21  # rows < 2M
_SIGS: dict[tuple, int] = {}
_TEXTS: dict[str, int] = {}
_make_fact = partial(tuple.__new__, Fact)
_EMPTY = np.zeros(0, np.int64)
_NEG = np.full(1024, -1, np.int64)


_CHECKED: list[object] = [None, None]  # the last world id and owner arrays found plain
_NEW_CODE = threading.Lock()  # codes are made on a live node's tick and writer threads


def _sig_id(sig: tuple) -> int:
    got = _SIGS.get(sig)
    if got is None:
        with _NEW_CODE:
            got = _SIGS.setdefault(sig, len(_SIGS))
    return got


def text_code(text: str) -> int:
    """A process-wide integer for a value_text."""
    got = _TEXTS.get(text)
    if got is None:
        with _NEW_CODE:
            got = _TEXTS.setdefault(text, len(_TEXTS))
    return got


class Group(NamedTuple):
    """One run of facts sharing their property (see the module doc)."""

    prop: str
    subj: np.ndarray | str
    tgt: np.ndarray | str | tuple[np.ndarray, np.ndarray]  # rows, a constant, (codes, labels)
    value_text: str | tuple[np.ndarray, np.ndarray]  # constant or (codes, labels)
    value_num: np.ndarray | float | None
    conf: np.ndarray | float
    obs: float
    property_type: str
    sub_property: str
    tgt_owner: np.ndarray | str = ""
    subj_owner: str = ""
    size: int = 0


class FactBatch:
    """A producer's snapshot as array groups, tied to the world whose rows it names."""

    __slots__ = ("_facts", "_ids", "groups", "n", "world")

    def __init__(self, world: Any) -> None:
        self.world = world
        self.groups: list[Group] = []
        self.n = 0
        self._facts: list[Fact] | None = None
        self._ids: tuple[np.ndarray, np.ndarray] | None = None

    def pin(self) -> FactBatch:
        """Bind the batch to the world's ids and owners as they are now, so that its facts
        can be built later on another thread (a live node's writer) while the world goes on
        (the arrays are replaced, never changed, when entities change)."""
        self._ids = (self.world.id_array(), self.world.owner_id_array())
        return self

    def __len__(self) -> int:
        return self.n

    def add(
        self,
        prop: str,
        subj: np.ndarray | str,
        tgt: np.ndarray | str | tuple[np.ndarray, np.ndarray] = "",
        *,
        value_text: str | tuple[np.ndarray, np.ndarray] = "true",
        value_num: np.ndarray | float | None = None,
        conf: np.ndarray | float = 1.0,
        obs: float = 1.0,
        property_type: str = "",
        sub_property: str = "",
        tgt_owner: np.ndarray | str = "",
        subj_owner: str = "",
    ) -> None:
        """Append a group; array columns all have the group's length.

        ``subj_owner`` is used only with a constant subject (row subjects derive theirs).
        """
        if isinstance(subj, np.ndarray):
            size = len(subj)
        elif isinstance(tgt, np.ndarray):
            size = len(tgt)
        elif isinstance(tgt, tuple):
            size = len(tgt[0])
        else:
            size = 1
        if size == 0:
            return
        self.groups.append(
            Group(
                prop,
                subj,
                tgt,
                value_text,
                value_num,
                conf,
                obs,
                property_type,
                sub_property,
                tgt_owner,
                subj_owner,
                size,
            )
        )
        self.n += size
        self._facts = None

    # -- tuples ------------------------------------------------------------------------------
    def facts(self) -> list[Fact]:
        """The Fact tuples, in group order (built once, then cached)."""
        if self._facts is None:
            out: list[Fact] = []
            for g in self.groups:
                out.extend(self._group_facts(g, None))
            self._facts = out
        return self._facts

    def facts_at(self, positions: np.ndarray) -> list[Fact]:
        """The Fact tuples at these group-order positions (in their order), building only
        those: a store writing a few changes of a large snapshot needs no more."""
        if self._facts is not None:
            facts = self._facts
            return [facts[i] for i in positions.tolist()]
        order = np.argsort(positions, kind="stable")
        wanted = positions[order]
        out: list[Fact] = []
        start = 0
        for g in self.groups:
            lo, hi = np.searchsorted(wanted, (start, start + g.size))
            if hi > lo:
                out.extend(self._group_facts(g, wanted[lo:hi] - start))
            start += g.size
        result: list[Any] = [None] * len(out)
        for slot, fact in zip(order.tolist(), out, strict=True):
            result[slot] = fact
        return result

    def numbers(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(value_num with NaN for none, confidence, observability) per fact, group order."""
        if not self.groups:
            return np.zeros(0), np.zeros(0), np.zeros(0)
        num, conf, obs = [], [], []
        for g in self.groups:
            m = g.size
            if isinstance(g.value_num, np.ndarray):
                num.append(np.asarray(g.value_num, np.float64))
            else:
                num.append(np.full(m, np.nan if g.value_num is None else g.value_num))
            conf.append(
                np.asarray(g.conf, np.float64)
                if isinstance(g.conf, np.ndarray)
                else np.full(m, float(g.conf))
            )
            obs.append(np.full(m, float(g.obs)))
        return np.concatenate(num), np.concatenate(conf), np.concatenate(obs)

    def _group_facts(self, g: Group, local: np.ndarray | None) -> list[Fact]:
        """One group's facts, all of them or those at ``local`` positions in the group."""
        ids, owners = self._ids or (self.world.id_array(), self.world.owner_id_array())
        m = g.size if local is None else len(local)

        def pick(column: Any) -> Any:
            return column if local is None else column[local]

        if isinstance(g.subj, np.ndarray):
            rows = pick(g.subj)
            subj: Any = ids[rows].tolist()
            subj_owner: Any = owners[rows].tolist()
        else:
            subj, subj_owner = repeat(g.subj, m), repeat(g.subj_owner, m)
        if isinstance(g.tgt, np.ndarray):
            tgt: Any = ids[pick(g.tgt)].tolist()
        elif isinstance(g.tgt, tuple):
            tgt = g.tgt[1][pick(g.tgt[0])].tolist()
        else:
            tgt = repeat(g.tgt, m)
        if isinstance(g.value_text, tuple):
            codes, labels = g.value_text
            vt: Any = labels[pick(codes)].tolist()
        else:
            vt = repeat(g.value_text, m)
        vn = (
            pick(g.value_num).tolist()
            if isinstance(g.value_num, np.ndarray)
            else repeat(g.value_num, m)
        )
        cf = pick(g.conf).tolist() if isinstance(g.conf, np.ndarray) else repeat(g.conf, m)
        if isinstance(g.tgt_owner, np.ndarray):
            owners = pick(g.tgt_owner)
            to: Any = np.where(owners >= 0, ids[owners], "").tolist()
        else:
            to = repeat(g.tgt_owner, m)
        return list(
            map(
                _make_fact,
                zip(  # noqa: B905
                    subj,
                    repeat(g.prop, m),
                    tgt,
                    vt,
                    vn,
                    cf,
                    repeat(g.obs, m),
                    repeat(g.property_type, m),
                    repeat(g.sub_property, m),
                    subj_owner,
                    to,
                ),
            )
        )

    # -- validation ---------------------------------------------------------------------------
    def plain(self) -> bool:
        """True when every fact of the batch passes :func:`toaster.model.check_fact`
        unchanged (its fast path), checked as arrays: each constant and label once, the world's
        ids once per id array, the numbers with numpy. False: check the facts one by one (a
        bad value then fails in one line, as for any producer)."""
        ids, owners = self._ids or (self.world.id_array(), self.world.owner_id_array())
        if not (_CHECKED[0] is ids and _CHECKED[1] is owners):
            if not (_all_ids(ids.tolist(), subject=True) and _all_ids(owners.tolist())):
                return False
            _CHECKED[:] = [ids, owners]
        return all(map(_plain_group, self.groups))

    # -- keys ----------------------------------------------------------------------------------
    def keys(self) -> tuple[np.ndarray, np.ndarray]:
        """(int64 fact keys, int64 value_text codes) for every fact, in group order."""
        groups = self.groups
        if not groups:
            return _EMPTY, _EMPTY
        sizes = np.fromiter((g.size for g in groups), np.int64, len(groups))
        base = np.empty(len(groups), np.int64)
        code = np.empty(len(groups), np.int64)
        subj_parts: list[np.ndarray] = []
        tgt_parts: list[np.ndarray] = []
        labelled: list[tuple[int, tuple[np.ndarray, np.ndarray]]] = []
        named: list[tuple[int, np.ndarray]] = []  # groups of labelled targets: base per fact
        neg = _neg1(int(sizes.max()))
        for i, g in enumerate(groups):
            subj_row = isinstance(g.subj, np.ndarray)

            def sig(target: str | None, g: Group = g, subj_row: bool = subj_row) -> int:
                return _sig_id(
                    (
                        g.prop,
                        g.sub_property,
                        None if subj_row else (g.subj, g.subj_owner),
                        target,
                        None if isinstance(g.tgt_owner, np.ndarray) else g.tgt_owner,
                    )
                )

            tgt = g.tgt
            if isinstance(tgt, tuple):  # the keys of one constant-target group per label
                codes, labels = tgt
                table = np.array([sig(x) for x in labels.tolist()], np.int64)
                named.append((i, table[codes]))
                base[i] = 0
            else:
                base[i] = sig(None if isinstance(tgt, np.ndarray) else tgt)
            subj_parts.append(g.subj if isinstance(g.subj, np.ndarray) else neg[: g.size])
            tgt_parts.append(g.tgt if isinstance(g.tgt, np.ndarray) else neg[: g.size])
            if isinstance(g.value_text, tuple):
                code[i] = -1
                labelled.append((i, g.value_text))
            else:
                code[i] = text_code(g.value_text)
        keys = np.repeat(base * (_B * _B), sizes)
        keys += (np.concatenate(subj_parts) + 1) * _B
        keys += np.concatenate(tgt_parts) + 1
        if named:
            ends = np.cumsum(sizes)
            for i, bases in named:
                keys[ends[i] - sizes[i] : ends[i]] += bases * (_B * _B)
        codes = np.repeat(code, sizes)
        if labelled:
            ends = np.cumsum(sizes)
            for i, (lab_codes, labels) in labelled:
                table = np.array([text_code(x) for x in labels.tolist()], np.int64)
                codes[ends[i] - sizes[i] : ends[i]] = table[lab_codes]
        return keys, codes


def _is_id(x: object, *, subject: bool = False) -> bool:
    """``x`` passes model._plain as an id (subject or property: non-empty, not blank)."""
    return (
        type(x) is str
        and len(x) <= MAX_ID_BYTES
        and x.isascii()
        and "\x00" not in x
        and (not subject or (bool(x) and not x.isspace()))
    )


def _all_ids(xs: list[Any], *, subject: bool = False) -> bool:
    return all(_is_id(x, subject=subject) for x in xs)


def _is_text(x: object) -> bool:
    return type(x) is str and x.isascii() and "\x00" not in x


def _plain_group(g: Group) -> bool:
    """One group's constants, labels and numbers pass model._plain (ids: checked apart)."""
    if not (
        _is_id(g.prop, subject=True)
        and _is_id(g.sub_property)
        and _is_text(g.property_type)
        and type(g.obs) is float
        and 0.0 <= g.obs <= 1.0
    ):
        return False
    if not isinstance(g.subj, np.ndarray) and not (
        _is_id(g.subj, subject=True) and _is_id(g.subj_owner)
    ):
        return False
    tgt = g.tgt
    if isinstance(tgt, tuple):
        if not _all_ids(tgt[1].tolist()):
            return False
    elif not isinstance(tgt, np.ndarray) and not _is_id(tgt):
        return False
    if not isinstance(g.tgt_owner, np.ndarray) and not _is_id(g.tgt_owner):
        return False
    vt = g.value_text
    if isinstance(vt, tuple):
        if not all(map(_is_text, vt[1].tolist())):
            return False
    elif not _is_text(vt):
        return False
    vn, conf = g.value_num, g.conf
    if isinstance(vn, np.ndarray):
        if vn.dtype.kind != "f" or not np.isfinite(vn).all():
            return False
    elif not (vn is None or (type(vn) is float and np.isfinite(vn))):
        return False
    if isinstance(conf, np.ndarray):
        return conf.dtype.kind == "f" and bool(((conf >= 0.0) & (conf <= 1.0)).all())
    return type(conf) is float and 0.0 <= conf <= 1.0


def _neg1(m: int) -> np.ndarray:
    global _NEG
    if len(_NEG) < m:
        _NEG = np.full(max(m, 2 * len(_NEG)), -1, np.int64)
    return _NEG


class TickFacts(Mapping[str, list[Fact]]):
    """A tick's facts per producer, as Fact tuples built on first access: the outputs of a
    tick read few of them (a crowd's agent_monitor holds thousands), and those that can use
    the arrays take them (:meth:`raw`)."""

    __slots__ = ("_out",)

    def __init__(self, out: Mapping[str, list[Fact] | FactBatch]) -> None:
        self._out = dict(out)

    def __getitem__(self, name: str) -> list[Fact]:
        return as_facts(self._out[name])

    def __iter__(self) -> Iterator[str]:
        return iter(self._out)

    def __len__(self) -> int:
        return len(self._out)

    def raw(self, name: str) -> list[Fact] | FactBatch | None:
        """A producer's snapshot as it came (a batch or a list), or None."""
        return self._out.get(name)

    def __repr__(self) -> str:
        return f"TickFacts({ {name: len(f) for name, f in self._out.items()} })"


def as_facts(facts: Any) -> list[Fact]:
    """Fact tuples from a batch or any iterable of facts."""
    if isinstance(facts, FactBatch):
        return facts.facts()
    return facts if isinstance(facts, list) else list(facts)
