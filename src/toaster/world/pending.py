"""The poses a live source holds until a tick applies them, as columns in push order.

One row per pose; each entity and each (entity, kind, owner, joint) signature is interned to an
integer, so that a tick picks every entity's newest due pose with a few sorts instead of a loop
over entities, and a batch of poses (a /tf message of a crowd) is appended as arrays. The rules
are those of a queue per entity (:class:`toaster.world.live.LiveSource`): an entity keeps at most
``max_pending`` poses, the newest by stamp (equal stamps: the last pushed); a tick applies, per
entity, its newest pose due (equal stamps: the first pushed) and keeps the later ones; entities
come in the order their queues opened (the first push since their queue was last emptied).
"""

from __future__ import annotations

from typing import NamedTuple

import numpy as np

#: rows held at least before the oldest poses of crowded entities are dropped
MIN_ROWS = 4096
#: interned signatures beyond this many per world row (plus MIN_ROWS) are forgotten at a tick
INTERN_SLACK = 2
_F = np.float64
_I = np.int64
Sig = tuple[str, str, str, str]  # entity id, kind, owner id (joints), joint name


class Cols(NamedTuple):
    """Pending poses, one row each: signature and entity codes, push number, stamp (ns, before
    the source's offset), position (n, 3), orientation (n, 4: a quaternion x, y, z, w, or
    roll, pitch, yaw and 0), whether it is a quaternion, confidence."""

    sig: np.ndarray
    eid: np.ndarray
    seq: np.ndarray
    stamp: np.ndarray
    pos: np.ndarray
    orient: np.ndarray
    quat: np.ndarray
    conf: np.ndarray

    def take(self, rows: np.ndarray) -> Cols:
        return Cols(*(column[rows] for column in self))


def _empty() -> Cols:
    return Cols(
        np.zeros(0, _I),
        np.zeros(0, _I),
        np.zeros(0, _I),
        np.zeros(0, _I),
        np.zeros((0, 3)),
        np.zeros((0, 4)),
        np.zeros(0, bool),
        np.zeros(0),
    )


class Pending:
    """Poses pushed and not yet applied (not thread-safe: the source holds its lock)."""

    def __init__(self, max_pending: int) -> None:
        self.max_pending = max(1, int(max_pending))
        self.seq = 0  # the next push's number
        self.limit = MIN_ROWS  # compact past this many rows
        self._forget()
        self._rows: list[tuple] = []  # single pushes, not yet in columns
        self._chunks: list[Cols] = []  # batches, not yet in columns
        self._cols = _empty()
        self.count = 0

    def _forget(self) -> None:
        self.sig_code: dict[Sig, int] = {}
        self.sigs: list[Sig] = []
        self.eid_code: dict[str, int] = {}
        self.eids: list[str] = []
        self._sig_eid: list[int] = []
        self._sig_joint: list[bool] = []
        self.entry = np.zeros(0, _I)  # per entity: push number that opened its queue, or -1

    # -- interning --------------------------------------------------------------------------------
    def code(self, sig: Sig) -> int:
        """The signature's code (interned on first use)."""
        got = self.sig_code.get(sig)
        if got is None:
            eid = self.eid_code.get(sig[0])
            if eid is None:
                eid = self.eid_code[sig[0]] = len(self.eids)
                self.eids.append(sig[0])
            got = self.sig_code[sig] = len(self.sigs)
            self.sigs.append(sig)
            self._sig_eid.append(eid)
            self._sig_joint.append(sig[1] == "joint")
        return got

    def sig_eid(self, codes: np.ndarray) -> np.ndarray:
        """Entity codes of signature codes."""
        return np.asarray(self._sig_eid, _I)[codes] if len(codes) else np.zeros(0, _I)

    def sig_joint(self, codes: np.ndarray) -> np.ndarray:
        """Whether each signature is a joint's."""
        return np.asarray(self._sig_joint, bool)[codes] if len(codes) else np.zeros(0, bool)

    def _grow_entry(self) -> None:
        if len(self.entry) < len(self.eids):
            grow = max(len(self.eids), 2 * len(self.entry), 16) - len(self.entry)
            self.entry = np.concatenate([self.entry, np.full(grow, -1, _I)])

    def _open(self, eids: np.ndarray, seqs: np.ndarray) -> None:
        """Note the push opening each entity's queue (the first of ``eids`` without one)."""
        self._grow_entry()
        fresh = self.entry[eids] < 0
        if fresh.any():
            first, at = np.unique(eids[fresh], return_index=True)
            self.entry[first] = seqs[fresh][at]

    # -- adding -----------------------------------------------------------------------------------
    def add_one(
        self, sig: Sig, stamp: int, pos: tuple, orient: tuple, quat: bool, conf: float
    ) -> None:
        """One pose (``orient``: a quaternion, or roll, pitch, yaw)."""
        code = self.code(sig)
        eid = self._sig_eid[code]
        o = (*orient, 0.0) if len(orient) == 3 else orient
        self._rows.append((code, eid, self.seq, stamp, *pos, *o, quat, conf))
        self._grow_entry()
        if self.entry[eid] < 0:
            self.entry[eid] = self.seq
        self.seq += 1
        self._added(1)

    def add_many(
        self, codes: np.ndarray, stamps: np.ndarray, pos: np.ndarray, quats: np.ndarray
    ) -> None:
        """Poses of interned signatures with quaternions, confidence 1, in order."""
        n = len(codes)
        self._rows_to_chunk()  # push order
        seq = np.arange(self.seq, self.seq + n, dtype=_I)
        eids = self.sig_eid(codes)
        self._chunks.append(
            Cols(codes, eids, seq, stamps, pos, quats, np.ones(n, bool), np.ones(n))
        )
        self._open(eids, seq)
        self.seq += n
        self._added(n)

    def _added(self, n: int) -> None:
        self.count += n
        if self.count > self.limit:
            self.compact()
            self.limit = max(MIN_ROWS, 2 * self.count)

    def columns(self) -> Cols:
        """Every pending pose, in push order."""
        self._rows_to_chunk()
        if self._chunks:
            parts = [self._cols, *self._chunks]
            self._cols = Cols(*(np.concatenate(c) for c in zip(*parts, strict=True)))
            self._chunks = []
        return self._cols

    def _rows_to_chunk(self) -> None:
        if self._rows:
            r = self._rows
            rows = Cols(
                np.fromiter((p[0] for p in r), _I, len(r)),
                np.fromiter((p[1] for p in r), _I, len(r)),
                np.fromiter((p[2] for p in r), _I, len(r)),
                np.fromiter((p[3] for p in r), _I, len(r)),
                np.array([p[4:7] for p in r], _F).reshape(-1, 3),
                np.array([p[7:11] for p in r], _F).reshape(-1, 4),
                np.fromiter((p[11] for p in r), bool, len(r)),
                np.fromiter((p[12] for p in r), _F, len(r)),
            )
            self._chunks.append(rows)
            self._rows = []

    # -- bounding ---------------------------------------------------------------------------------
    def compact(self) -> None:
        """Keep each entity's newest ``max_pending`` poses by stamp (equal stamps: the last
        pushed), as a queue trimmed at every push would."""
        c = self.columns()
        if not len(c.eid) or np.bincount(c.eid).max() <= self.max_pending:
            return
        order = np.lexsort((c.seq, c.stamp, c.eid))
        e = c.eid[order]
        ends = np.searchsorted(e, e, side="right")
        kept = np.sort(order[ends - np.arange(len(e)) <= self.max_pending])
        self._cols = c.take(kept)
        self.count = len(kept)

    def forget_unused(self, world_rows: int) -> bool:
        """Forget the signatures no pending pose uses when there are many more than the world
        has rows (a publisher inventing ids); True if forgotten (codes changed)."""
        if len(self.sigs) <= INTERN_SLACK * world_rows + MIN_ROWS:
            return False
        c = self.columns()
        sigs, entry = self.sigs, self.entry
        old_eids = c.eid
        self._forget()
        remap = np.full(len(sigs), -1, _I)
        for code in np.unique(c.sig).tolist():
            remap[code] = self.code(sigs[code])
        codes = remap[c.sig]
        eids = self.sig_eid(codes)
        self._cols = c._replace(sig=codes, eid=eids)
        self.entry = np.full(max(len(self.eids), 16), -1, _I)
        self.entry[eids] = entry[old_eids]
        return True

    # -- taking -----------------------------------------------------------------------------------
    def newest(self, limit: int | None = None) -> int | None:
        """The newest stamp pending (at most ``limit``), or None."""
        self.compact()
        stamps = self.columns().stamp
        if limit is not None:
            stamps = stamps[_due(stamps, limit)]
        return int(stamps.max()) if len(stamps) else None

    def take_due(self, limit: int) -> Cols:
        """Each entity's newest pose stamped at most ``limit`` (equal stamps: the first
        pushed), entities in the order their queues opened; the later poses stay."""
        self.compact()
        c = self.columns()
        due = _due(c.stamp, limit)
        d = np.flatnonzero(due)
        if not d.size:
            return _empty()
        order = np.lexsort((-c.seq[d], c.stamp[d], c.eid[d]))
        s = d[order]
        e = c.eid[s]
        last = np.ones(len(s), bool)
        last[:-1] = e[1:] != e[:-1]
        chosen = s[last]
        opened = self.entry[c.eid[chosen]]
        chosen = chosen[np.argsort(opened, kind="stable")]
        keep = np.flatnonzero(~due)
        self._cols = c.take(keep)
        self.count = len(keep)
        left = np.zeros(len(self.eids), bool)
        left[self._cols.eid] = True
        done = c.eid[chosen]
        self.entry[done[~left[done]]] = -1
        return c.take(chosen)


def _due(stamps: np.ndarray, limit: int) -> np.ndarray:
    """``stamps <= limit`` for any Python int ``limit`` (stamps are 0 to 2^63 - 1)."""
    if limit >= np.iinfo(_I).max:
        return np.ones(len(stamps), bool)
    if limit < 0:
        return np.zeros(len(stamps), bool)
    return stamps <= limit
