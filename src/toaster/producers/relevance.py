"""Relevance: which (subject, target) pairs are near enough to be worth a pair fact.

Pair facts (IsMovingToward, Distance, IsLookingToward / IsLookingAt) are computed only for
pairs within a range, found with a KD-tree (``scipy.spatial.cKDTree``) on the targets' x, y,
so a tick costs O(subjects × neighbours + targets log targets) instead of O(subjects ×
targets). The index is planar: a 2D ball contains the 3D ball of the same radius, so it
gives candidates for 3D ranges too; callers (and :func:`pairs_within`) then apply their exact
test to the candidates with the same per-pair formula as a dense computation, so the facts
inside the range are exactly those of the dense computation. Small sets (fewer than
``DENSE_MAX_PAIRS`` pairs) skip the tree: a dense array is cheaper there.
"""

from __future__ import annotations

from itertools import chain

import numpy as np
from scipy.spatial import cKDTree  # type: ignore[import-untyped]

#: Below this many (subject × target) pairs the dense test beats building a tree (measured:
#: docs/producers.md, "Relevance").
DENSE_MAX_PAIRS = 20_000
#: Relative slack on the query radius, so float rounding in the tree never drops a pair that
#: the exact test keeps (the exact test decides).
_SLACK = 1e-9
_EMPTY = np.zeros(0, np.int64)


class PlanarIndex:
    """Targets' x, y with a KD-tree built on first need; answers "which targets are near"."""

    __slots__ = ("_tree", "xy")

    def __init__(self, xy: np.ndarray) -> None:
        self.xy = np.ascontiguousarray(xy[:, :2], dtype=float)
        self._tree: cKDTree | None = None

    def __len__(self) -> int:
        return len(self.xy)

    def candidates(self, a: np.ndarray, r: float) -> tuple[np.ndarray, np.ndarray]:
        """(a index, target index) of every pair whose 2D distance is ≤ r (plus a hair).

        Sorted by a index, then target index (the order of ``np.nonzero`` on a dense array).
        """
        m, n = len(a), len(self.xy)
        if m == 0 or n == 0 or not r >= 0:
            return _EMPTY, _EMPTY
        r = float(r) * (1 + _SLACK) + _SLACK
        if m * n <= DENSE_MAX_PAIRS or not np.isfinite(r):
            dx = self.xy[None, :, 0] - a[:, None, 0]
            dy = self.xy[None, :, 1] - a[:, None, 1]
            ai, bi = np.nonzero(dx * dx + dy * dy <= r * r)
            return ai.astype(np.int64, copy=False), bi.astype(np.int64, copy=False)
        if self._tree is None:
            # unbalanced, non-compact: the cheapest build, and it is rebuilt every tick
            self._tree = cKDTree(self.xy, balanced_tree=False, compact_nodes=False)
        hits = self._tree.query_ball_point(
            np.ascontiguousarray(a[:, :2], dtype=float), r, return_sorted=True
        )
        counts = np.fromiter(map(len, hits), np.int64, m)
        total = int(counts.sum())
        if total == 0:
            return _EMPTY, _EMPTY
        bi = np.fromiter(chain.from_iterable(hits), np.int64, total)
        return np.repeat(np.arange(m, dtype=np.int64), counts), bi


def pair_distance(a: np.ndarray, b: np.ndarray, ai: np.ndarray, bi: np.ndarray) -> np.ndarray:
    """Euclidean distance of each pair, over the columns of ``a`` (2 or 3), dense rounding."""
    dx = b[bi, 0] - a[ai, 0]
    dy = b[bi, 1] - a[ai, 1]
    if a.shape[1] < 3:
        return np.sqrt(dx * dx + dy * dy)
    dz = b[bi, 2] - a[ai, 2]
    return np.sqrt(dx * dx + dy * dy + dz * dz)


def pairs_within(
    a: np.ndarray,
    b: np.ndarray,
    r: float,
    *,
    strict: bool = False,
    index: PlanarIndex | None = None,
) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """(ai, bi, dist) of the pairs of rows of ``a`` and ``b`` at distance ≤ r (< r if strict).

    The distance is over ``a``'s columns (x, y or x, y, z), computed per pair as a dense
    ``sqrt(dx² + dy² [+ dz²])`` would be. Pairs are sorted by ``ai`` then ``bi``. ``index``
    reuses a :class:`PlanarIndex` already built on ``b``.
    """
    index = PlanarIndex(b) if index is None else index
    ai, bi = index.candidates(a, r)
    dist = pair_distance(a, b, ai, bi)
    keep = dist < r if strict else dist <= r
    return ai[keep], bi[keep], dist[keep]
